"""``pneunet-grasp figures``: regenerate the seed paper's figures (PNG + CSV) and check its statements.

The command line only: the figures are computed and drawn by :mod:`pneunet_env.paper.figures`, the statements
measured by :mod:`pneunet_env.paper.checks`. Writes ``NAME.csv`` and ``NAME.png`` per figure and
``paper_checks.md`` (each atomically: a file there is replaced whole); exits 1 if an equilibrium did not converge or
a check disagrees with its expected outcome. ``--out`` is checked before any equilibrium is computed: a folder that
exists or can be created (with ``--table-only``: one that exists, holding the CSVs).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pneunet_env import arguments
from pneunet_env.files import atomic_write_text
from pneunet_env.paper import checks as paper_checks
from pneunet_env.paper.figures import FIGURES, generate, load_tables
from pneunet_env.progress import add_progress_argument, progress_enabled

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=arguments.output_dir,
                        help="output folder (created): NAME.png, NAME.csv, paper_checks.md")
    parser.add_argument("--quick", action="store_true", help="coarser grids (CI): well under a minute")
    parser.add_argument("--only", nargs="+", metavar="NAME", choices=list(FIGURES),
                        help=f"only these figures (default all: {', '.join(FIGURES)}); the checks need all")
    parser.add_argument("--no-csv", action="store_true", help="write only the PNGs (and print the checks)")
    parser.add_argument("--table-only", action="store_true",
                        help="compute nothing: read the CSVs already in --out and print the checks' markdown table")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.table_only:
        if not out.is_dir():
            raise ValueError(f"--table-only reads the CSVs in --out {str(out)!r}, which is no folder; run "
                             f"'pneunet-grasp figures --out {out}' first")
        try:
            tables = load_tables(out)
        except FileNotFoundError as exc:
            raise ValueError(f"--table-only: {exc}") from None
        print(paper_checks.render_markdown(paper_checks.run_checks(tables)))
        return 0
    report = generate(out, quick=args.quick, names=args.only, csv_files=not args.no_csv,
                      show_progress=progress_enabled(args.progress))  # off unless stderr is a terminal
    for p in report.files:
        print(f"wrote {p}")
    print(f"{report.states} equilibria in {report.seconds:.1f} s; "
          f"{report.unconverged} did not converge" + (" (see the 'converged' column)" if report.unconverged else ""))
    status = 0 if report.unconverged == 0 else 1
    if args.only is None:
        results = paper_checks.run_checks(report.tables)
        md = paper_checks.render_markdown(results)
        if not args.no_csv:
            atomic_write_text(out / "paper_checks.md", md + "\n")
            print(f"wrote {out / 'paper_checks.md'}")
        print()
        print(md)
        if any(r.passed != r.expected for r in results):
            print("\nsome checks disagree with their expected outcome (see the table)", file=sys.stderr)
            status = 1
    return status
