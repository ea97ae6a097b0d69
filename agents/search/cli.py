"""``pneunet-grasp search`` (``python -m agents.search``): the command of the best-ramp search
(:mod:`agents.search.ramp`, which says what it searches and where it writes the result).

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
from pathlib import Path

from agents.common.cli import add_catalogue, parse_overrides, usage_error
from agents.common.words import damage_rule_text, rate_parts, regime_text, task_description
from agents.figures.search import plot_search
from agents.search.ramp import COARSE_TARGETS, DURATIONS, save_best, search_ramp
from agents.search.sensitivity import sensitivity_study
from pneunet_env.arguments import count, integer, output_file, real
from pneunet_env.arguments import seed as seed_type
from pneunet_env.config import load_config
from pneunet_env.locks import RunLock, release_held
from pneunet_env.progress import add_progress_argument

__all__ = ["add_arguments", "run", "main"]


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
    add_catalogue(parser)
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
    from agents.policies.registry import _beside_path, tuned_path
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
        overrides = parse_overrides(args.overrides, args.catalogue)
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
