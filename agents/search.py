"""The best-ramp search: one blind schedule, tuned once over the object distribution, fixed for all objects.

``python -m agents.search`` grid-searches :class:`agents.scripted.LinearRamp`'s two parameters, the target
(a fraction of ``p_max``; for the rigid gripper, of its jaw travel) and the ramp duration (steps from 0 to the
target), maximising the success rate over ``--objects`` objects drawn from the env's object distribution with
fixed seeds (``reset(seed=seed * 1_000_003 + i)``, the same objects for every candidate). It runs the env
itself (``PneuNetGrasp-v0`` or ``RigidGrasp-v0``), so the score is exactly the env's. A coarse grid comes first,
then a finer one around the best target. Ties (common: a plateau of equally good targets) go to the higher mean
return (a gentler failure: a late slip costs less than a crush), then to the middle of the tied plateau.

The result is written to ``agents/best_ramp.json`` (``--gripper pneunet``, the ``best-ramp`` policy) or
``agents/best_rigid.json`` (``--gripper rigid``, the ``rigid`` policy), so both are fixed, reproducible policies.

``python -m agents.search --sensitivity --out DIR`` runs the threshold sensitivity study instead
(:data:`SENSITIVITY_SETTINGS`, :func:`sensitivity_study`): for each setting of the thresholds that decide the
soft side (object density, friction, the crush rule, object size), a fresh best-ramp and rigid search, then the
best-ramp, the oracle and the rigid gripper on a stiffness grid. It writes ``DIR/sensitivity.json``,
``DIR/sensitivity.md`` (a table) and ``DIR/sensitivity.png``. It is a study of the thresholds of the paper's task
(its 250 mm ring, the crush-fraction rule), *not* the environment's defaults: the defaults stay the physically
justified ones of ``docs/env.md``. It takes ``--objects``, ``--seed``, ``--grid`` and ``--out``; the search's own
options (``--gripper``, ``--targets``, ``--durations``, ``--refine``, ``--plot``, ``--config``, ``--set``) are an
error with it, and ``--grid`` an error without it (exit status 2).

Nothing is written until the search (or the study) ends, and each output is written whole (a temporary file in
the same folder, then renamed): Ctrl-C leaves the previous result as it was. The output (the JSON; with
``--sensitivity``, the folder) is locked while a search runs (:class:`pneunet_env.locks.RunLock`): a second search
on the same output is refused by name; ``--force`` takes over a lock whose process looks alive.

Both print the task they run on (its objects, its damage rule in words). A PNG (``--plot``, ``--sensitivity``) needs
matplotlib (extra ``plot``), checked before the search starts.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.evaluate import (
    damage_rule_text,
    parse_overrides,
    rate_parts,
    regime_text,
    run_episode,
    task_description,
    usage_error,
)
from agents.plotting import plot_search, plot_sensitivity  # the figures (re-exported: they lived here)
from agents.scripted import LinearRamp, jsonable
from pneunet_env import PAPER_TASK
from pneunet_env.arguments import count, integer, output_file, real
from pneunet_env.arguments import seed as seed_type
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.files import atomic_write_json, atomic_write_text, deferred_interrupt
from pneunet_env.locks import RunLock, release_held
from pneunet_env.progress import add_progress_argument
from pneunet_env.progress import progress as progress_bar

__all__ = ["Candidate", "object_seeds", "score", "grid_search", "search_ramp", "SENSITIVITY_SETTINGS",
           "strain_crush_fraction", "sensitivity_study", "add_arguments", "run", "main"]

COARSE_TARGETS = tuple(round(0.025 * i, 4) for i in range(1, 41))  # 0.025 .. 1.0
DURATIONS = (20, 60, 80)
"""Ramp durations searched (steps from 0 to the target). Every duration that ends inside the 50-step squeeze phase
gives the same outcome, object for object (the model is quasi-static: measured by
:func:`agents.batch.duration_invariance` over the 40 coarse targets x 200 objects, durations 1, 10, 20, 30, 40 and 50
differ in 0 of 8,000 pairs), so one of them, 20, stands for all; 60 and 80 reach the target in the hold phase and
differ (735 and 2,361 pairs)."""
ALL_DURATIONS = (1, 10, 20, 30, 40, 50, 60, 80)
"""The durations searched before 0.6 (``--durations`` takes any)."""


@dataclass
class Candidate:
    """One ramp's score over the search objects."""

    target: float
    n_steps: int
    success_rate: float
    damage_rate: float
    slip_rate: float
    mean_return: float
    success: np.ndarray  # per object (bool)
    stiffness: np.ndarray  # per object (k~)
    curvature: np.ndarray  # per object (w kappa_obj)

    def summary(self, config: EnvConfig) -> dict[str, Any]:
        """The scores, and success by the object's regime read off the mechanics at ``config``'s maximum pressure
        (:func:`agents.evaluate.regime_rates`: force-controlled, position-controlled; the paper ring's ``k~``
        thresholds would class every hand-scale object as stiff). For the rigid jaw too, the regime is the
        pneu-net's on the same object."""
        from agents.evaluate import regime_rates

        return {"target": self.target, "n_steps": self.n_steps, "success_rate": self.success_rate,
                "damage_rate": self.damage_rate, "slip_rate": self.slip_rate, "mean_return": self.mean_return,
                **regime_rates(self.success, self.stiffness, self.curvature, config)}


def object_seeds(n: int, seed: int = 0) -> list[int]:
    """The search's fixed episode seeds: ``seed * 1_000_003 + i``."""
    return [seed * 1_000_003 + i for i in range(n)]


def score(env, policy, seeds: Sequence[int]) -> dict[str, Any]:
    """Run ``policy`` once per seed (objects from the env's distribution); rates and per-object arrays."""
    res = [run_episode(env, policy, s) for s in seeds]
    return {
        "success_rate": float(np.mean([r["success"] for r in res])),
        "damage_rate": float(np.mean([r["damaged"] for r in res])),
        "slip_rate": float(np.mean([r["dropped"] for r in res])),
        "mean_return": float(np.mean([r["return"] for r in res])),
        "success": np.array([r["success"] for r in res]),
        "stiffness": np.array([r["stiffness"] for r in res]),
        "curvature": np.array([r["curvature"] for r in res]),
    }


def grid_search(env, config: EnvConfig, seeds: Sequence[int], targets: Sequence[float], durations: Sequence[int],
                bar=None, cache: dict | None = None) -> list[Candidate]:
    """Score every ``LinearRamp(target, n_steps)``; ``cache`` (keyed by the pair) avoids repeats.

    ``env=None`` scores the pressure ramps batched (:func:`agents.batch.ramp_grid`: every target of one duration on
    every object as one vector env run, object for object the single env's outcome); an env (the rigid jaw's)
    runs episode by episode."""
    cache = {} if cache is None else cache
    out = []
    for n in durations:
        todo = [t for t in targets if (round(float(t), 10), int(n)) not in cache]
        if env is None and todo:
            _batched_candidates(config, seeds, todo, int(n), cache)
        for t in targets:
            key = (round(float(t), 10), int(n))
            if key not in cache:
                s = score(env, LinearRamp(key[0], key[1], config), seeds)
                cache[key] = Candidate(key[0], key[1], s["success_rate"], s["damage_rate"], s["slip_rate"],
                                       s["mean_return"], s["success"], s["stiffness"], s["curvature"])
            out.append(cache[key])
            if bar is not None:
                bar.update()
    return out


def _batched_candidates(config: EnvConfig, seeds: Sequence[int], targets: Sequence[float], n_steps: int,
                        cache: dict) -> None:
    from agents.batch import ramp_grid

    keys = [round(float(t), 10) for t in targets]
    g = ramp_grid(config, seeds, keys, n_steps)
    o = g.outcome
    for i, t in enumerate(keys):
        cache[(t, n_steps)] = Candidate(t, n_steps, float(o.success[i].mean()), float(o.damaged[i].mean()),
                                        float(o.dropped[i].mean()), float(o.returns[i].mean()), o.success[i].copy(),
                                        o.stiffness, o.curvature)


def best_candidate(cands: Sequence[Candidate]) -> Candidate:
    """Highest success; then highest mean return; then the middle of the tied plateau (by target, then steps)."""
    top = max(c.success_rate for c in cands)
    tied = [c for c in cands if c.success_rate >= top - 1e-12]
    top_ret = max(c.mean_return for c in tied)
    tied = sorted({(c.target, c.n_steps): c for c in tied if c.mean_return >= top_ret - 1e-9}.values(),
                  key=lambda c: (c.target, c.n_steps))
    return tied[(len(tied) - 1) // 2]


def make_env(config: EnvConfig, gripper: str):
    """The env a search runs on: ``PneuNetGrasp-v0`` (``gripper="pneunet"``) or ``RigidGrasp-v0``."""
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v0)

    if gripper == "rigid":
        return gym.make("RigidGrasp-v0", config=config)
    if gripper != "pneunet":
        raise ValueError(f"gripper must be 'pneunet' or 'rigid', got {gripper!r}")
    return gym.make("PneuNetGrasp-v0", config=config)


def search_ramp(config: EnvConfig | None = None, gripper: str = "pneunet", n_objects: int = 200, seed: int = 0,
                targets: Sequence[float] = COARSE_TARGETS, durations: Sequence[int] = DURATIONS,
                refine: float = 0.005, progress: bool | None = None,
                batched: bool = True) -> tuple[Candidate, list[Candidate]]:
    """The best ramp over ``n_objects`` seeded objects: a grid over ``targets`` x ``durations``, then a grid of
    spacing ``refine`` around the best target (``0`` skips it). Returns ``(best, every candidate scored)``.

    The pressure ramps are scored batched (:mod:`agents.batch`; ``batched=False``: one episode at a time, the old
    path, kept to time against); the rigid jaw, which has no vector env, episode by episode."""
    config = EnvConfig() if config is None else config
    if int(n_objects) != n_objects or n_objects < 1:
        raise ValueError(f"n_objects must be an integer >= 1, got {n_objects!r}")
    targets = sorted({float(t) for t in targets})
    if not targets or targets[0] <= 0.0 or targets[-1] > 1.0:
        raise ValueError(f"targets must lie in (0, 1], got {targets!r}")
    durations = sorted({int(n) for n in durations})
    if not durations or durations[0] < 1:
        raise ValueError(f"durations must be integers >= 1, got {durations!r}")
    env = make_env(config, gripper) if gripper == "rigid" or not batched else None
    seeds = object_seeds(n_objects, seed)
    spacing = float(min(np.diff(targets))) if len(targets) > 1 else 0.0
    bar = progress_bar(total=len(durations) * len(targets), desc=f"search {gripper}", unit="ramp", enabled=progress)
    cache: dict = {}
    best = best_candidate(grid_search(env, config, seeds, targets, durations, bar, cache))
    if refine > 0 and spacing > refine:
        lo, hi = max(refine, best.target - spacing), min(1.0, best.target + spacing)
        fine = [float(t) for t in np.arange(lo, hi + refine / 2, refine) if 0.0 < t <= 1.0]
        bar.total += len(fine) * len(durations)
        bar.refresh()
        grid_search(env, config, seeds, fine, durations, bar, cache)
        best = best_candidate(list(cache.values()))
    bar.close()
    if env is not None:
        env.close()
    return best, list(cache.values())


def save_best(best: Candidate, path: Path, config: EnvConfig, gripper: str, n_objects: int, seed: int,
              overrides: dict[str, Any], elapsed: float) -> Path:
    """Write the found ramp (with its score and how it was found) as JSON.

    The schedule is defined in physical units (:func:`agents.scripted.ramp_target`): ``target_kpa`` and the
    ``max_pressure_kpa`` its ``target`` is a fraction of (``target_mm`` and ``jaw_travel_mm`` for the jaw), so that a
    config with another maximum runs the same kPa, and an edit of one target that the other contradicts is refused."""
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    meta: dict[str, Any] = {"gripper": gripper}
    if gripper == "rigid":
        travel = default_jaw_travel_mm(config)
        meta.update(target_mm=best.target * travel, jaw_travel_mm=travel)
    else:
        meta.update(target_kpa=best.target * config.task.max_pressure_kpa,
                    max_pressure_kpa=config.task.max_pressure_kpa)
    meta.update(
        search={"objects": n_objects, "seed": seed, "episode_seeds": "seed * 1000003 + i",
                "objective": "success rate over the env's object distribution; ties: mean return, then the "
                             "middle of the plateau",
                "config_overrides": overrides, "elapsed_s": round(elapsed, 2)},
        score=best.summary(config),
        created_by=f"python -m agents.search --gripper {gripper} --objects {n_objects} --seed {seed}",
    )
    data = {**LinearRamp(best.target, best.n_steps, config).to_dict(), **meta}  # save_ramp's form, written whole
    with deferred_interrupt():
        return atomic_write_json(path, data, default=jsonable)


# ---------------------------------------------------------------------------------------------
# Sensitivity study of the thresholds (NOT the env's defaults)
# ---------------------------------------------------------------------------------------------


def strain_crush_fraction(config: EnvConfig | None = None) -> float:
    """The ``crush_fraction`` that makes ``delta > crush_fraction H`` the hoop-strain rule ``delta kappa_obj > eps_f``.

    Eq. 3.2's object is a thin ring; its indentation is a radial shrink of the whole ring, whose hoop strain is
    ``delta kappa_obj``. At the middle of the config's ranges: ``eps_f / (H kappa_obj)`` (7.5 at the paper's
    object: 0.3 / (10 mm x 4 /m)).
    """
    c = load_config(**PAPER_TASK) if config is None else config  # the paper task's ranges
    mid = lambda r: 0.5 * (r[0] + r[1])  # noqa: E731
    o = c.objects
    return mid(o.object_failure_strain) / (mid(o.object_thickness_mm) * 1e-3 * mid(o.object_curvature_per_m))


_STRAIN = strain_crush_fraction()

SENSITIVITY_SETTINGS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("default", "default: rho 1000 kg/m^3, mu_f 0.5, crushed at delta > H", {}),
    ("rho100", "dense foam: rho 100", {"object_density_kg_m3": 100.0}),
    ("rho30", "light foam: rho 30", {"object_density_kg_m3": 30.0}),
    ("muf1", "dry silicone friction: mu_f 1.0", {"friction_coefficient": 1.0}),
    ("strain", f"hoop-strain crush: delta kappa_obj > 0.3 (crush_fraction {_STRAIN:g})",
     {"crush_fraction": _STRAIN}),
    ("rho100+strain", "rho 100 + hoop-strain crush", {"object_density_kg_m3": 100.0, "crush_fraction": _STRAIN}),
    ("rho30+strain", "rho 30 + hoop-strain crush", {"object_density_kg_m3": 30.0, "crush_fraction": _STRAIN}),
    ("rhomix+strain", "rho 30-1000 (log-uniform) + hoop-strain crush",
     {"object_density_kg_m3": [30.0, 1000.0], "crush_fraction": _STRAIN}),
    ("rho30+strain+size", "rho 30 + hoop-strain crush + object size +-10 % (kappa_obj 3.6-4.4 /m)",
     {"object_density_kg_m3": 30.0, "crush_fraction": _STRAIN, "object_curvature_per_m": [3.6, 4.4]}),
)
"""``(key, description, config overrides)``: the threshold settings of the sensitivity study."""


def sensitivity_study(out: Path, settings=SENSITIVITY_SETTINGS, n_objects: int = 120, grid: int = 25,
                      episodes: int = 1, seed: int = 0, progress: bool | None = None,
                      log: Callable[[str], Any] = print) -> list[dict[str, Any]]:
    """For each setting: search best-ramp and rigid, evaluate them and the oracle on a grid; write the outputs.

    Settings whose object properties are ranges get ``max(episodes, 4)`` episodes per grid point.
    """
    from agents.evaluate import SOFT_MAX, STIFF_MIN, evaluate_policies, regime_summary, stiffness_grid
    from agents.oracle import Oracle, feasible_stiffness
    from agents.policies import PolicyEntry
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    coarse = tuple(round(0.05 * i, 4) for i in range(1, 21))
    durations = (1, 25, 50)
    results = []
    paper = load_config(None, **PAPER_TASK)
    log(f"the threshold sensitivity study of the paper's task ({task_description(paper)}; by default "
        f"{damage_rule_text(paper)}); success on the paper's k~ bins, soft (k~ < {SOFT_MAX:g}) and stiff "
        f"(k~ >= {STIFF_MIN:g}), per setting:")
    for key, desc, overrides in settings:
        t0 = time.perf_counter()
        config = load_config(None, **{**PAPER_TASK, **overrides})  # a study of the paper's task
        best_p, _ = search_ramp(config, "pneunet", n_objects, seed, coarse, durations, 0.01, progress)
        best_r, _ = search_ramp(config, "rigid", n_objects, seed, coarse, durations, 0.01, progress)
        travel = default_jaw_travel_mm(config)
        entries = [
            PolicyEntry("best-ramp", f"best-ramp ({best_p.target * config.task.max_pressure_kpa:.3g} kPa, "
                        f"{best_p.n_steps} steps)", LinearRamp(best_p.target, best_p.n_steps, config)),
            PolicyEntry("oracle", "oracle", Oracle(config), blind=False),
            PolicyEntry("rigid", f"rigid ({best_r.target * travel:.3g} mm, {best_r.n_steps} steps)",
                        LinearRamp(best_r.target, best_r.n_steps, config), env_id="RigidGrasp-v0", command="jaw"),
        ]
        ranged = any(isinstance(v, list) for v in overrides.values())
        ks = stiffness_grid(config, grid)
        rows = evaluate_policies(entries, config, ks, max(episodes, 4) if ranged else episodes, seed, progress)
        reg = regime_summary(rows)
        res = {
            "key": key, "description": desc, "overrides": overrides,
            "feasible_stiffness": feasible_stiffness(config),
            "best_ramp": {"target_kpa": best_p.target * config.task.max_pressure_kpa, "n_steps": best_p.n_steps,
                          "search_success_rate": best_p.success_rate},
            "rigid": {"target_mm": best_r.target * travel, "n_steps": best_r.n_steps,
                      "search_success_rate": best_r.success_rate, "jaw_travel_mm": travel},
            "regimes": reg, "rows": rows, "elapsed_s": time.perf_counter() - t0,
        }
        results.append(res)
        rate = lambda p, g: _pct(reg[p][g]["success_rate"])  # noqa: E731, B023
        log(f"{key:>18}: best-ramp {res['best_ramp']['target_kpa']:5.1f} kPa soft {rate('best-ramp', 'soft')} stiff "
            f"{rate('best-ramp', 'stiff')} | oracle soft {rate('oracle', 'soft')} stiff {rate('oracle', 'stiff')} | "
            f"rigid {res['rigid']['target_mm']:5.1f} mm soft {rate('rigid', 'soft')} stiff {rate('rigid', 'stiff')}"
            f"  ({res['elapsed_s']:.0f} s)")
    out.mkdir(parents=True, exist_ok=True)
    meta = {"note": "a sensitivity study of the damage/slip thresholds; NOT the environment's defaults",
            "objects_per_search": n_objects, "stiffness_grid": grid, "episodes": episodes, "seed": seed}
    with deferred_interrupt():
        atomic_write_json(out / "sensitivity.json", {"meta": meta, "settings": results})
        atomic_write_text(out / "sensitivity.md", sensitivity_table(results))
    plot_sensitivity(results, out / "sensitivity.png")
    return results


def _pct(x: float | None) -> str:
    """A rate as ``" 95%"``, or ``"   -"`` where there were no objects."""
    return "   -" if x is None else f"{x:4.0%}"


def sensitivity_table(results) -> str:
    """A markdown table: per setting, success on soft / stiff objects for best-ramp, oracle and rigid."""
    lines = [
        "| setting | feasible from k~ | best-ramp | best-ramp soft / stiff | oracle soft / stiff | rigid | "
        "rigid soft / stiff |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        reg = r["regimes"]
        pct = lambda p, g: _pct(reg[p][g]["success_rate"]).strip()  # noqa: E731, B023
        lines.append(
            f"| {r['description']} | {r['feasible_stiffness']:.2g} | {r['best_ramp']['target_kpa']:.3g} kPa, "
            f"{r['best_ramp']['n_steps']} steps | {pct('best-ramp', 'soft')} / {pct('best-ramp', 'stiff')} | "
            f"{pct('oracle', 'soft')} / {pct('oracle', 'stiff')} | {r['rigid']['target_mm']:.3g} mm | "
            f"{pct('rigid', 'soft')} / {pct('rigid', 'stiff')} |"
        )
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------
# Command line: python -m agents.search
# ---------------------------------------------------------------------------------------------


SEARCH_DEFAULTS = {"gripper": "pneunet", "objects": 200, "targets": list(COARSE_TARGETS),
                   "durations": list(DURATIONS), "refine": 0.005}
"""The search's defaults (its options default to ``None``, so that an option given is seen)."""
SENSITIVITY_OBJECTS = 120
"""``--sensitivity``'s objects per search (default)."""
SENSITIVITY_GRID = 25
"""``--sensitivity``'s stiffness grid (default)."""
PROG = "pneunet-grasp search"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gripper", choices=("pneunet", "rigid"), default=None,
                        help="pneunet: the best-ramp policy (default); rigid: the rigid gripper's jaw ramp")
    parser.add_argument("--objects", type=count, default=None,
                        help=f"objects (seeded episodes) per candidate (default {SEARCH_DEFAULTS['objects']}; "
                             f"with --sensitivity {SENSITIVITY_OBJECTS})")
    parser.add_argument("--seed", type=seed_type, default=0, help="base seed of the objects (default 0)")
    parser.add_argument("--targets", type=real(0, 1, above=True), nargs="+", default=None,
                        help="coarse grid of targets, fractions of p_max or of the jaw travel (default 0.025 .. 1)")
    parser.add_argument("--durations", type=integer(1, 1_000_000, "--durations"), nargs="+", default=None,
                        help=f"ramp durations in steps (default {' '.join(map(str, DURATIONS))})")
    parser.add_argument("--refine", type=real(0, 1), default=None,
                        help="spacing of the fine grid around the best target (default 0.005; 0: none)")
    parser.add_argument("--out", type=output_file, default=None,
                        help="where to write the result (default agents/best_ramp.json or agents/best_rigid.json); "
                             "with --sensitivity, the output directory")
    parser.add_argument("--plot", type=output_file, default=None, help="also plot success vs target to this PNG")
    parser.add_argument("--config", default=None, help="environment config YAML (default: the env's defaults)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key (repeatable; VALUE is YAML)")
    parser.add_argument("--sensitivity", action="store_true",
                        help="run the threshold sensitivity study of the paper's task instead (writes "
                             "sensitivity.{json,md,png} to --out; takes --objects, --seed, --grid, --out only)")
    parser.add_argument("--grid", type=integer(2, 10_000, "--grid"), default=None,
                        help=f"--sensitivity only: stiffness grid size (default {SENSITIVITY_GRID})")
    parser.add_argument("--force", action="store_true",
                        help="take over the output's lock even if the process holding it looks alive (only when you "
                             "know it is gone; a lock of a dead process on this host is taken over without it)")
    add_progress_argument(parser, "--quiet")


def _given_search_options(args: argparse.Namespace) -> list[str]:
    """The search's own options that were given (``--sensitivity`` ignores them: an error)."""
    flags = [f"--{k}" for k in SEARCH_DEFAULTS if k != "objects" and getattr(args, k) is not None]
    flags += [flag for flag, given in (("--plot", args.plot is not None), ("--config", args.config is not None),
                                       ("--set", bool(args.overrides))) if given]
    return flags


def run(args: argparse.Namespace) -> int:
    from agents.policies import _beside_path, tuned_path
    from pneunet_env.extras import require_extra

    if args.sensitivity:
        given = _given_search_options(args)
        if given:
            usage_error(PROG, f"--sensitivity studies the paper's task with its own settings, so "
                              f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} not apply; it takes "
                              "--objects, --seed, --grid and --out")
        require_extra("search", "matplotlib", "plot", "the sensitivity study's sensitivity.png")
        out = Path("docs/img/results") if args.out is None else args.out
        with RunLock(out, command=" ".join([PROG, "--sensitivity", "--out", str(out)]),
                     force=getattr(args, "force", False), what="output folder"):
            sensitivity_study(out, n_objects=SENSITIVITY_OBJECTS if args.objects is None else args.objects,
                              grid=SENSITIVITY_GRID if args.grid is None else args.grid, seed=args.seed,
                              progress=args.progress)
        print(f"wrote {out / 'sensitivity.json'}, {out / 'sensitivity.md'}, {out / 'sensitivity.png'}")
        return 0
    if args.grid is not None:
        usage_error(PROG, "--grid is the sensitivity study's stiffness grid: add --sensitivity, or leave it out")
    for key, default in SEARCH_DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, default)
    if args.plot is not None:
        require_extra("search", "matplotlib", "plot", f"--plot {args.plot}")
    try:
        overrides = parse_overrides(args.overrides)
        config = load_config(args.config, **overrides)
    except ValueError as exc:
        raise SystemExit(f"{PROG}: {exc}") from None
    print(f"{PROG}: the best blind {'jaw' if args.gripper == 'rigid' else 'pressure'} ramp over {args.objects} "
          f"objects of {task_description(config)}")
    print(f"  {damage_rule_text(config)}")
    print(f"  {regime_text(config)}")
    # A config file's search lands beside it (DIR/NAME.best_ramp.json, where demo and evaluate look for it), never
    # over the package's own schedule for the default or the paper's task, which only a search without --config writes.
    out = args.out or (_beside_path(args.config, args.gripper) if args.config is not None
                       else tuned_path(config, args.gripper))
    with RunLock(out, file=True, command=f"{PROG} --gripper {args.gripper} --out {out}",
                 force=getattr(args, "force", False)):  # one search writes it at a time; nothing until the end
        try:
            t0 = time.perf_counter()
            best, cands = search_ramp(config, args.gripper, args.objects, args.seed, args.targets, args.durations,
                                      args.refine, progress=args.progress)
        except ValueError as exc:
            raise SystemExit(f"{PROG}: {exc}") from None
        elapsed = time.perf_counter() - t0
        save_best(best, out, config, args.gripper, args.objects, args.seed,
                  {**({"config": str(args.config)} if args.config else {}), **overrides}, elapsed)
    s = best.summary(config)
    unit = "of the jaw travel" if args.gripper == "rigid" else "of p_max"
    regimes = rate_parts([("force-controlled", s["success_rate_force"], s["objects_force"]),
                          ("position-controlled", s["success_rate_position"], s["objects_position"])])
    print(f"best {args.gripper} ramp: target {best.target:.4g} {unit}, {best.n_steps} steps: success "
          f"{s['success_rate']:.1%} ({regimes}), damaged {s['damage_rate']:.1%}, slipped "
          f"{s['slip_rate']:.1%}; {len(cands)} candidates x {args.objects} objects in {elapsed:.0f} s")
    if args.gripper == "pneunet" and best.target >= max(args.targets) - 1e-12:
        if max(args.targets) >= 1.0 - 1e-12:
            print(f"note: the best target is the top of the range ({config.task.max_pressure_kpa:g} kPa): more "
                  "pressure may do better; raise it with --set max_pressure_kpa=... (a stiffer elastomer needs more)")
        else:
            print(f"note: the best target is the largest of --targets ({max(args.targets):g} of p_max): a higher "
                  "one may do better")
    print(f"wrote {out}")
    if args.plot is not None:
        plot_search(cands, best, args.plot, config, args.gripper)
        print(f"wrote {args.plot}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.search``: as ``pneunet-grasp search``; Ctrl-C ends it with one line and exit status 130
    (nothing is written before the search ends, and each output is written whole)."""
    parser = argparse.ArgumentParser(prog="python -m agents.search", description=__doc__.split("\n\n")[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except KeyboardInterrupt:
        release_held()  # a lock whose with-statement's exit the interrupt cut at its start
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
