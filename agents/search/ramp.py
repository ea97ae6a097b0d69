"""The best-ramp search: one blind schedule, tuned once over the object distribution, fixed for all objects.

:func:`search_ramp` grid-searches :class:`agents.policies.scripted.LinearRamp`'s two parameters, the target
(a fraction of ``p_max``; for the rigid gripper, of its jaw travel) and the ramp duration (steps from 0 to the
target), maximising the success rate over ``--objects`` objects drawn from the env's object distribution with
fixed seeds (``reset(seed=seed * 1_000_003 + i)``, the same objects for every candidate). It runs the env
itself (``PneuNetGrasp-v1`` or ``RigidGrasp-v1``), so the score is exactly the env's. A coarse grid comes first,
then a finer one around the best target. Ties (common: a plateau of equally good targets) go to the higher mean
return (a gentler failure: a late slip costs less than a crush), then to the middle of the tied plateau.

The result is written to ``agents/best_ramp.json`` (``--gripper pneunet``, the ``best-ramp`` policy) or
``agents/best_rigid.json`` (``--gripper rigid``, the ``rigid`` policy), so both are fixed, reproducible policies.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.evaluation.episodes import run_episode
from agents.policies.scripted import LinearRamp, jsonable
from pneunet_env.config import EnvConfig
from pneunet_env.files import atomic_write_json, deferred_interrupt
from pneunet_env.progress import progress as progress_bar

__all__ = ["COARSE_TARGETS", "DURATIONS", "ALL_DURATIONS", "Candidate", "object_seeds", "score", "grid_search",
           "best_candidate", "make_env", "search_ramp", "save_best"]


COARSE_TARGETS = tuple(round(0.025 * i, 4) for i in range(1, 41))  # 0.025 .. 1.0


DURATIONS = (20, 60, 80)
"""Ramp durations searched (steps from 0 to the target). Every duration that ends inside the 50-step squeeze phase
gives the same outcome, object for object (the model is quasi-static: measured by
:func:`agents.evaluation.batch.duration_invariance` over the 40 coarse targets x 200 objects, durations 1, 10, 20, 30,
40 and 50 differ in 0 of 8,000 pairs), so one of them, 20, stands for all; 60 and 80 reach the target in the hold phase
and differ (735 and 2,361 pairs)."""


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
        (:func:`agents.common.regimes.regime_rates`: force-controlled, position-controlled; the paper ring's ``k~``
        thresholds would class every hand-scale object as stiff). For the rigid jaw too, the regime is the
        pneu-net's on the same object."""
        from agents.common.regimes import regime_rates

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

    ``env=None`` scores the pressure ramps batched (:func:`agents.evaluation.batch.ramp_grid`: every target of one
    duration on every object as one vector env run, object for object the single env's outcome); an env (the rigid
    jaw's) runs episode by episode."""
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
    from agents.evaluation.batch import ramp_grid

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
    """The env a search runs on: ``PneuNetGrasp-v1`` (``gripper="pneunet"``) or ``RigidGrasp-v1``."""
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v1)

    if gripper == "rigid":
        return gym.make("RigidGrasp-v1", config=config)
    if gripper != "pneunet":
        raise ValueError(f"gripper must be 'pneunet' or 'rigid', got {gripper!r}")
    return gym.make("PneuNetGrasp-v1", config=config)


def search_ramp(config: EnvConfig | None = None, gripper: str = "pneunet", n_objects: int = 200, seed: int = 0,
                targets: Sequence[float] = COARSE_TARGETS, durations: Sequence[int] = DURATIONS,
                refine: float = 0.005, progress: bool | None = None,
                batched: bool = True) -> tuple[Candidate, list[Candidate]]:
    """The best ramp over ``n_objects`` seeded objects: a grid over ``targets`` x ``durations``, then a grid of
    spacing ``refine`` around the best target (``0`` skips it). Returns ``(best, every candidate scored)``.

    The pressure ramps are scored batched (:mod:`agents.evaluation.batch`; ``batched=False``: one episode at a time, the
    old path, kept to time against); the rigid jaw, which has no vector env, episode by episode."""
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

    The schedule is defined in physical units (:func:`agents.policies.scripted.ramp_target`): ``target_kpa`` and the
    ``max_pressure_kpa`` its ``target`` is a fraction of (``target_mm`` and ``jaw_travel_mm`` for the jaw), so that a
    config with another maximum runs the same kPa, and an edit of one target that the other contradicts is refused."""
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    meta: dict[str, Any] = {"gripper": gripper}
    if gripper == "rigid":
        travel = default_jaw_travel_mm(config)
        meta.update(target_mm=_clean(best.target * travel), jaw_travel_mm=travel)
    else:
        meta.update(target_kpa=_clean(best.target * config.task.max_pressure_kpa),
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


def _clean(physical: float) -> float:
    """A physical target to 12 significant digits: ``0.585 * 60`` is ``35.1``, not ``35.099999999999994`` (the
    fraction, on a 0.005 grid, is exact to far fewer digits; the loader checks the two agree to 1e-9)."""
    return float(f"{physical:.12g}")
