"""The commands of the docs pages beyond the README's first ones (design, env, figures, performance, physics,
results-paper, ...) run, by ``tests/test_readme_commands.py``'s rules: its module holds the extraction, the smoke
sizes and the runner; this file only takes the other half of the commands, so that pytest-xdist's
``--dist loadfile`` (the README's test command) runs the two halves side by side."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("readme_commands_for_docs", ROOT / "tests" / "test_readme_commands.py")
rc = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = rc  # its dataclasses look their module up there
_spec.loader.exec_module(rc)

PARAMS = rc._run_params(first_pages=False)


def test_the_other_pages_have_commands_to_run():
    """Not vacuous: the design, env, figures and performance pages' concrete commands are here."""
    pages = {p.values[0].page for p in PARAMS}
    assert {"docs/design.md", "docs/env.md", "docs/figures.md", "docs/performance.md"} <= pages, sorted(pages)


@pytest.fixture(scope="module")
def status_before() -> str | None:
    """``git status --porcelain`` before the first command of this module ran."""
    return rc._git_status()


@pytest.fixture(autouse=True)
def _snapshot(status_before):
    return status_before


@pytest.mark.parametrize(("cmd", "also"), PARAMS)
def test_docs_command_runs(cmd, also, tmp_path, capfd, monkeypatch):
    rc.run_command(cmd, also, tmp_path, capfd, monkeypatch)


def test_the_repository_is_untouched(status_before):
    """Last: no command wrote into the repository."""
    rc.check_untouched(status_before, "docs pages'")
