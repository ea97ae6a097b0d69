"""``pneunet-grasp train --seeds N``: one training config over ``N`` seeds, and what the seeds say together.

One seed proves little: an untrained network may already command a good blind pressure (its initial mean action
is a pressure setpoint), and two seeds of the same config can land far apart. So every learner is reported over
seeds, next to its own untrained start:

1. **Training.** Seed ``s`` (``seed``, ``seed + 1``, ...) trains in ``RUN_DIR/seed-<s>`` as a plain
   ``pneunet-grasp train`` run (:func:`agents.training.train.train`), evaluated at step 0 (the untrained policy, also
   saved as ``initial_model.zip``) and every ``eval_freq`` steps. A seed whose ``run.json`` reached ``n_timesteps`` is
   done and kept; any other resumes from its newest checkpoint: running the same command again resumes an
   interrupted study, and a larger ``--timesteps`` extends a finished one. ``--jobs J`` trains ``J`` seeds at
   once, one process each.
2. **Scoring.** Each seed's best evaluation's model (what ``--export`` ships) and its untrained start are run on the
   same held-out objects (``--objects``, default 400: the objects ``pneunet-grasp demo --objects 400`` draws), by
   regime (force- or position-controlled, from the mechanics), with best-ramp on the same objects.
3. **Outputs.** ``RUN_DIR/seeds.json`` (every seed's curve and scores; mean, standard deviation, min and max over
   seeds) and ``RUN_DIR/learning_curves.png`` (success against timesteps, each seed and the mean with its range,
   best-ramp drawn on it; and the held-out success of each seed, untrained against trained). ``--export DIR/NAME``
   exports the **median seed's** model (by held-out success on all objects), and its JSON says so and lists every
   seed's score.

Nothing is lost: the study folder is locked while the study runs (:class:`pneunet_env.locks.RunLock`; a second
study on it is refused by name, ``--force`` takes the lock over), and so is each seed's folder while it trains
(:func:`agents.training.train.train`). Every file is written whole or not at all. Ctrl-C stops the seeds that are
training (each saves its model as a checkpoint and records ``state: interrupted``), starts no other, and propagates; the
same command resumes.

With ``--jobs``, each seed trains in a worker process watched by the parent (:func:`agents.common.workers.run_jobs`). A
worker that dies (the OOM killer's or a pre-emption's SIGKILL) is noticed at once: its seed's ``run.json`` says
``state: failed`` with the cause and the exit signal, its lock and the temporary files its cut writes left are
removed (:func:`_mark_died`), no other seed starts, and the seeds training are stopped as Ctrl-C stops them (their
checkpoints saved): the study needs every seed, so it must be run again anyway, and a stopped seed loses nothing
while one left training may be the next one killed. The command ends with one line naming each seed's end and
saying to run it again, which resumes every seed from its newest readable checkpoint. A SIGINT, from the terminal
or sent to the parent alone, stops every worker once.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.figures.training import plot_seeds  # the figure (re-exported: it lived here)
from pneunet_env.files import atomic_write_json, deferred_interrupt
from pneunet_env.yamlio import load_json_file

__all__ = ["run_seeds", "train_seed", "score_seeds", "summarise", "plot_seeds", "median_seed"]


def _seed_dir(run_dir: Path, seed: int) -> Path:
    return run_dir / f"seed-{seed}"


def train_seed(hp: dict[str, Any], run_dir: Path, progress: bool, config_path: str, command: str,
               force: bool = False) -> dict[str, Any]:
    """Train one seed in ``run_dir`` (resumed from its newest readable checkpoint if it has one); its run record.

    A seed whose ``run.json`` reached ``hp["n_timesteps"]`` (and is not marked running, interrupted or failed) is
    done: its record is returned as it is. One that stopped short (interrupted, or a study extended by a larger
    ``--timesteps``) resumes from its newest checkpoint. ``force``: take over the seed folder's lock."""
    from agents.training.train import latest_checkpoint, train

    if _done(run_dir, hp):
        return _record(run_dir)
    resume = latest_checkpoint(run_dir)
    if (old := _record(run_dir)) is not None and (run_dir / "final_model.zip").is_file():  # extended: from its end
        steps = int(old.get("timesteps", 0))
        if resume is None or steps > int(resume.stem.split("_")[1]):
            resume = run_dir / "final_model.zip"
    return train(hp, run_dir, resume, progress=progress, config_path=config_path, command=command, force=force)


_FREE = ("n_timesteps", "max_train_minutes", "torch_threads")
"""Settings a seed's run may change between invocations: how long it trains, and on how many threads."""


def _record(run_dir: Path) -> dict[str, Any] | None:
    try:
        data = load_json_file(run_dir / "run.json", "run record")
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _check_settings(run_dir: Path, hp: dict[str, Any]) -> None:
    """``SystemExit`` naming the keys where a seed's earlier run was trained with other settings than ``hp``."""
    record = _record(run_dir)
    old = (record or {}).get("hyperparameters")
    if not isinstance(old, dict):
        return
    new = json.loads(json.dumps(hp, default=str))
    changed = sorted(k for k in set(old) | set(new) if k not in _FREE and old.get(k) != new.get(k))
    if changed:
        raise SystemExit(f"pneunet-grasp train: {run_dir} was trained with other settings ({', '.join(changed)}); "
                         "use another --run-dir, or the same settings to resume or extend it")


_UNFINISHED = ("running", "interrupted", "failed")
"""A run record's states that are not an end (a record without ``state``, written by 0.7.0 or older, ended)."""


def _done(run_dir: Path, hp: dict[str, Any]) -> bool:
    record = _record(run_dir)
    try:
        return (record is not None and record.get("state") not in _UNFINISHED
                and int(record["timesteps"]) >= int(hp["n_timesteps"]))
    except (ValueError, KeyError, TypeError):
        return False


def _train_job(job: tuple) -> dict[str, Any]:  # a worker process (agents.common.workers): module-level, to pickle
    return train_seed(*job)


def _mark_died(run_dir: Path, seed: int, out) -> bool:
    """Seed ``seed``'s worker died (``out``: its :class:`agents.common.workers.Outcome`): its lock is released, the
    temporary files its cut writes left are removed, and its ``run.json`` says ``state: failed``, with the cause, the
    exit signal and the timesteps a resume starts from (its newest readable checkpoint's). Returns whether its run had
    finished before it died (then its record is kept as it is). A worker that died before it made its folder
    leaves nothing to record."""
    import time

    from agents.training.train import _CKPT, latest_checkpoint, write_record
    from pneunet_env.files import remove_temporary
    from pneunet_env.locks import RunLock, release_dead

    if not run_dir.is_dir():
        return False
    release_dead(run_dir, out.pid)
    with RunLock(run_dir, command=f"pneunet-grasp train --seeds: recording seed {seed}'s dead worker",
                 what="seed folder"):
        remove_temporary(run_dir)
        record = _record(run_dir) or {}
        if record.get("state") in ("finished", "stopped"):
            return True
        last = latest_checkpoint(run_dir, report=False)
        steps = int(_CKPT.search(last.name).group(1)) if last is not None else 0
        cause = out.cause()
        invocations = record.get("invocations") if isinstance(record.get("invocations"), list) else []
        invocations.append({"start_timesteps": int(record.get("timesteps") or 0), "end_timesteps": steps,
                            "wall_s": round(time.monotonic() - out.started, 1) if out.started else None,
                            "finished": False, "failed": cause, "exit_signal": out.signal_name})
        record.update(seed=seed, invocations=invocations, state="failed", timesteps=steps, failed=cause,
                      exit_signal=out.signal_name,
                      total_wall_s=round(sum(i.get("wall_s") or 0.0 for i in invocations), 1))
        write_record(run_dir / "run.json", record)
    return False


def _seed_list(seeds: list[int]) -> str:
    return ("seed " if len(seeds) == 1 else "seeds ") + ", ".join(map(str, seeds))


def _train_in_workers(todo: list[int], jobs_of: dict[int, tuple], jobs: int, dirs: dict[int, Path],
                      n_timesteps: int) -> dict[int, dict[str, Any]]:
    """Train the seeds ``todo`` in ``jobs`` worker processes (:func:`agents.common.workers.run_jobs`); their records.

    A worker that dies is noticed at once: its seed's run is marked failed (:func:`_mark_died`), no other seed
    starts, and the seeds training are stopped as Ctrl-C stops them (each saves its model as a checkpoint), so that
    the whole study resumes from where it stood with the same command. Raises ``SystemExit`` with one line naming
    each seed's end and how to resume, or ``KeyboardInterrupt`` (its note says the same) after a Ctrl-C."""
    from agents.common.workers import run_jobs
    from agents.training.train import latest_checkpoint

    def on_end(out) -> bool:
        s = todo[out.index]
        if out.state == "done":
            _report_seed(s, out.value)
            return True
        if out.state == "died":
            return _mark_died(dirs[s], s, out)
        return False

    ran = run_jobs(_train_job, [jobs_of[s] for s in todo], min(jobs, len(todo)), on_end=on_end,
                   preload=("agents.training.seeds", "agents.training.train", "stable_baselines3", "torch",
                            "matplotlib"))
    records = {todo[o.index]: o.value for o in ran.by_state("done")}
    for o in ran.by_state("died"):
        if (record := _record(dirs[todo[o.index]])) is not None and record.get("state") in ("finished", "stopped"):
            records[todo[o.index]] = record  # it died after its run was whole: kept
    if ran.clean or (not ran.interrupted and len(records) == len(todo)):
        return records
    parts = []
    for o in ran.outcomes:
        s = todo[o.index]
        if s in records:
            continue
        steps = (_record(dirs[s]) or {}).get("timesteps")
        at = f" at {steps} timesteps" if isinstance(steps, int) else ""
        if o.state == "died":
            parts.append(f"seed {s}: {o.cause()}{at} (its run is marked failed)")
        elif o.state == "error":
            exc = o.value
            parts.append(f"seed {s} failed: {str(exc) or type(exc).__name__}"
                         if isinstance(exc, (ValueError, TypeError, SystemExit)) else
                         f"seed {s} failed: {type(exc).__name__}: {exc}")
        elif o.state == "interrupted":
            saved = latest_checkpoint(dirs[s], report=False) is not None
            parts.append(f"seed {s} stopped{at}" + (" with a checkpoint saved" if saved else
                                                     " before its training began"))
    waiting = [todo[o.index] for o in ran.by_state("not started")]
    if waiting:
        parts.append(f"{_seed_list(waiting)} not started")
    where = (f"run the same command again to resume every seed from its newest checkpoint (to {n_timesteps} "
             "timesteps)")
    if ran.interrupted or (ran.by_state("interrupted") and not ran.by_state("died", "error")):
        raise KeyboardInterrupt(f"({'; '.join(parts)}): {where}")
    raise SystemExit(f"pneunet-grasp train: {'; '.join(parts)}: {where}")


def _report_seed(seed: int, record: dict[str, Any]) -> None:
    print(f"seed {seed}: {record['timesteps']} timesteps in {record['total_wall_s']:.0f} s; best evaluation "
          f"{record['best_eval']}")


def _curve(run_dir: Path) -> dict[str, list[float]]:
    data = np.load(run_dir / "evaluations.npz")
    out = {"timesteps": [int(t) for t in data["timesteps"]],
           "mean_return": [float(x) for x in data["results"].mean(axis=1)]}
    if "successes" in data and len(data["successes"]):
        out["success"] = [float(x) for x in data["successes"].mean(axis=1)]
    return out


def _rates(success: np.ndarray, regime: np.ndarray) -> dict[str, float | None]:
    from pneunet_env.physics.regimes import REGIMES

    out: dict[str, float | None] = {"all": float(success.mean())}
    for code, name in enumerate(REGIMES):
        m = regime == code
        if m.any() or code < 2:  # "unreachable" only where the task has such objects
            out[name] = float(success[m].mean()) if m.any() else None
    return out


def score_seeds(hp: dict[str, Any], seed_dirs: dict[int, Path], objects: int) -> dict[str, Any]:
    """Each seed's best model and untrained start, and best-ramp, on ``objects`` held-out objects (batched:
    :func:`agents.evaluation.batch.run_policy`); success by regime."""
    from agents.common.regimes import object_regimes
    from agents.evaluation.batch import episode_seeds, run_policy
    from agents.policies.registry import make_policy
    from pneunet_env.config import load_config
    from pneunet_env.physics.regimes import REGIMES

    cfg = load_config(None, **hp["env_kwargs"])
    seeds = episode_seeds(objects, 0, held_out=True)
    ramp = run_policy(make_policy("best-ramp", cfg), cfg, seeds)
    regime = object_regimes(ramp.stiffness, ramp.curvature, cfg)
    out: dict[str, Any] = {"objects": int(objects), "object_seeds": f"{int(seeds[0])} + i (demo's held-out objects)",
                           "regime_counts": {name: int((regime == code).sum()) for code, name in
                                             enumerate(REGIMES) if code < 2 or (regime == code).any()},
                           "best_ramp": _rates(ramp.success[0], regime), "seeds": {}}
    for seed, folder in seed_dirs.items():
        row = {}
        for key, name in (("trained", "best_model.zip"), ("untrained", "initial_model.zip")):
            path = folder / name
            if not path.is_file() and key == "trained":
                path = folder / "final_model.zip"
            if not path.is_file():
                row[key] = None
                continue
            entry = make_policy(str(path), cfg)
            row[key] = _rates(run_policy(entry, cfg, seeds).success[0], regime)
        out["seeds"][str(seed)] = row
    return out


def _spread(values: list[float]) -> dict[str, float]:
    x = np.asarray([v for v in values if v is not None], dtype=float)
    if not len(x):  # no objects in the group (JSON has no NaN)
        return {"mean": None, "std": None, "min": None, "max": None, "n": 0}
    return {"mean": float(x.mean()), "std": float(x.std(ddof=1)) if len(x) > 1 else 0.0, "min": float(x.min()),
            "max": float(x.max()), "n": int(len(x))}


def summarise(scores: dict[str, Any]) -> dict[str, Any]:
    """Mean, sample standard deviation, min and max over seeds of every held-out rate, trained and untrained."""
    out: dict[str, Any] = {}
    for key in ("trained", "untrained"):
        rows = [r[key] for r in scores["seeds"].values() if r.get(key)]
        out[key] = {g: _spread([r[g] for r in rows]) for g in (rows[0] if rows else {})}
    return out


def median_seed(scores: dict[str, Any]) -> int:
    """The seed whose trained model's held-out success (all objects) is the median (the lower one of an even
    count), ties broken by the seed."""
    ranked = sorted((r["trained"]["all"], int(s)) for s, r in scores["seeds"].items() if r.get("trained"))
    return ranked[(len(ranked) - 1) // 2][1]


def _command(args: argparse.Namespace, run_dir: Path, seed: int) -> str:
    from agents.training.train import _command as one

    single = argparse.Namespace(**{**vars(args), "seed": seed, "export": None, "resume": None})
    return one(single, run_dir)


def _pct(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def run_seeds(args: argparse.Namespace, hp: dict[str, Any], run_dir: Path) -> int:
    """The ``--seeds`` form of ``pneunet-grasp train`` (see the module's docstring)."""
    from pneunet_env.locks import RunLock

    n, jobs, objects = args.seeds, args.jobs, args.objects
    for flag, value in (("--seeds", n), ("--jobs", jobs), ("--objects", objects)):
        if value < 1:
            raise SystemExit(f"pneunet-grasp train: {flag} must be >= 1, got {value}")
    if args.resume is not None:
        raise SystemExit("pneunet-grasp train: --seeds resumes by itself (run the same command again); drop --resume")
    force = bool(getattr(args, "force", False))
    with RunLock(run_dir, command=_command(args, run_dir, hp["seed"]) + f" --seeds {n}", force=force,
                 what="seed study folder"):  # released on any end; a folder it made and nothing filled is removed
        return _run_seeds(args, hp, run_dir, force)


def _run_seeds(args: argparse.Namespace, hp: dict[str, Any], run_dir: Path, force: bool) -> int:
    from agents.training.export import export

    n, jobs, objects = args.seeds, args.jobs, args.objects
    first = hp["seed"]
    seeds = list(range(first, first + n))
    dirs = {s: _seed_dir(run_dir, s) for s in seeds}
    jobs_list = [({**hp, "seed": s}, dirs[s], not args.no_progress and jobs == 1, str(args.config),
                  _command(args, dirs[s], s), force) for s in seeds]
    for s in seeds:
        _check_settings(dirs[s], {**hp, "seed": s})
    todo = [s for s in seeds if not _done(dirs[s], {**hp, "seed": s})]
    print(f"training {hp['algo'].upper()} over {n} seeds ({', '.join(map(str, seeds))}; {len(todo)} to train, "
          f"{jobs} at once) for {hp['n_timesteps']} timesteps each -> {run_dir}/seed-<s>")
    records: dict[int, dict[str, Any]] = {}
    if jobs > 1 and len(todo) > 1:
        records = _train_in_workers(todo, dict(zip(seeds, jobs_list, strict=True)), jobs, dirs, hp["n_timesteps"])
    for s, job in zip(seeds, jobs_list, strict=True):
        if s not in records:
            records[s] = train_seed(*job)
            if s in todo:
                _report_seed(s, records[s])
    print(f"scoring every seed's model and its untrained start on {objects} held-out objects ...")
    held_out = score_seeds(hp, dirs, objects)
    result: dict[str, Any] = {
        "algo": hp["algo"], "seeds": seeds,
        "observation": ("pressure and chamber volume" if hp["env_kwargs"].get("observe_volume") else "pressure only"),
        "n_timesteps": hp["n_timesteps"], "config": str(getattr(args, "config_given", args.config)),
        "hyperparameters": hp, "timesteps": {str(s): records[s]["timesteps"] for s in seeds},
        "finished": {str(s): records[s]["timesteps"] >= hp["n_timesteps"] for s in seeds},
        "wall_s": {str(s): records[s]["total_wall_s"] for s in seeds},
        "curves": {str(s): _curve(dirs[s]) for s in seeds if (dirs[s] / "evaluations.npz").is_file()},
        "eval_best_ramp": {str(s): records[s].get("best_ramp_eval_success_rate") for s in seeds},
        "held_out": held_out, "summary": summarise(held_out), "median_seed": median_seed(held_out),
    }
    with deferred_interrupt():
        path = atomic_write_json(run_dir / "seeds.json", result, default=str)
    png = plot_seeds(result, run_dir / "learning_curves.png")
    groups = list(result["summary"]["trained"])
    print(f"\nheld-out success over {n} seeds ({objects} objects; mean ± std [min, max]):")
    print(f"{'':>22}" + "".join(f"  {g:>30}" for g in groups))
    for key in ("untrained", "trained"):
        cells = []
        for g in groups:
            st = result["summary"][key][g]
            cells.append("-" if st["n"] == 0 else
                         f"{_pct(st['mean'])} ± {100 * st['std']:.1f} [{_pct(st['min'])}, {_pct(st['max'])}]")
        print(f"{key + (' (step 0)' if key == 'untrained' else ''):>22}" + "".join(f"  {c:>30}" for c in cells))
    print(f"{'best-ramp':>22}" + "".join(f"  {_pct(held_out['best_ramp'][g]):>30}" for g in groups))
    print(f"median seed: {result['median_seed']}; wrote {path}" + (f" and {png}" if png else ""))
    short = [s for s in seeds if not result["finished"][str(s)]]
    if short:
        print(f"seed(s) {', '.join(map(str, short))} stopped short of {hp['n_timesteps']} timesteps (the time budget, "
              "max_train_minutes): the scores above compare unequal runs; run the same command again to go on")
        if args.export is not None:
            print("not exporting until every seed has reached n_timesteps")
            return 1
    if args.export is not None:
        s = result["median_seed"]
        zip_path = export(dirs[s], args.export, records[s])
        meta_path = Path(args.export).with_suffix(".json")
        meta = load_json_file(meta_path, "exported model's sidecar")
        meta["seed_study"] = {
            "chosen": f"the median of {n} seeds by held-out success (all {objects} objects)", "seed": s,
            "held_out": held_out["seeds"][str(s)], "every_seed": held_out["seeds"], "best_ramp": held_out["best_ramp"],
            "summary": result["summary"], "study": str(path)}
        with deferred_interrupt():
            atomic_write_json(meta_path, meta, default=str)
        print(f"exported seed {s}'s best evaluation's model (the median seed) to {zip_path}")
    return 0
