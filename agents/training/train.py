"""``pneunet-grasp train --config configs/train/ppo.yaml``: train a stable-baselines3 agent on ``PneuNetGrasp-v1``.

The config is two files, ``ppo.yaml`` (a plain rl-zoo3 hyperparameter file: ``python -m rl_zoo3.train`` trains
from it as it is) and ``ppo.project.yaml`` beside it (this command's own keys): :mod:`agents.training.config` reads them
and documents every key, and what a train config may run (only classes of SB3, sb3-contrib, Gymnasium and this
package; a train config is data, not code).

The run directory (``--run-dir``, default ``runs/<algo>``) receives ``config.yaml`` and ``config.project.yaml``
(the resolved hyperparameters, in the same two-file form: ``--config RUN_DIR/config.yaml`` trains the same run
again), ``run.json`` (seeds, versions, timesteps, wall time, each invocation), ``monitor/``, ``evaluations.npz``
(EvalCallback's log: rewards, lengths, successes), ``best_model.zip`` with ``best_model_vecnormalize.json`` (the
statistics as numbers) and ``.pkl`` (SB3's pickle), ``checkpoints/``, ``final_model.zip`` with
``final_model_vecnormalize.json`` and ``.pkl``, and ``training.png`` (success rate and return of each evaluation,
with matplotlib). ``--resume`` continues from the newest readable checkpoint (one cut short by a hard kill under
an older version is skipped, and said so on stderr; or ``--resume PATH.zip``) up to ``n_timesteps``, with the
statistics beside it as numbers (``model_vecnormalize_<N>_steps.json``); a pickle is loaded only when named
(``--resume-vecnormalize PATH.pkl``) or the run's own, in ``--run-dir`` (:func:`agents.training.export.resume_stats`).

Nothing is lost (:func:`train`): every file of the run is written to a temporary name in its folder and renamed
(the monitor CSVs, logs, excepted); ``run.json`` gives the run's ``state`` (``running``, ``finished``, ``stopped``
by the time budget, ``interrupted``, ``failed``); Ctrl-C saves the model as a checkpoint, records
``state: interrupted`` and stops (``pneunet-grasp`` exits with status 130), and ``--resume`` goes on from it. A cut
``run.json`` is refused by name on ``--resume`` (restore it, or move it aside to start a new record). The run folder
is locked while it trains (``RUN_DIR/.lock``: :mod:`pneunet_env.locks`): a second ``train`` on it is refused by
name; ``--force`` takes over a lock whose process looks alive (a dead one's is taken over anyway).

``--export agents/models/ppo_pneunet`` copies the best model, its statistics (JSON) and a metadata
JSON there, each file written to a temporary name in that folder and then renamed over the old one (a failure
leaves the previous export whole): the policy registry (:mod:`agents.policies`) then loads
``agents/models/ppo_pneunet.zip`` by path.

The command's parts: this module holds the training loop, the saved models and the run's record
(``run.json``) and the command line; :mod:`agents.training.config` the config; :mod:`agents.training.envs` the vec envs
and callbacks; :mod:`agents.training.export` ``--export``; :mod:`agents.figures` ``training.png``. Their public
names are importable from here too.

torch and stable-baselines3 are imported only inside the functions (``pip install -e ".[rl]"``).
"""

from __future__ import annotations

import argparse
import io
import json
import pickle
import platform
import re
import sys
import time
from pathlib import Path
from typing import Any

from agents.figures.training import plot_training
from agents.policies.sb3 import STATS_SUFFIX, NormalizationStats, check_model_zip
from agents.training.config import ENV_ID, PROJECT_KEYS, _algo_kwargs, _resolve_policy_kwargs, action_mode
from agents.training.envs import make_callbacks, make_vec_env, reference_success
from agents.training.export import resume_stats
from pneunet_env.files import (
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_many,
    atomic_write_text,
    deferred_interrupt,
)
from pneunet_env.locks import RunLock
from pneunet_env.yamlio import dump_yaml, load_json_file

__all__ = ["no_folder_logger", "latest_checkpoint", "train", "write_record"]


def _model_bytes(model) -> bytes:
    """The model's zip (SB3's ``save``), in memory."""
    buf = io.BytesIO()
    model.save(buf)
    return buf.getvalue()


def _save_stats(model, stem: Path) -> None:
    """``STEM_vecnormalize.json`` (numbers, what :mod:`agents.policies` loads) and ``STEM_vecnormalize.pkl``
    (SB3's ``VecNormalize.save``: the object pickled) for a model trained on a ``VecNormalize``; nothing otherwise.
    Each written whole or not at all."""
    vn = model.get_vec_normalize_env()
    if vn is not None:
        with deferred_interrupt():
            NormalizationStats.from_vecnormalize(vn).save(stem.with_name(stem.name + STATS_SUFFIX))
            atomic_write_bytes(stem.with_name(stem.name + "_vecnormalize.pkl"), pickle.dumps(vn))


def _save_model(model, stem: Path) -> Path:
    """``STEM.zip`` and its statistics (:func:`_save_stats`): every file staged in full beside its name first, then
    all renamed into place, the zip last (an interrupt while staging leaves the previous files whole)."""
    outputs: list[tuple[Path, bytes]] = []
    vn = model.get_vec_normalize_env()
    if vn is not None:
        stats = NormalizationStats.from_vecnormalize(vn).to_dict()
        outputs += [(stem.with_name(stem.name + STATS_SUFFIX), (json.dumps(stats, indent=1) + "\n").encode()),
                    (stem.with_name(stem.name + "_vecnormalize.pkl"), pickle.dumps(vn))]
    outputs.append((stem.with_name(stem.name + ".zip"), _model_bytes(model)))
    return atomic_write_many(outputs)[-1]  # a Ctrl-C is raised once every file is in place


def no_folder_logger():
    """SB3's logger with no outputs. Without one, every ``learn()`` of a model with ``verbose=0`` and no tensorboard
    folder makes an empty ``$TMPDIR/SB3-<date and time>`` folder (``stable_baselines3.common.logger.configure``) and
    leaves it there: one a run, thousands a test session. The run's own records are ``run.json``, the monitor CSVs and
    the evaluations."""
    from stable_baselines3.common.logger import Logger

    return Logger(folder=None, output_formats=[])


def _save_checkpoint(model, folder: Path) -> Path:
    """``folder/model_<N>_steps.zip`` (``N``: the model's timesteps) and, for a ``VecNormalize`` run,
    ``folder/model_vecnormalize_<N>_steps.json`` (the statistics as numbers, what ``--resume`` reads) and ``.pkl``
    (SB3's CheckpointCallback's names), the statistics first, each file written whole
    (:func:`pneunet_env.files.atomic_write_bytes`)."""
    n = int(model.num_timesteps)
    vn = model.get_vec_normalize_env()
    stats = None if vn is None else pickle.dumps(vn)
    data = _model_bytes(model)
    with deferred_interrupt():  # every file, or a Ctrl-C before any: raised after them
        if stats is not None:
            NormalizationStats.from_vecnormalize(vn).save(folder / f"model_vecnormalize_{n}_steps.json")
            atomic_write_bytes(folder / f"model_vecnormalize_{n}_steps.pkl", stats)
        return atomic_write_bytes(folder / f"model_{n}_steps.zip", data)


def _callbacks(hp, run_dir: Path, eval_env, seed: int, deadline: float, resuming: bool = False) -> list:
    """The run's callbacks (:func:`agents.training.envs.make_callbacks`), saving models through this module's
    :func:`_save_model` and :func:`_save_checkpoint`."""
    return make_callbacks(hp, run_dir, eval_env, seed, deadline, resuming, save_model=_save_model,
                          save_checkpoint=_save_checkpoint)


_CKPT = re.compile(r"model_(\d+)_steps\.zip$")


def latest_checkpoint(run_dir: Path, *, report: bool = True) -> Path | None:
    """The readable checkpoint with the most timesteps in ``run_dir/checkpoints`` (``None`` if there is none).

    A checkpoint that is not a whole model zip (cut by a hard kill or a full disk under an older version, which
    wrote in place; damaged) is skipped, and (``report``) said so on stderr, naming it and why."""
    found = sorted(((int(m.group(1)), p) for p in (run_dir / "checkpoints").glob("model_*_steps.zip")
                    if (m := _CKPT.search(p.name))), reverse=True)
    for _, path in found:
        try:
            check_model_zip(path)
        except ValueError as exc:
            if report:
                print(f"skipping checkpoint {path}: {exc}", file=sys.stderr)
            continue
        return path
    return None


def _versions() -> dict[str, str]:
    import gymnasium
    import numpy
    import stable_baselines3
    import torch

    import pneunet_env

    return {"python": platform.python_version(), "pneunet_env": pneunet_env.__version__,
            "stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__,
            "gymnasium": gymnasium.__version__, "numpy": numpy.__version__}


def train(hp: dict[str, Any], run_dir: Path, resume: Path | None = None, progress: bool = True,
          config_path: str | None = None, *, command: str | None = None, force: bool = False,
          resume_vecnormalize: Path | None = None) -> dict[str, Any]:
    """Train (or resume) one run; returns the run record written to ``run_dir/run.json``.

    Nothing is lost, and the folder has one writer:

    * ``run_dir`` is locked for the whole call (:class:`pneunet_env.locks.RunLock`, ``run_dir/.lock``): a second
      process on the same folder is refused (``ValueError`` naming the folder and the holder's pid); ``force``
      takes the lock over. A lock whose process is dead on this host is taken over anyway.
    * Every file is written whole or not at all (a temporary file in the same folder, then renamed): checkpoints,
      the best, initial and final models, their statistics, ``evaluations.npz``, ``run.json``, the configs and
      ``training.png``. The monitor CSVs are logs, appended line by line.
    * ``run.json`` says the run's ``state``: ``running`` while it trains, then ``finished`` (``n_timesteps``
      reached), ``stopped`` (the time budget spent first), ``interrupted`` or ``failed``.
    * On Ctrl-C (``KeyboardInterrupt``) once the model exists, the model is saved as a checkpoint
      (``checkpoints/model_<N>_steps.zip``), the record is written (``state: interrupted``), and the interrupt
      propagates: ``--resume`` goes on from there. Interrupted before the model exists, a folder this call created
      is removed again (nothing was trained).

    Args:
        resume: a checkpoint (or final model) of this run to continue from; its ``run.json`` is read first, and an
            unreadable one is a ``ValueError`` naming it (restore it, or move it aside to start a new record).
        resume_vecnormalize: the statistics to resume a normalised run with (``--resume-vecnormalize``: a ``.json``,
            or a pickle, loaded because it is named); default: those beside ``resume``, never an unnamed pickle
            outside ``run_dir`` (:func:`agents.training.export.resume_stats`).
        command: the command line, recorded in ``run.json`` and the lock file.
        force: take over the run folder's lock even if its holder looks alive.
    """
    import numpy as np
    import stable_baselines3 as sb3
    import torch
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    record_path = run_dir / "run.json"
    record = _read_record(record_path) if resume is not None else {}
    stats = None
    if resume is not None:
        check_model_zip(resume)
        if hp["normalize"]:  # named before the work starts: no unnamed pickle, no fresh statistics for a trained model
            stats = resume_stats(resume, run_dir, resume_vecnormalize)
    created = not run_dir.exists()
    lock = RunLock(run_dir, command=command or f"pneunet-grasp train --run-dir {run_dir}", force=force)
    t0 = time.monotonic()
    model = venv = eval_env = None
    done, ended, appended = 0, False, False
    try:
        lock.acquire()
        deadline = t0 + 60.0 * hp["max_train_minutes"]
        torch.set_num_threads(hp["torch_threads"])
        seed = hp["seed"]
        set_random_seed(seed)
        algo_cls = getattr(sb3, hp["algo"].upper())
        venv = make_vec_env(hp, hp["n_envs"], seed, run_dir / "monitor")
        eval_env = make_vec_env(hp, hp["n_eval_envs"], seed + 10_000, None)
        norm = hp["normalize"]
        if norm:
            if stats is not None:
                venv = stats.to_vecnormalize(venv, training=True, source=f"the statistics of {resume}")
            else:
                venv = VecNormalize(venv, gamma=float(hp.get("gamma", 0.99)), **norm)
            eval_env = VecNormalize(eval_env, training=False, norm_obs=norm.get("norm_obs", True), norm_reward=False)
        if hp.get("frame_stack") is not None:
            venv = VecFrameStack(venv, hp["frame_stack"])
            eval_env = VecFrameStack(eval_env, hp["frame_stack"])
        algo_kwargs = _algo_kwargs(hp)
        record.setdefault("invocations", [])  # filled before the model exists: an interrupt from then on records
        record.update(algo=hp["algo"], env_id=ENV_ID, seed=seed, seeds={"train_envs": f"{seed} + i",
                      "eval_env": seed + 10_000, "torch_numpy_random": seed}, config_path=config_path,
                      hyperparameters=hp, action=action_mode(hp), versions=_versions(),
                      vec_env=type(venv.unwrapped if hasattr(venv, "unwrapped") else venv).__name__,
                      state="running", timesteps=done)
        if command is not None:
            record["command"] = command
        if resume is not None:
            model = algo_cls.load(str(resume), env=venv, device="cpu")
            done = int(model.num_timesteps)
        else:
            model = algo_cls(hp["policy"], venv, seed=seed, device="cpu", verbose=0,
                             policy_kwargs=_resolve_policy_kwargs(hp["policy_kwargs"]), **algo_kwargs)
        model.set_logger(no_folder_logger())
        if done == 0 and (resume is None or not (run_dir / "initial_model.zip").is_file()):
            _save_model(model, run_dir / "initial_model")  # the untrained policy: step 0 of the learning curve
        remaining = max(0, hp["n_timesteps"] - done)
        zoo = {k: v for k, v in hp.items() if k not in PROJECT_KEYS}
        with deferred_interrupt():
            atomic_write_text(run_dir / "config.yaml", dump_yaml({ENV_ID: zoo}, sort_keys=False))
            atomic_write_text(run_dir / "config.project.yaml",
                              dump_yaml({ENV_ID: {k: hp[k] for k in PROJECT_KEYS}}, sort_keys=False))
        record["timesteps"] = done
        write_record(record_path, record)
        if remaining > 0:
            callbacks = _callbacks(hp, run_dir, eval_env, seed + 10_000, deadline, resuming=resume is not None)
            # with gradients on, whatever the caller's mode: a Ctrl-C inside an earlier torch.no_grad() of this
            # process (raised within its __enter__, so its __exit__ never ran) leaves them off, and SB3's update then
            # fails ("element 0 of tensors does not require grad"); the caller's mode is restored afterwards
            with torch.enable_grad():
                model.learn(total_timesteps=remaining, callback=callbacks, progress_bar=progress,
                            reset_num_timesteps=resume is None)
        _save_model(model, run_dir / "final_model")
        wall = time.monotonic() - t0
        steps = int(model.num_timesteps)
        ref = reference_success(hp, seed + 10_000)
        record["invocations"].append({"resumed_from": None if resume is None else str(resume),
                                      "start_timesteps": done, "end_timesteps": steps, "wall_s": round(wall, 1),
                                      "time_budget_min": hp["max_train_minutes"],
                                      "finished": steps >= hp["n_timesteps"]})
        appended = True
        record.update(timesteps=steps, best_eval=_best_eval(run_dir, np), best_ramp_eval_success_rate=ref,
                      total_wall_s=round(sum(i["wall_s"] for i in record["invocations"]), 1),
                      state="finished" if steps >= hp["n_timesteps"] else "stopped")
        write_record(record_path, record)
        ended = True
        plot_training(run_dir, reference=ref, reference_label="best-ramp on the same objects")
        return record
    except BaseException as exc:
        note = None
        if model is not None and not ended:
            note = _record_end(model, run_dir, record, resume, done, t0, hp, exc, np, appended)
        if note is not None and isinstance(exc, KeyboardInterrupt) and not exc.args:
            # the CLI prints one line: "pneunet-grasp train: interrupted at N timesteps; saved ...: --resume ..."
            raise KeyboardInterrupt(note) from exc
        raise
    finally:
        for env in (venv, eval_env):
            if env is not None:
                env.close()
        lock.release()
        if model is None and created:
            _remove_if_empty(run_dir)


def _best_eval(run_dir: Path, np) -> dict[str, Any]:
    """The best trained evaluation of ``run_dir/evaluations.npz`` (step 0, the untrained start, never is)."""
    evals = run_dir / "evaluations.npz"
    best: dict[str, Any] = {}
    if evals.is_file():
        data = np.load(evals)
        trained = np.flatnonzero(data["timesteps"] > 0)
        if len(trained):
            i = int(trained[np.argmax(data["results"][trained].mean(axis=1))])
            best = {"timesteps": int(data["timesteps"][i]), "mean_reward": float(data["results"][i].mean())}
            if "successes" in data and len(data["successes"]):
                best["success_rate"] = float(np.mean(data["successes"][i]))
    return best


def _record_end(model, run_dir: Path, record: dict[str, Any], resume: Path | None, done: int, t0: float,
                hp: dict[str, Any], exc: BaseException, np, appended: bool = False) -> str | None:
    """A run that ends early: on Ctrl-C, the model saved as a checkpoint and ``state: interrupted``; on an error,
    ``state: failed`` (no checkpoint: the model may be what failed). Either way the record is written. Returns the
    note the interrupt carries to the command line's one line (where the run was saved), or ``None``."""
    interrupted = isinstance(exc, KeyboardInterrupt)
    steps = int(model.num_timesteps)
    ckpt = None
    if interrupted:
        ckpt = _save_checkpoint(model, run_dir / "checkpoints")
    else:  # what a resume would go on from: the last checkpoint, not this model
        last = latest_checkpoint(run_dir, report=False)
        steps = int(_CKPT.search(last.name).group(1)) if last is not None else done
    invocation = {"resumed_from": None if resume is None else str(resume), "start_timesteps": done,
                  "end_timesteps": steps, "wall_s": round(time.monotonic() - t0, 1),
                  "time_budget_min": hp["max_train_minutes"], "finished": False}
    if interrupted:
        invocation["interrupted"] = True
    else:
        invocation["failed"] = f"{type(exc).__name__}: {exc}"
    if appended:  # ended while writing the record of a whole invocation: that one stands, marked
        record["invocations"][-1].update({k: v for k, v in invocation.items() if k in ("interrupted", "failed")})
    else:
        record["invocations"].append(invocation)
    record.update(timesteps=steps, best_eval=_best_eval(run_dir, np), state="interrupted" if interrupted else "failed",
                  total_wall_s=round(sum(i["wall_s"] for i in record["invocations"]), 1))
    write_record(run_dir / "run.json", record)
    if ckpt is not None:
        return f"at {steps} timesteps; saved {ckpt}: --resume goes on from there"
    return None


def _remove_if_empty(run_dir: Path) -> None:
    """Remove a run folder this call created and that holds nothing but an empty monitor log (interrupted or failed
    before the model existed)."""
    monitor = run_dir / "monitor"
    if monitor.is_dir() and all(p.is_file() and p.suffix == ".csv" for p in monitor.iterdir()):
        for p in monitor.iterdir():
            p.unlink(missing_ok=True)
        monitor.rmdir()
    try:
        run_dir.rmdir()
    except OSError:  # something else is there: left as it is
        pass


def _read_record(path: Path) -> dict[str, Any]:
    """A run's ``run.json`` (``{}`` if there is none).

    Raises:
        ValueError: it exists but cannot be read (cut, not JSON, not a mapping), naming it: resuming would otherwise
            drop the run's history. Restore it, or move it aside to start a new record (the checkpoints are kept).
    """
    if not path.is_file():
        return {}
    try:
        data = load_json_file(path, "run record")
    except (OSError, ValueError) as exc:
        raise ValueError(f"run record {str(path)!r} is unreadable ({type(exc).__name__}: {exc}); restore it, or move "
                         "it aside to start a new record (the checkpoints are kept, the earlier invocations' history "
                         "is not)") from None
    if not isinstance(data, dict):
        raise ValueError(f"run record {str(path)!r} is not a JSON mapping; restore it, or move it aside to start a new "
                         "record")
    return data


def write_record(path: Path, record: dict[str, Any]) -> None:
    """Write ``run.json`` whole or not at all: a temporary file in the same folder, then renamed over it."""
    with deferred_interrupt():
        atomic_write_json(path, record, default=str)


def _command(args: argparse.Namespace, run_dir: Path) -> str:
    """The command line of this invocation (recorded in run.json and the exported model's JSON)."""
    parts = ["pneunet-grasp train", f"--config {getattr(args, 'config_given', args.config)}", f"--run-dir {run_dir}"]
    for flag, value in (("--timesteps", args.timesteps), ("--n-envs", args.n_envs), ("--seed", args.seed),
                        ("--eval-freq", args.eval_freq), ("--n-eval-episodes", args.n_eval_episodes),
                        ("--checkpoint-freq", args.checkpoint_freq), ("--max-minutes", args.max_minutes),
                        ("--vec-env", args.vec_env), ("--threads", args.threads), ("--export", args.export)):
        if value is not None:
            parts.append(f"{flag} {value:g}" if isinstance(value, float) else f"{flag} {value}")
    parts += [f"--set {item}" for item in getattr(args, "overrides", [])]
    if args.resume is not None:
        parts.append("--resume" if args.resume == "latest" else f"--resume {args.resume}")
    if getattr(args, "resume_vecnormalize", None) is not None:
        parts.append(f"--resume-vecnormalize {args.resume_vecnormalize}")
    return " ".join(parts)
