"""Shared fixtures."""

from __future__ import annotations

import pytest

from pneunet_env import ActuatorParams


@pytest.fixture
def params() -> ActuatorParams:
    """The paper's defaults (J = 20)."""
    return ActuatorParams()
