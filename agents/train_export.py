"""``pneunet-grasp train --export PATH_STEM``: a run's best model (else its final one), its statistics and a metadata
JSON copied out of the run folder (:func:`export`), each file replaced atomically, so a failure leaves the previous
export whole. The policy registry (:mod:`agents.policies`) then loads ``PATH_STEM.zip`` by path.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from agents.policies import STATS_SUFFIX, NormalizationStats, load_pickled_vecnormalize
from agents.train_config import action_mode
from pneunet_env.files import atomic_write_many, deferred_interrupt

__all__ = ["export", "export_source"]


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


def export_source(run_dir: Path) -> str:
    """What :func:`export` copies from ``run_dir``, in words."""
    if (run_dir / "best_model.zip").is_file():
        return "the best evaluation's model"
    return "the final model (no evaluation ran, so there is no best model)"
