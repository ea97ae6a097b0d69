"""ruff is clean on the whole repository."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_ruff_clean():
    # ruff is in the dev extra, which the README's test command installs: a missing ruff is a failure, not a skip.
    try:
        import ruff  # noqa: F401
    except ImportError:
        pytest.fail("ruff is not installed (pip install -e '.[dev]')")
    res = subprocess.run([sys.executable, "-m", "ruff", "check", str(ROOT)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
