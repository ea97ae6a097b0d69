"""The solver study's runner: every method on every scene, the stability map, the step-size study and the
``auto`` model's tolerance sweep (``pneunet-grasp bench solvers``; the command line is
:mod:`pneunet_env.bench.solvers`, the charts :mod:`pneunet_env.bench.solver_plots`).

:func:`run_study` returns ``(records, details)``, what ``solvers.json`` and ``solvers_details.json`` hold. Times
are seconds of this machine; states, pressures and errors are dimensionless (``kappa~``, ``e_s``, ``p~``).
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Sequence

import numpy as np

from pneunet_env.bench.models import AUTO_TOLERANCE, equilibrium_for_model
from pneunet_env.bench.solver_methods import (
    BRANCH_TOL,
    CORRECT_TOL,
    FAILURE_TEXT,
    FAILURES,
    OUTCOMES,
    SLOW_FACTOR,
    STATIONARY_TOL,
    AutoMethod,
    Method,
    PackageMethod,
    PathRun,
    Scene,
    classify,
    make_methods,
    make_scenes,
    ramp,
    reference_states,
    solve_path,
    solve_steps,
)
from pneunet_env.physics import mechanics
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.linear import LinearModel, linear_reach, linear_state
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import solve_equilibrium
from pneunet_env.progress import progress as progress_bar

__all__ = ["anchored_ramp", "run_study", "stationarity"]

# ------------------------------------------------------------------------------------------ the study
def _timed_path(method: Method, pressures, k, ko, params, repeats: int) -> PathRun:
    run = solve_path(method, pressures, k, ko, params)
    for _ in range(repeats - 1):  # timing only: keep the fastest pass (the answers are deterministic)
        again = solve_path(method, pressures, k, ko, params)
        if again.seconds.sum() < run.seconds.sum():
            run.seconds = again.seconds
    return run


def _evaluate(method: Method, run: PathRun, pressures, ref, k, ko, params) -> list[tuple[str, float]]:
    return [classify(run.states[i], ref[i], float(p), k, ko, params, method.kind) for i, p in enumerate(pressures)]


def stationarity(states: np.ndarray, scene: Scene) -> tuple[float | None, float | None]:
    """``(max |grad U~|_2, min lambda_min(H))`` of the full energy over the answers inside the domain (``None``
    if there is none): an answer is a converged minimum when ``|grad| <= 1e-10`` and ``lambda_min > 0``."""
    grads, eigs = [], []
    for x, p in zip(states, scene.pressures, strict=True):
        if not np.all(np.isfinite(x)):
            continue
        ok, _, g0, g1, a, b, c, *_ = mechanics.scalar_terms(float(x[0]), float(x[1]), float(p),
                                                             *scene.params.as_tuple(), scene.object_stiffness,
                                                             scene.object_curvature)
        if ok:
            grads.append(math.hypot(g0, g1))
            eigs.append(0.5 * (a + c) - math.hypot(0.5 * (a - c), b))
    return (max(grads), min(eigs)) if grads else (None, None)


def _record(method: Method, scene: Scene, run: PathRun, outcomes: list[tuple[str, float]]) -> dict:
    errors = np.array([e for _, e in outcomes])
    grad, eig = stationarity(run.states, scene)
    kinds = [o for o, _ in outcomes]
    failed = [i for i, o in enumerate(kinds) if o in FAILURES]
    ok = [i for i in range(len(kinds)) if i not in failed]
    return {
        "method": method.name,
        "scene": scene.name,
        "time_s": float(run.seconds.sum() / len(run.seconds)),
        "error": None if np.isnan(errors).any() else float(errors.max()),
        "failure": FAILURE_TEXT[kinds[failed[0]]] if failed else None,
        "default": method.default,
        "kind": method.kind,
        "label": method.label,
        "solves": len(kinds),
        "failed_solves": len(failed),
        "outcomes": {o: kinds.count(o) for o in OUTCOMES if o in kinds},
        "first_failure_pressure": float(scene.pressures[failed[0]]) if failed else None,
        "first_failure_message": run.messages[failed[0]] if failed else None,
        "error_where_not_failed": float(np.max(errors[ok])) if ok else None,
        "evaluations_per_solve": float(run.evaluations.mean()),
        "max_gradient_norm": grad,
        "min_hessian_eigenvalue": eig,
    }


def _fold_window(k: float, ko: float, params: ActuatorParams, p_max: float, dp: float = 1e-3) -> tuple[float, float]:
    """``(p_down, p_up)``: the last pressure still on the upper branch when unloading, and the loading snap.

    Found with the package's continuation on a ``dp`` grid: the bistable window is ``(p_down, p_up)`` to
    within ``dp``.
    """
    from pneunet_env.physics.solver import load_path

    ps = np.round(np.arange(1, int(round(p_max / dp)) + 1) * dp, 10)
    path = load_path(np.concatenate([ps, ps[-2::-1]]), k, ko, params)
    n = len(ps)
    i_up = np.flatnonzero(path.snapped[:n])
    i_down = np.flatnonzero(path.snapped[n:])
    p_up = float(ps[i_up[0]]) if len(i_up) else math.nan
    p_down = float(ps[-2::-1][i_down[0]] + dp) if len(i_down) else math.nan
    return p_down, p_up


def anchored_ramp(anchor: float, p_max: float, dp: float) -> tuple[float, ...]:
    """Load from ``p > 0`` to ``<= p_max`` and back, on the grid ``anchor + j dp`` (which always holds ``anchor``)."""
    j0 = -int(math.floor((anchor - 1e-9) / dp))
    up = [round(anchor + j * dp, 10) for j in range(j0, int(math.floor((p_max - anchor) / dp + 1e-9)) + 1)]
    up = [p for p in up if p > 0.0]
    return tuple(up + up[-2::-1])


def run_study(quick: bool = False, repeats: int | None = None, progress: bool | None = None,
              methods: Sequence[Method] | None = None) -> tuple[list[dict], dict]:
    """Run the whole study; return ``(records, details)`` (what ``solvers.json`` and ``solvers_details.json`` hold).

    ``progress``: bars on stderr; ``None`` (default): when stderr is a terminal.
    """
    repeats = (1 if quick else 3) if repeats is None else repeats
    methods = list(make_methods() if methods is None else methods)
    scenes = make_scenes(quick)
    solve_equilibrium(0.1, 1e-4)  # compile the numba kernels outside the timings
    t_start = time.perf_counter()

    # 1. scenes x methods, each method warm-started from its own previous answer
    refs = {s.name: reference_states(s.pressures, s.object_stiffness, s.object_curvature, s.params)
            for s in progress_bar(scenes, desc="reference paths (mpmath)", enabled=progress)}
    records: list[dict] = []
    tasks = [(m, s) for m in methods for s in scenes]
    for m, s in progress_bar(tasks, desc="methods x scenes", enabled=progress):
        run = _timed_path(m, s.pressures, s.object_stiffness, s.object_curvature, s.params, repeats)
        outcomes = _evaluate(m, run, s.pressures, refs[s.name], s.object_stiffness, s.object_curvature, s.params)
        records.append(_record(m, s, run, outcomes))

    # 2. stability map: pressure x stiffness, one step from the reference's previous equilibrium
    params = ActuatorParams()
    dp_map = 0.1 if quick else 0.05
    map_ps = ramp(2.0, dp_map)
    map_ks = [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0] if quick else [0.0] + [
        float(v) for v in np.logspace(-6, 0, 13)]
    map_refs = {k: reference_states(map_ps, k, 0.02, params)
                for k in progress_bar(map_ks, desc="map reference paths", enabled=progress)}
    grid: dict[str, list[list[str]]] = {}
    evals: dict[str, list[list[int]]] = {}
    tasks2 = [(m, k) for m in methods for k in map_ks]
    for m, k in progress_bar(tasks2, desc="stability map", enabled=progress):
        run = solve_steps(m, map_ps, map_refs[k], k, 0.02, params)
        grid.setdefault(m.name, []).append([o for o, _ in _evaluate(m, run, map_ps, map_refs[k], k, 0.02, params)])
        evals.setdefault(m.name, []).append([int(v) for v in run.evaluations])
    for m in methods:  # "slow": correct, but SLOW_FACTOR times the method's typical effort
        ev = np.array(evals[m.name], dtype=float)
        typical = float(np.median(ev))
        for i, row in enumerate(grid[m.name]):
            for j, o in enumerate(row):
                if o == "correct" and ev[i, j] > SLOW_FACTOR * max(typical, 1.0):
                    row[j] = "slow"

    # 3. step size: the fold scene's loop at increasing pressure increments
    k_fold, p_top = 1e-4, 1.2
    window = _fold_window(k_fold, 0.02, params, p_top)
    anchor = round(0.5 * (window[0] + window[1]), 3)
    steps = [0.05, 0.1, 0.2, 0.4] if quick else [0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4]
    step_rows = []
    tasks3 = [(m, dp) for dp in steps for m in methods]
    for m, dp in progress_bar(tasks3, desc="step sizes", enabled=progress):
        ps = anchored_ramp(anchor, p_top, dp)
        ref = reference_states(ps, k_fold, 0.02, params)
        run = solve_path(m, ps, k_fold, 0.02, params)
        outcomes = _evaluate(m, run, ps, ref, k_fold, 0.02, params)
        errs = np.array([e for _, e in outcomes])
        step_rows.append({
            "method": m.name, "increment": dp, "solves": len(ps),
            "error": None if np.isnan(errs).any() else float(errs.max()),
            "failures": sum(o in FAILURES for o, _ in outcomes),
            "loop": _loop_status(ps, run.states, ref, window),
        })

    # 4. the auto model: what it saves and costs along the scenes, for several tolerances
    auto = _auto_sweep(scenes, refs, repeats, progress)

    details = {
        "quick": quick,
        "repeats": repeats,
        "wall_s": time.perf_counter() - t_start,
        "numba": HAVE_NUMBA,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "thresholds": {"correct": CORRECT_TOL, "stationary": STATIONARY_TOL, "slow_factor": SLOW_FACTOR,
                       "branch": BRANCH_TOL, "auto_tolerance": AUTO_TOLERANCE},
        "linear_valid_until": LinearModel(params).valid_until,
        "scenes": [s.as_dict() for s in scenes],
        "methods": [{"name": m.name, "label": m.label, "kind": m.kind, "default": m.default} for m in methods],
        "map": {"pressures": list(map_ps), "stiffnesses": map_ks, "object_curvature": 0.02, "outcomes": grid,
                "evaluations": evals},
        "step_size": {"object_stiffness": k_fold, "p_max": p_top, "fold_window": list(window), "anchor": anchor,
                      "rows": step_rows},
        "auto": auto,
    }
    return records, details


def _loop_status(ps, states, ref, window) -> str:
    """``captured``, ``missed`` (a point of the loop on the wrong branch) or ``unresolved`` (no pressure inside)."""
    p_down, p_up = window
    inside = [i for i, p in enumerate(ps) if p_down < p < p_up]
    if not inside:
        return "unresolved"
    ok = all(np.all(np.isfinite(states[i])) and np.max(np.abs(states[i] - ref[i])) <= BRANCH_TOL for i in inside)
    return "captured" if ok else "missed"


def _auto_sweep(scenes: list[Scene], refs: dict, repeats: int, progress: bool | None) -> dict:
    """``auto`` against ``full`` (the package's solver) along the scenes, for several tolerances.

    Times are the fastest of ``max(repeats, 5)`` passes, ``full`` and ``auto`` passes interleaved so that both
    see the same machine load.
    """
    from pneunet_env.physics.solver import load_path

    tolerances = sorted({1e-5, 1e-4, 1e-3, 1e-2, AUTO_TOLERANCE})
    passes = max(repeats, 5)
    n_total = sum(len(s.pressures) for s in scenes)
    full = PackageMethod("full", "full")
    rows = []
    for tol in progress_bar(tolerances, desc="auto tolerance sweep", enabled=progress):
        auto = AutoMethod("auto", "auto", tol)
        t_auto, t_full, n_lin, err_ref, per_scene = 0.0, 0.0, 0, 0.0, {}
        for s in scenes:
            args = (s.pressures, s.object_stiffness, s.object_curvature, s.params)
            best_full, best_auto, run = math.inf, math.inf, None
            for _ in range(passes):
                best_full = min(best_full, solve_path(full, *args).seconds.sum())
                run = solve_path(auto, *args)
                best_auto = min(best_auto, run.seconds.sum())
            t_auto += best_auto
            t_full += best_full
            lin = sum(msg == "linear" for msg in run.messages)
            n_lin += lin
            e = float(np.max(np.abs(run.states - refs[s.name])))
            err_ref = max(err_ref, e)
            per_scene[s.name] = {"linear_solves": lin, "solves": len(s.pressures), "error": e,
                                 "time_per_solve_s": best_auto / len(s.pressures),
                                 "full_time_per_solve_s": best_full / len(s.pressures)}
        rows.append({
            "tolerance": tol,
            "linear_fraction": n_lin / n_total,
            "time_per_solve_s": t_auto / n_total,
            "full_time_per_solve_s": t_full / n_total,
            "time_saved_fraction": 1.0 - t_auto / t_full,
            "max_error": err_ref,
            "scenes": per_scene,
        })
    # The linear model alone on the free actuator: its error against the full model, on a fine grid.
    params = ActuatorParams()
    dp = 1e-3
    ps = np.round(np.arange(1, 401) * dp, 10)
    fp = load_path(ps, 0.0, 0.02, params)
    xs = np.column_stack([fp.curvature, fp.side_strain])
    lin = np.array([linear_state(float(p), 0.0, 0.02, params)[:2] for p in ps])
    lin_err = np.max(np.abs(lin - xs), axis=1)
    slope = np.max(np.abs(np.gradient(xs, dp, axis=0)), axis=1)  # |dx/dp|_inf of the full path
    reach, p_equiv = {}, {}
    for t in tolerances:
        i = int(np.flatnonzero(lin_err > t)[0]) - 1 if (lin_err > t).any() else len(ps) - 1
        reach[f"{t:g}"] = float(ps[i])
        p_equiv[f"{t:g}"] = float(lin_err[i] / slope[i])  # the pressure shift that moves the full state as much
    small = ps <= 0.05
    coef = float(np.sum(lin_err[small] * ps[small] ** 2) / np.sum(ps[small] ** 4))  # least squares err = c p^2
    # One step where auto answers with the linear model (p~ 0.04 -> 0.05), against the full solve of it.
    prev = solve_equilibrium(0.04)
    t_lin, t_full = math.inf, math.inf
    for _ in range(passes):
        t0 = time.perf_counter()
        for _ in range(200):
            equilibrium_for_model("auto", 0.05, previous=prev)
        t1 = time.perf_counter()
        for _ in range(200):
            solve_equilibrium(0.05, initial=prev)
        t2 = time.perf_counter()
        t_lin, t_full = min(t_lin, (t1 - t0) / 200), min(t_full, (t2 - t1) / 200)
    return {
        "linear_step_time_s": t_lin,
        "full_step_time_s": t_full,
        "tolerance": AUTO_TOLERANCE,
        "sweep": rows,
        "linear_error_free": {"pressures": ps[::10].tolist(), "error": lin_err[::10].tolist()},
        "linear_reach_free_measured": reach,
        "linear_reach_free_estimated": {f"{t:g}": linear_reach(params, t) for t in tolerances},
        "pressure_equivalent_of_error_at_reach": p_equiv,
        "linear_error_coefficient": coef,
    }
