"""``pneunet-grasp train --export PATH_STEM``: a run's best model (else its final one), its statistics and a metadata
JSON copied out of the run folder (:func:`export`), each file replaced atomically, so a failure leaves the previous
export whole. The policy registry (:mod:`agents.policies`) then loads ``PATH_STEM.zip`` by path.

The statistics a ``--resume`` goes on with (:func:`resume_stats`) are numbers too: no pickle is loaded unless its path
is named (``--resume-vecnormalize PATH``), or it is the run's own, in the ``--run-dir`` it resumes.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from agents.policies.sb3 import STATS_SUFFIX, NormalizationStats, load_pickled_vecnormalize
from agents.training.config import action_mode
from pneunet_env.files import atomic_write_many, deferred_interrupt

__all__ = ["export", "export_source", "resume_stats"]


def export(run_dir: Path, dest: Path, record: dict[str, Any]) -> Path:
    """Copy the best model (else the final one), its statistics and a metadata JSON to ``dest.zip``,
    ``dest_vecnormalize.json`` and ``dest.json``.

    Each file is replaced atomically: every new file is first written in full (and flushed) to a temporary file in
    ``dest``'s folder, and only then are they renamed over the old ones (``os.replace``), so a failure while writing
    (a full disk, an interrupt) leaves the previous export whole and no temporary file behind. A statistics file of
    an earlier export is removed only when the new model has none, after the new model is in place, so a model is
    never paired with stale statistics.
    """
    src, stem = run_dir / "best_model.zip", run_dir / "best_model"
    model_timesteps = record["best_eval"].get("timesteps")
    if not src.is_file():
        src, stem = run_dir / "final_model.zip", run_dir / "final_model"
        model_timesteps = record["timesteps"]
    stats = _run_stats(stem)
    hyper = record["hyperparameters"]
    meta = {"algo": record["algo"], "action": record.get("action") or action_mode(hyper), "env_id": record["env_id"],
            "source": str(src), "seed": record["seed"], "model_timesteps": model_timesteps,
            "timesteps": record["timesteps"], "total_wall_s": record["total_wall_s"], "best_eval": record["best_eval"],
            "best_ramp_eval_success_rate": record.get("best_ramp_eval_success_rate"),
            "hyperparameters": hyper, "versions": record["versions"], "reproduce": record.get("command")}
    dest.parent.mkdir(parents=True, exist_ok=True)
    zip_path = dest.with_suffix(".zip")
    stats_dest = dest.with_name(dest.name + STATS_SUFFIX)
    outputs: list[tuple[Path, bytes | Path]] = [(zip_path, src)]
    if stats is not None:
        outputs.append((stats_dest, (json.dumps(stats.to_dict(), indent=1) + "\n").encode()))
    outputs.append((dest.with_suffix(".json"), (json.dumps(meta, indent=1, default=str) + "\n").encode()))
    with deferred_interrupt():  # a Ctrl-C is raised once the export is whole (or the previous one untouched)
        atomic_write_many(outputs)
        if stats is None:
            stats_dest.unlink(missing_ok=True)
    return zip_path


def _run_stats(stem: Path) -> NormalizationStats | None:
    """The statistics saved beside a model of the run (JSON; a run of an older version has only SB3's pickle,
    which is read: it is the run's own output, in the folder of the model that is unpickled as well)."""
    js = stem.with_name(stem.name + STATS_SUFFIX)
    if js.is_file():
        return NormalizationStats.load(js)
    pkl = stem.with_name(stem.name + "_vecnormalize.pkl")
    if pkl.is_file():
        return NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(pkl))
    return None


def _stats_beside(checkpoint: Path, suffix: str) -> Path | None:
    """The statistics file beside a model of a run, by SB3's names: ``model_vecnormalize_<N>_steps<suffix>`` for the
    checkpoint ``model_<N>_steps.zip``, ``STEM_vecnormalize<suffix>`` for ``STEM.zip``; ``None`` where neither
    exists."""
    m = re.fullmatch(r"model_(\d+)_steps\.zip", checkpoint.name)
    names = [f"model_vecnormalize_{m.group(1)}_steps{suffix}"] if m else []
    names.append(f"{checkpoint.stem}_vecnormalize{suffix}")
    return next((p for p in (checkpoint.with_name(n) for n in names) if p.is_file()), None)


def _inside(path: Path, run_dir: Path) -> bool:
    """Whether ``path`` is a model of the run ``run_dir``: in the folder itself or in its ``checkpoints/``."""
    return path.resolve().parent in (run_dir.resolve(), (run_dir / "checkpoints").resolve())


def resume_stats(checkpoint: str | Path, run_dir: str | Path,
                 named: str | Path | None = None) -> NormalizationStats:
    """The normalisation statistics a run trained on a ``VecNormalize`` goes on with from ``checkpoint``.

    In order: ``named`` (``--resume-vecnormalize PATH``: a ``.json`` read as numbers, any other file unpickled, which
    runs code from it: the user named it); the JSON beside the checkpoint (``model_vecnormalize_<N>_steps.json``,
    ``STEM_vecnormalize.json``: numbers, no code runs); the pickle beside it (SB3's names, ``.pkl``) only where the
    checkpoint is the run's own, in ``run_dir`` or its ``checkpoints/`` (written by a version before checkpoints carried
    JSON; the user named that folder, whose model zip SB3 unpickles as well). A pickle beside a checkpoint anywhere
    else is never loaded: it is a file the user did not name.

    Raises:
        ValueError: naming the files: the pickle beside a checkpoint outside ``run_dir`` (and the option that loads it),
            no statistics at all (a model trained on normalised observations would go on with fresh ones), or
            statistics that cannot be read.
    """
    checkpoint, run_dir = Path(checkpoint), Path(run_dir)
    if named is not None:
        named = Path(named)
        if named.suffix == ".json":
            return NormalizationStats.load(named)
        return NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(named))  # named: trusted by the user
    if (js := _stats_beside(checkpoint, ".json")) is not None:
        return NormalizationStats.load(js)
    pkl = _stats_beside(checkpoint, ".pkl")
    if pkl is not None and _inside(checkpoint, run_dir):
        return NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(pkl))
    if pkl is not None:
        raise ValueError(f"the statistics beside {str(checkpoint)!r} are only a pickle, {str(pkl)!r}, outside the run "
                         f"folder {str(run_dir)!r}: a pickle runs code when loaded and is never loaded unless named; "
                         f"if you trust it, pass --resume-vecnormalize {pkl}")
    raise ValueError(f"no normalisation statistics beside {str(checkpoint)!r} (looked for its _vecnormalize.json and "
                     f".pkl); the run normalises its observations, and its model would go on with fresh statistics: "
                     "name them with --resume-vecnormalize PATH (.json, or a .pkl you trust)")


def export_source(run_dir: Path) -> str:
    """What :func:`export` copies from ``run_dir``, in words."""
    if (run_dir / "best_model.zip").is_file():
        return "the best evaluation's model"
    return "the final model (no evaluation ran, so there is no best model)"
