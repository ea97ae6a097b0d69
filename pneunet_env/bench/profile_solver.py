"""Profile the quasi-static solve: time per solve on each entry point, and where the iterations go.

Run ``python -m pneunet_env.bench.profile_solver [--quick] [--dp 0.02] [--json PATH]``. It prints one
table of figures (no thresholds: timings are noisy; the speed benchmark ``pneunet-grasp bench speed``
compares the env against CartPole). The workload is env-like: equilibria at random pressures
``p~ ~ U(0, 1.2)`` for random objects (15 % free, else ``k~_obj`` log-uniform in ``[1e-5, 1e-1]``,
``w kappa_obj = 0.02``), each stepped by ``dp~ ~ U(-dp, dp)`` (clipped to ``[0, 1.2]``).

Rows:

* ``solve_equilibrium``: the public API, validation and an :class:`~pneunet_env.physics.solver.Equilibrium` included.
* ``step_state``: the compiled continuation called from Python (what an env's step can call).
* ``step_state, p1 = p0``: the warm start alone (one energy evaluation at the previous equilibrium).
* ``numba call overhead``: an empty compiled function with the same arguments.
* ``solve_batch[numba|numpy] N=...``: the batched solver, per env.
* ``snap``: one step across the fold of ``k~_obj = 1e-4`` (``p~`` 0.66 -> 0.70).

Energy evaluations per solve are the solver's own counter (``Equilibrium.evaluations``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable

import numpy as np

from pneunet_env.files import atomic_write_text
from pneunet_env.physics import batched, solver
from pneunet_env.physics._jit import HAVE_NUMBA

__all__ = ["workload", "count_evaluations", "profile", "main"]

P_MAX = 1.2
KO = 0.02


def workload(n: int, dp: float, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` env-like steps from equilibria (see the module docstring), as arrays."""
    rng = np.random.default_rng(seed)
    kobj = np.where(rng.random(n) < 0.15, 0.0, 10.0 ** rng.uniform(-5.0, -1.0, n))
    p0 = rng.uniform(0.0, P_MAX, n)
    start = batched.solve_batch(np.zeros(n), np.zeros(n), 0.0, p0, kobj, KO)
    p1 = np.clip(p0 + rng.uniform(-dp, dp, n), 0.0, P_MAX)
    return {"kappa": start.curvature, "side_strain": start.side_strain, "p0": p0, "p1": p1, "kobj": kobj}


def count_evaluations(w: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Energy evaluations of each of the first ``n`` steps: the solver's own work counter
    (:attr:`~pneunet_env.physics.solver.Equilibrium.evaluations`; a test checks it against a pure-Python count)."""
    r = batched.solve_batch(w["kappa"][:n], w["side_strain"][:n], w["p0"][:n], w["p1"][:n], w["kobj"][:n], KO)
    return np.asarray(r.evaluations, dtype=np.int64)


def _per_call(fn: Callable[[], object], calls: int, repeat: int = 3) -> float:
    """Best-of-``repeat`` seconds of ``fn()`` (which makes ``calls`` solves), per solve."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best / calls


def profile(quick: bool = False, dp: float = 0.02, seed: int = 0) -> dict:
    """Measure; return ``{"rows": [(name, us_per_solve, note)], "iterations": {...}, ...}``."""
    t = time.perf_counter()
    solver.solve_equilibrium(0.3, 1e-4)  # compiles on a process's first call (numba)
    first_call = time.perf_counter() - t
    m = 2000 if quick else 20000
    w = workload(m, dp, seed)
    k, s, p0, p1, kobj = w["kappa"], w["side_strain"], w["p0"], w["p1"], w["kobj"]
    prm, opts = solver.params_tuple(None), solver.DEFAULT_OPTIONS.as_tuple()
    ks, ss, p0s, p1s, kobjs = (a.tolist() for a in (k, s, p0, p1, kobj))
    idx = range(m)
    rows: list[tuple[str, float, str]] = []

    eqs = [solver.Equilibrium(p0s[i], ks[i], ss[i], 0.0, 0.0, 0.0, False, 0.0, 0.0, 0.0, 1.0, True, 0, 0, False,
                              "converged", kobjs[i], KO) for i in idx]
    solve = solver.solve_equilibrium

    def api():
        for i in idx:
            solve(p1s[i], kobjs[i], KO, None, eqs[i])

    rows.append(("solve_equilibrium", _per_call(api, m) * 1e6, "public API: validation + Equilibrium"))
    step = solver.step_state

    def entry():
        for i in idx:
            step(ks[i], ss[i], p0s[i], p1s[i], prm, kobjs[i], KO, opts)

    note = "compiled entry from Python" if HAVE_NUMBA else "pure Python"
    rows.append(("step_state", _per_call(entry, m) * 1e6, note))

    def warm():
        for i in idx:
            step(ks[i], ss[i], p0s[i], p0s[i], prm, kobjs[i], KO, opts)

    rows.append(("step_state, p1 = p0", _per_call(warm, m) * 1e6, "the warm start alone (polish at p0)"))
    if HAVE_NUMBA:
        import numba

        empty = numba.njit(lambda k, s, a, b, prm, kobj, ko, opts: k)

        def call():
            for i in idx:
                empty(ks[i], ss[i], p0s[i], p1s[i], prm, kobjs[i], KO, opts)

        rows.append(("numba call overhead", _per_call(call, m) * 1e6, "empty compiled function, same arguments"))

    sizes = (1, 64, 1024, 16384)
    backends = (["numba"] if HAVE_NUMBA else []) + ["numpy"]
    for backend in backends:
        variants = [("serial", False), ("parallel", True)] if backend == "numba" else [("", None)]
        for label, parallel in variants:
            for n in sizes:
                if n > m:
                    reps = int(math.ceil(n / m))
                    cols = [np.tile(a, reps)[:n] for a in (k, s, p0, p1, kobj)]
                else:
                    cols = [np.ascontiguousarray(a[:n]) for a in (k, s, p0, p1, kobj)]
                ko = np.full(n, KO)
                act = np.ones(n, dtype=bool)
                if backend == "numba":
                    def run(cols=cols, ko=ko, act=act, parallel=parallel):
                        return batched.solve_batch_numba(*cols, ko, prm, opts, act, parallel=parallel)
                else:
                    def run(cols=cols, ko=ko, act=act):
                        return batched.solve_batch_numpy(*cols, ko, prm, opts, act)
                if backend == "numpy" and quick and n > 1024:
                    continue
                inner = max(1, (20000 if backend == "numba" else 2000) // n)
                if quick:
                    inner = max(1, inner // 10)

                def many(run=run, inner=inner):
                    for _ in range(inner):
                        run()

                us = _per_call(many, inner * n, repeat=2 if backend == "numpy" else 3) * 1e6
                rows.append((f"solve_batch[{backend}{', ' + label if label else ''}] N={n}", us, "per env"))

    # One step across the fold.
    before = solver.solve_equilibrium(0.66, 1e-4)
    snap = solver.step_state(before.curvature, before.side_strain, 0.66, 0.70, prm, 1e-4, KO, opts)
    us = _per_call(lambda: solver.step_state(before.curvature, before.side_strain, 0.66, 0.70, prm, 1e-4, KO, opts),
                   1) * 1e6
    rows.append(("snap (k~=1e-4, p~ 0.66->0.70)", us, f"{snap[5]} iterations, {snap[6]} sub-steps, snapped={snap[7]}"))

    r = batched.solve_batch(k, s, p0, p1, kobj, KO)
    evals = count_evaluations(w, min(m, 2000))
    its = r.iterations
    stats = {
        "iterations_mean": float(its.mean()),
        "iterations_median": float(np.median(its)),
        "iterations_p99": float(np.percentile(its, 99)),
        "iterations_max": int(its.max()),
        "substeps_mean": float(r.substeps.mean()),
        "evaluations_mean": float(evals.mean()),
        "evaluations_median": float(np.median(evals)),
        "snapped_fraction": float(r.snapped.mean()),
        "converged_fraction": float(r.converged.mean()),
        "worst_gradient_norm": float(r.gradient_norm.max()),
    }
    return {"rows": rows, "stats": stats, "first_call_s": first_call, "numba": HAVE_NUMBA, "dp": dp, "steps": m}


def _print(result: dict) -> None:
    st = result["stats"]
    print(f"workload: {result['steps']} env-like steps, dp~ ~ U(-{result['dp']}, {result['dp']}); "
          f"numba {'on' if result['numba'] else 'off'}; first solve in this process {result['first_call_s']:.2f} s")
    print(f"iterations per solve: mean {st['iterations_mean']:.2f}, median {st['iterations_median']:.0f}, "
          f"p99 {st['iterations_p99']:.0f}, max {st['iterations_max']}; sub-steps mean {st['substeps_mean']:.2f}")
    print(f"energy evaluations per solve: mean {st['evaluations_mean']:.2f}, median {st['evaluations_median']:.0f}; "
          f"snapped {100 * st['snapped_fraction']:.2f} %, converged {100 * st['converged_fraction']:.1f} %, "
          f"worst |grad| {st['worst_gradient_norm']:.1e}")
    width = max(len(r[0]) for r in result["rows"])
    print(f"{'entry point':<{width}}  {'us/solve':>9}  note")
    for name, us, note in result["rows"]:
        print(f"{name:<{width}}  {us:9.3f}  {note}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pneunet_env.bench.profile_solver",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (seconds instead of a minute)")
    parser.add_argument("--dp", type=float, default=0.02, help="largest |pressure step| dp~ (default 0.02)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.dp) and args.dp > 0):
        raise SystemExit(f"--dp must be a positive number, got {args.dp}")
    result = profile(args.quick, args.dp, args.seed)
    _print(result)
    if args.json:
        atomic_write_text(args.json, json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
