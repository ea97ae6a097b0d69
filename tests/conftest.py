"""Shared fixtures."""

from __future__ import annotations

import pytest

from pneunet_env import ActuatorParams


@pytest.fixture
def params() -> ActuatorParams:
    """The paper's defaults (J = 20)."""
    return ActuatorParams()


@pytest.fixture
def python_ctrl_c():
    """Python's own Ctrl-C handler for the test (a run started in the background of a non-interactive shell inherits
    SIGINT ignored, and Python then leaves it so), restored afterwards."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
