"""One design's score: the batched grid of blind pressures, its regimes, oracle, window and manufacturing error."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from agents.design.space import (
    FIT_STRETCH,
    MODULUS_ERROR,
    N_ERRORS,
    PRESSURE_ERROR_KPA,
    RAMP_STEPS,
    TARGETS,
    WALL_ERROR,
    WINDOW_POINTS,
    corner_configs,
    design_config,
    elastomers,
    perturbed_config,
    table1_design,
    wall_stretch,
)
from pneunet_env.config import EnvConfig


def _rate(ok: np.ndarray, mask: np.ndarray) -> float:
    return float(ok[mask].mean()) if mask.any() else math.nan


def _regime_rates(ok: np.ndarray, regimes: np.ndarray) -> dict[str, float]:
    from pneunet_env.physics.regimes import FORCE, POSITION

    return {"force": _rate(ok, regimes == FORCE), "position": _rate(ok, regimes == POSITION),
            "all": float(ok.mean())}


@dataclass
class DesignScore:
    """What one design achieves on one object set (rates are fractions; pressures kPa).

    ``blind``, ``oracle`` and ``robust`` are ``{"force", "position", "all"}`` rates by Table 1's regime labels;
    ``blind_own`` by the design's own. ``robust`` is the random draw (one perturbed actuator per object: a second
    figure, it averages the corners away) and ``robust_worst`` its worst single actuator. ``corners`` holds each
    corner's rates (:func:`agents.design.space.corner_configs`, and the blind pressure off by the regulator's error
    either way) and ``worst_corner`` the worst of them, regime by regime: what the design is ranked on.
    ``pressure_kpa`` is the blind pressure: the centre of the window (a robust choice, not the best point,
    ``pressure_best_kpa``). ``wall_stretch`` is the largest wall stretch at it; ``outside_data`` whether that lies
    beyond the stretch the material's fit was made on (``None``: no material data, Table 1's).
    """

    params: dict[str, Any]
    pressure_kpa: float
    target: float
    blind: dict[str, float]
    blind_own: dict[str, float]
    oracle: dict[str, float]
    robust: dict[str, float]
    robust_worst: dict[str, float]
    window_kpa: tuple[float, float]
    window_fraction: float
    objects: dict[str, int]
    by_class: dict[str, dict[str, float]] = field(default_factory=dict)
    rate_vs_pressure: list[float] = field(default_factory=list)
    pressures_kpa: list[float] = field(default_factory=list)
    seconds: float = 0.0
    corners: dict[str, dict[str, float]] = field(default_factory=dict)
    worst_corner: dict[str, float] = field(default_factory=dict)
    pressure_best_kpa: float = math.nan
    pressure_error_kpa: float = PRESSURE_ERROR_KPA
    wall_stretch: float = math.nan
    outside_data: bool | None = None

    @property
    def score(self) -> float:
        """The design's rank value: the worst of its blind and under-error success, by regime (:func:`design_rank`)."""
        return design_rank(self)[0]

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["score"] = self.score
        return d


def design_rank(s: DesignScore) -> tuple[float, float]:
    """``(worst of blind force/position and the worst corner's force/position, window fraction)``: higher is better.

    An empty regime (NaN) does not count; a design that holds nothing scores 0."""
    worst = s.worst_corner or s.robust
    vals = [v for v in (s.blind["force"], s.blind["position"], worst["force"], worst["position"])
            if not math.isnan(v)]
    return (min(vals) if vals else 0.0, s.window_fraction)


def _error_draws(seed: int, n_objects: int) -> tuple[np.ndarray, np.ndarray]:
    """``(factors, assignment)``: :data:`N_ERRORS` rows of (top, side, base, modulus) factors, and which row each
    object meets. The same for every design of a study (common random numbers)."""
    rng = np.random.default_rng([int(seed), 7_919])
    walls = rng.uniform(1 - WALL_ERROR, 1 + WALL_ERROR, size=(N_ERRORS, 3))
    mod = rng.uniform(1 - MODULUS_ERROR, 1 + MODULUS_ERROR, size=(N_ERRORS, 1))
    return np.hstack([walls, mod]), rng.integers(0, N_ERRORS, size=n_objects)


def reference_regimes(seeds: Sequence[int], base: EnvConfig | None = None) -> np.ndarray:
    """Table 1's regime of each object of ``seeds`` (the same physical objects for every design)."""
    from agents.common.regimes import object_regimes
    from agents.evaluation.batch import draw_objects

    cfg = design_config(table1_design(), base)
    obj = draw_objects(cfg, seeds)  # a reset is all it takes
    return object_regimes(obj.stiffness, obj.curvature, cfg)


def evaluate_design(params: Mapping[str, Any], seeds: Sequence[int], reference: np.ndarray,
                    base: EnvConfig | None = None, seed: int = 0, target: float | None = None,
                    backend: str = "auto", parallel: bool | None = None,
                    pressure_error_kpa: float = PRESSURE_ERROR_KPA) -> DesignScore:
    """Score one design on the objects of ``seeds`` (see the module docstring).

    Args:
        params: the design (:func:`design_config`'s).
        seeds: the objects' episode seeds.
        reference: Table 1's regime of each object (:func:`reference_regimes`).
        base: the env config the design changes (its objects and task); the defaults if ``None``.
        seed: the manufacturing-error draws' seed.
        target: evaluate this blind target (a fraction of the design's ``max_pressure_kpa``) instead of choosing
            one: the held-out report uses the schedule found on the search objects.
        pressure_error_kpa: the regulator's error (kPa) the blind pressure is also scored at, either way.
    """
    from agents.common.regimes import object_regimes
    from agents.evaluation.batch import ramp_actions, ramp_grid, run_batch

    t0 = time.perf_counter()
    cfg = design_config(params, base)
    seeds = np.asarray(seeds, dtype=np.int64)
    grid = ramp_grid(cfg, seeds, TARGETS, RAMP_STEPS, backend, parallel)
    o = grid.outcome
    best = grid.best()
    lo, hi = grid.window(best, WINDOW_POINTS)
    if target is None:  # the centre of the window around the best point (on the grid): robust to the regulator
        target = float(grid.targets[int(np.argmin(np.abs(grid.pressure_kpa - (lo + hi) / 2)))])
    i = int(np.argmin(np.abs(grid.targets - target)))
    if abs(grid.targets[i] - target) > 1e-9:
        extra = ramp_grid(cfg, seeds, [target], RAMP_STEPS, backend, parallel).outcome
        ok = extra.success[0]
        t_best = float(target)
    else:
        ok = o.success[i]
        t_best = float(grid.targets[i])
    own = object_regimes(o.stiffness, o.curvature, cfg)
    p_best = t_best * cfg.task.max_pressure_kpa
    # manufacturing error: the same blind schedule (kPa) on perturbed actuators, one per object
    factors, assign = _error_draws(seed, seeds.size)
    hits = np.zeros((N_ERRORS, seeds.size), bool)
    for g, f in enumerate(factors):
        pc = perturbed_config(cfg, f)
        act = ramp_actions(np.full(seeds.size, t_best), RAMP_STEPS, pc)
        hits[g] = run_batch(pc, seeds, act, backend=backend, parallel=parallel).success[0]
    robust_ok = hits[assign, np.arange(seeds.size)]
    worst = [_regime_rates(h, reference) for h in hits]
    # the corners, with the same schedule: walls x modulus, the material's range, the regulator's error
    corners: dict[str, dict[str, float]] = {}
    runs = [(label, pc, t_best) for label, pc in corner_configs(cfg, params.get("elastomer"))]
    for sign in (-1.0, 1.0):
        p = min(max(p_best + sign * pressure_error_kpa, 0.0), cfg.task.max_pressure_kpa)
        runs.append((f"pressure {sign * pressure_error_kpa:+g} kPa", cfg, p / cfg.task.max_pressure_kpa))
    for label, pc, t in runs:
        act = ramp_actions(np.full(seeds.size, t), RAMP_STEPS, pc)
        corners[label] = _regime_rates(run_batch(pc, seeds, act, backend=backend, parallel=parallel).success[0],
                                       reference)
    worst_corner = {k: min((c[k] for c in corners.values() if not math.isnan(c[k])), default=math.nan)
                    for k in ("force", "position", "all")}
    stretch = wall_stretch(cfg, p_best)
    has_data = elastomers().get(params.get("elastomer"))
    outside = None if has_data is None or has_data.gent_limit_range is None else bool(stretch > FIT_STRETCH)
    classes = np.array(o.classes)
    by_class = {c: {"draws": int((classes == c).sum()), "blind": float(ok[classes == c].mean()),
                    "oracle": float(grid.oracle()[classes == c].mean())} for c in dict.fromkeys(o.classes)}
    from pneunet_env.physics.regimes import FORCE, POSITION

    return DesignScore(
        params=dict(params), pressure_kpa=p_best, target=t_best,
        blind=_regime_rates(ok, reference), blind_own=_regime_rates(ok, own),
        oracle=_regime_rates(grid.oracle(), reference), robust=_regime_rates(robust_ok, reference),
        robust_worst={k: min(w[k] for w in worst) for k in ("force", "position", "all")},
        window_kpa=(lo, hi), window_fraction=(hi - lo) / p_best if p_best > 0 else 0.0,
        objects={"all": int(seeds.size), "force": int((reference == FORCE).sum()),
                 "position": int((reference == POSITION).sum()), "own_force": int((own == FORCE).sum()),
                 "own_position": int((own == POSITION).sum())},
        by_class=by_class, rate_vs_pressure=[float(x) for x in grid.rates()],
        pressures_kpa=[float(x) for x in grid.pressure_kpa], seconds=time.perf_counter() - t0,
        corners=corners, worst_corner=worst_corner, pressure_best_kpa=float(grid.pressure_kpa[best]),
        pressure_error_kpa=float(pressure_error_kpa), wall_stretch=stretch, outside_data=outside,
    )
