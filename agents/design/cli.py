"""``pneunet-grasp design``'s command line."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict
from pathlib import Path

from agents.design.outputs import write_design
from agents.design.space import PRESSURE_ERROR_KPA, parse_bounds
from agents.design.storage import make_storage
from agents.design.study import StudySpec, report, run_study, work
from pneunet_env import arguments as checks
from pneunet_env.files import atomic_write_text

_DESCRIPTION = ("which actuator lets one blind pressure schedule hold a use case's objects, with margin for "
                "manufacturing error (Optuna over the walls, the chamber and sourced elastomers)")


DESIGN_WORKER_BYTES = 1 << 30
"""The memory a design worker is given (bytes): --jobs is at most the available memory over this (and the cores)."""


def _weights(text: str | None) -> dict[str, float] | None:
    if text is None:
        return None
    out: dict[str, float] = {}
    for item in text.split(","):
        name, sep, val = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--class-weights must be NAME=WEIGHT,NAME=WEIGHT..., got {text!r}")
        try:
            out[name.strip()] = float(val)
        except ValueError:
            raise ValueError(f"--class-weights {text!r}: the weight of {name.strip()!r} is not a number") from None
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--use-case", default=None,
                        help="catalogue use case whose objects the design must hold (default: --config's own objects, "
                             "which are kitchen's without --config; see docs/env.md)")
    parser.add_argument("--class-weights", default=None, metavar="NAME=W,...",
                        help="catalogue class weights instead of a use case, e.g. apple=1,gelatin_gel=1")
    parser.add_argument("--trials", type=int, default=120,
                        help="designs in the study, in all (a resumed or joined study runs only the rest; default 120)")
    parser.add_argument("--jobs", type=int, default=1,
                        help="worker processes on this machine (default 1; at most one per usable core, and 1 GiB of "
                             "available memory each)")
    parser.add_argument("--storage", default=None,
                        help="Optuna storage shared by workers: an RDB URL (sqlite:///PATH, postgresql://...) or "
                             "journal:PATH (default: sqlite in --out, so a stopped run resumes)")
    parser.add_argument("--study-name", default=None, help="study name in the storage (default design-USE_CASE)")
    parser.add_argument("--objects", type=int, default=200, help="search objects per design (default 200)")
    parser.add_argument("--held-out", type=int, default=400,
                        help="held-out objects the best designs are reported on (default 400)")
    parser.add_argument("--top", type=int, default=3,
                        help="best designs reported and written (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="objects' and sampler's seed (default 0)")
    parser.add_argument("--sampler", choices=("tpe", "nsga2"), default="tpe",
                        help="Optuna's multi-objective sampler (default tpe)")
    parser.add_argument("--bound", action="append", default=[], metavar="KEY=LOW:HIGH",
                        help="narrow a parameter's range (repeatable), e.g. top_thickness_mm=1.5:3")
    parser.add_argument("--config", default=None, help="base env config YAML (objects, task) the design changes; "
                        "its own objects (a use case, class weights or ranges) unless --use-case or --class-weights")
    parser.add_argument("--catalogue", default=None, metavar="PATH",
                        help="your own object catalogue (pneunet_env/data/objects.yaml's format; classes may lack "
                             "sources, then reported unsourced); --use-case names one of its use cases (default: its "
                             "default)")
    parser.add_argument("--pressure-error-kpa", type=float, default=PRESSURE_ERROR_KPA, metavar="KPA",
                        help="the regulator's error a blind pressure is scored at, either way (default "
                             f"{PRESSURE_ERROR_KPA:g} kPa: 1 %% of a 100 kPa full scale, SMC ITV-series)")
    parser.add_argument("--out", type=checks.output_dir, default=None,
                        help="output folder (default design/USE_CASE), checked before any design is run")
    parser.add_argument("--export", type=checks.output_file, default=None,
                        help="also write the best design's env config here (PATH.yaml, with PATH.best_ramp.json)")
    parser.add_argument("--worker", action="store_true",
                        help="only run trials (a worker joining --storage from another machine); no report")
    parser.add_argument("--report", action="store_true", help="only report on the study as it stands")
    parser.add_argument("--checks", action="store_true",
                        help="instead of a study: measure the design findings (agents.design.checks) and print them")
    from pneunet_env.progress import add_progress_argument

    add_progress_argument(parser, "--quiet")


def spec_from_args(args: argparse.Namespace) -> StudySpec:
    """The study's settings from the command line, every value checked before any work."""
    weights = _weights(args.class_weights)
    out = args.out if args.out is not None else Path("design") / (
        (args.use_case or "default") if weights is None else "weights")
    checks.check_output_dir(out, "--out")  # the default folder too: refused now, not after the study
    most_of = checks.MAX_COUNT
    for flag, value, most in (("--trials", args.trials, most_of), ("--objects", args.objects, most_of),
                              ("--held-out", args.held_out, most_of), ("--jobs", args.jobs, 1024),
                              ("--top", args.top, 1000), ("--seed", args.seed, checks.MAX_SEED)):
        if value > most:  # the lower bounds, and the names of the settings, are StudySpec's
            raise ValueError(f"{flag} must be at most {most}, got {value}")
    if args.jobs >= 1:  # (below 1: StudySpec's refusal)
        from agents.common.workers import check_jobs

        check_jobs(args.jobs, DESIGN_WORKER_BYTES)
    if args.export is not None and args.export.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--export must name a .yaml file, got {str(args.export)!r}")
    if args.worker and args.report:
        raise ValueError("--worker and --report exclude each other")
    spec = StudySpec(out=out, use_case=args.use_case, catalogue=args.catalogue, class_weights=weights,
                     trials=args.trials, jobs=args.jobs, storage=args.storage, study_name=args.study_name,
                     seed=args.seed, objects=args.objects, held_out=args.held_out, sampler=args.sampler,
                     bounds=parse_bounds(args.bound), config=args.config, top=args.top,
                     pressure_error_kpa=args.pressure_error_kpa)
    make_storage(spec.storage, out)  # a storage it must not write to, or cannot reach, is named now, before any work
    return spec


def run(args: argparse.Namespace) -> int:
    if args.checks:
        return _run_checks(args)
    try:
        spec = spec_from_args(args)
        if args.worker:
            n = work(spec, parallel=None if spec.jobs == 1 else False, progress=args.progress)
            print(f"ran {n} designs in study {spec.name!r}")
            return 0
        t0 = time.perf_counter()
        if args.report:
            result = report(spec, progress=args.progress)
        else:
            print(f"design study {spec.name!r}: {spec.trials} designs, {spec.objects} search objects, "
                  f"{spec.held_out} held out, {spec.jobs} process(es); storage "
                  f"{spec.storage or spec.out / 'study.db'}")
            result = run_study(spec, progress=args.progress)
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp design: {exc}") from None
    best = next(r for r in result["designs"] if r["label"] == "rank-1")
    if args.export is not None:
        write_design(args.export, best, spec.base_config(), spec.name)
        print(f"wrote {args.export} and {args.export.with_suffix('.best_ramp.json')}")
    if result["importance"]:
        imp = result["importance"]
        print("importance (PED-ANOVA, design score): " + ", ".join(f"{k} {v:.2f}" for k, v in imp.items()))
    elif result.get("importance_note"):
        print(f"importance: {result['importance_note']}")
    print(f"{result['scored']} designs scored, {result['distinct']} distinct, in {result['trials']} trials"
          f"{_duplicates(result)}; wrote {spec.out / 'design.json'}, pareto.png, curves.png, "
          f"importance.png and designs/ in {time.perf_counter() - t0:.0f} s")
    return 0


def _duplicates(result) -> str:
    n = result.get("duplicates", 0)
    return f" ({n} duplicate design{'s' if n != 1 else ''} pruned unrun)" if n else ""


def _run_checks(args: argparse.Namespace) -> int:
    from agents.design.checks import render_markdown, run_design_checks

    try:
        spec = spec_from_args(args)
        res = run_design_checks(spec.objects, spec.seed, spec.base_config())
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp design: {exc}") from None
    table = render_markdown(res)
    print(table)
    if args.out is not None:
        spec.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(spec.out / "checks.md", table + "\n")
        atomic_write_text(spec.out / "checks.json", json.dumps([asdict(r) for r in res], indent=1) + "\n")
        print(f"wrote {spec.out / 'checks.md'} and checks.json")
    return 0 if all(r.passed == r.expected for r in res) else 1


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.design``: as ``pneunet-grasp design``; Ctrl-C ends it with one line (what to run again)
    and exit status 130."""
    parser = argparse.ArgumentParser(prog="pneunet-grasp design", description=_DESCRIPTION)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except KeyboardInterrupt as exc:
        note = " ".join(str(a) for a in exc.args if str(a).strip())
        print(f"{parser.prog}: interrupted" + (f" {note}" if note else ""), file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
