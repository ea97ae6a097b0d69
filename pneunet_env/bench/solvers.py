"""``pneunet-grasp bench solvers``: the solver study (speed against accuracy, stability map, step size).

Every method solves fixed loading paths (scenes) the way a user would: one solve per pressure, warm-started
from its own previous answer. Each answer is compared with a high-precision reference
(:mod:`pneunet_env.physics.reference`: mpmath, 30 digits, on the quasi-static branch) and classified:

=================  ==============================================================================
outcome            meaning
=================  ==============================================================================
correct            state error ``max(|d kappa~|, |d e_s|) <= 1e-6`` (:data:`CORRECT_TOL`)
slow               (map only) correct, but :data:`SLOW_FACTOR` times the method's median effort
model error        an approximate model (linear, auto) whose answer is off by more than 1e-6
wrong branch       a minimum of the energy, but not the one on the quasi-static path (a jump to
                   another basin), or an unfinished descent heading into another basin
saddle/maximum     a stationary point whose Hessian is not positive definite, accepted as an answer
left the domain    an answer outside the energy's domain (Gent limit, ``kappa~ < 0``, ...)
NaN                a NaN (or an exception) instead of a state
no convergence     stopped short of the reference's minimum (which a safeguarded descent then reaches)
=================  ==============================================================================

The last five are *failures* (``failure`` in ``solvers.json``); "model error" is the accuracy of an
approximation, reported as its ``error``.

Outputs in ``--out``: ``solvers.json`` (records ``{method, scene, time_s, error, failure, default, ...}``),
``solvers_details.json`` (scenes, thresholds, the map, the step-size study, the ``auto`` model's
tolerance sweep), ``speed_accuracy.png``, ``stability_map.png``, ``step_size.png``, each written atomically.

The study is split by concern: :mod:`pneunet_env.bench.solver_methods` (the scenes, the methods, the reference and
the classification), :mod:`pneunet_env.bench.solver_study` (the runner) and :mod:`pneunet_env.bench.solver_plots`
(the charts). This module is the command line, and every public name of those modules stays importable from here.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from pneunet_env.arguments import integer, output_dir
from pneunet_env.bench.solver_methods import (
    BRANCH_TOL,
    CORRECT_TOL,
    FAILURES,
    OUTCOMES,
    SLOW_FACTOR,
    STATIONARY_TOL,
    AutoMethod,
    CatalogueCorner,
    LinearMethod,
    Method,
    NaiveMethod,
    PackageMethod,
    PathRun,
    Scene,
    catalogue_corners,
    classify,
    make_methods,
    make_scenes,
    reference_states,
    solve_path,
    solve_steps,
)
from pneunet_env.bench.solver_plots import plot_speed_accuracy, plot_stability_map, plot_step_size
from pneunet_env.bench.solver_study import run_study
from pneunet_env.files import atomic_write_json
from pneunet_env.progress import add_progress_argument

__all__ = [
    "CORRECT_TOL",
    "STATIONARY_TOL",
    "SLOW_FACTOR",
    "FAILURES",
    "OUTCOMES",
    "Scene",
    "Method",
    "PathRun",
    "make_scenes",
    "catalogue_corners",
    "make_methods",
    "solve_path",
    "solve_steps",
    "classify",
    "reference_states",
    "run_study",
    "add_arguments",
    "run",
    # re-exported (importable from here as before the split)
    "BRANCH_TOL", "AutoMethod", "CatalogueCorner", "LinearMethod", "NaiveMethod", "PackageMethod",
    "plot_speed_accuracy", "plot_stability_map", "plot_step_size",
]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="fewer pressures and cells (CI: well under a minute)")
    parser.add_argument("--out", type=output_dir, default=Path("bench_out/solvers"), help="output folder")
    parser.add_argument("--repeats", type=integer(1, 1000, "--repeats"), default=None,
                        help="timing passes per method and scene, fastest kept (default 1 quick, 3 full)")
    add_progress_argument(parser)


def _table(records: list[dict]) -> str:
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    methods = list(dict.fromkeys(r["method"] for r in records))
    by = {(r["method"], r["scene"]): r for r in records}
    w = 15
    lines = [f"{'method':<14}" + "".join(f"{s:>{w}}" for s in scenes)]
    for m in methods:
        cells = []
        for s in scenes:
            r = by[(m, s)]
            err = "NaN" if r["error"] is None else f"{r['error']:.0e}"
            mark = "!" if r["failure"] else " "
            cells.append(f"{r['time_s'] * 1e3:6.2f}ms {err:>6}{mark}")
        lines.append(f"{m:<14}" + "".join(f"{c:>{w}}" for c in cells))
    lines.append("cells: time per solve, max error vs reference; '!' = failed somewhere (see solvers.json)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.repeats is not None and args.repeats < 1:
        raise SystemExit(f"--repeats must be >= 1, got {args.repeats}")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    records, details = run_study(quick=args.quick, repeats=args.repeats, progress=args.progress)
    atomic_write_json(out / "solvers.json", records, indent=1)
    atomic_write_json(out / "solvers_details.json", details, indent=1)
    plot_speed_accuracy(records, out / "speed_accuracy.png")
    plot_stability_map(details, out / "stability_map.png")
    plot_step_size(details, out / "step_size.png")
    print(_table(records))
    print()
    failures = sorted({(r["method"], r["scene"], r["failure"]) for r in records if r["failure"]})
    for m, s, f in failures:
        print(f"  {m:<13} {s:<12} {f}")
    print()
    for row in details["auto"]["sweep"]:
        print(f"auto tolerance {row['tolerance']:.0e}: linear model answers {row['linear_fraction']:.0%} of solves, "
              f"time {row['time_per_solve_s'] * 1e6:.0f} us/solve vs full {row['full_time_per_solve_s'] * 1e6:.0f} "
              f"({row['time_saved_fraction']:+.0%} saved), max error {row['max_error']:.1e}")
    default_bad = [r for r in records if r["default"] and (r["failure"] or r["error"] is None or r["error"] > 1e-9)]
    print(f"\nwrote {out}/solvers.json, solvers_details.json, speed_accuracy.png, stability_map.png, step_size.png "
          f"({details['wall_s']:.1f} s)")
    if default_bad:
        print(f"DEFAULT SOLVER FAILED: {[(r['scene'], r['failure'], r['error']) for r in default_bad]}")
        return 1
    return 0
