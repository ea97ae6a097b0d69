"""The benchmarks' modules: each under the house size, each file written through the atomic writer."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import pneunet_env

BENCH = Path(pneunet_env.__file__).resolve().parent / "bench"
WRITERS = {"write_text", "write_bytes", "savefig", "dump", "save", "savez", "savez_compressed", "to_csv"}
"""Calls that write a file in place (``json.dump``, ``Path.write_text``, ``fig.savefig``...)."""


def _in_place_writes(path: Path) -> list[str]:
    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Attribute) and f.attr in WRITERS:
                bad.append(f"{ast.unparse(f)} at line {node.lineno}")
            if isinstance(f, ast.Name) and f.id == "open" and any(
                    isinstance(a, ast.Constant) and isinstance(a.value, str) and ("w" in a.value or "a" in a.value)
                    for a in node.args[1:2]):
                bad.append(f"open(..., 'w') at line {node.lineno}")
    return bad


@pytest.mark.parametrize("name", ["solvers", "solver_methods", "solver_study", "solver_plots", "backends",
                                  "profile_solver", "render_speed", "models"])
def test_bench_modules_are_sized_by_concern_and_write_atomically(name):
    """JSON through :func:`pneunet_env.files.atomic_write_json` / ``atomic_write_text``, charts through
    :func:`pneunet_env.files.save_figure` (``bench solvers`` wrote its JSONs and charts in place)."""
    path = BENCH / f"{name}.py"
    assert len(path.read_text().splitlines()) <= 800, name
    assert not _in_place_writes(path), (name, _in_place_writes(path))


def test_solvers_still_exports_every_name_it_did_from_the_parts():
    from pneunet_env.bench import solver_methods, solver_plots, solver_study, solvers

    before_the_split = {"CORRECT_TOL", "STATIONARY_TOL", "SLOW_FACTOR", "FAILURES", "OUTCOMES", "Scene", "Method",
                        "PathRun", "make_scenes", "catalogue_corners", "make_methods", "solve_path", "solve_steps",
                        "classify", "reference_states", "run_study", "add_arguments", "run"}
    assert before_the_split <= set(solvers.__all__)
    for name in solvers.__all__:
        assert hasattr(solvers, name), name
    for module in (solver_methods, solver_plots, solver_study):
        for name in set(module.__all__) & set(solvers.__all__):
            assert getattr(solvers, name) is getattr(module, name), name
