"""Independent high-precision check: the solver agrees with an mpmath Newton at 30 digits on the same energy."""

from __future__ import annotations

import pytest

from pneunet_env import ActuatorParams, solve_equilibrium
from pneunet_env.physics.reference import reference_path

mpmath = pytest.importorskip("mpmath")
from pneunet_env.physics.reference import reference_minimum  # noqa: E402


@pytest.mark.parametrize(
    "p, kobj, J",
    [
        (0.05, 0.0, 20.0),
        (0.3, 0.0, 20.0),
        (0.6, 0.0, 20.0),  # balloon region
        (1.2, 0.0, 15.0),
        (1.2, 1e-5, 20.0),  # force control
        (0.6, 1e-4, 20.0),  # held branch, approaching the fold
        (0.8, 1e-4, 20.0),  # after the snap-through
        (1.4, 1e-2, 20.0),  # position control
        (1.0, 1e-1, 20.0),  # very stiff object
        (5.0, 0.0, 2.0),  # against the Gent limit
    ],
)
def test_solver_matches_30_digit_reference(p, kobj, J):
    params = ActuatorParams(gent_limit=J)
    eq = solve_equilibrium(p, kobj, 0.02, params)
    k, s = reference_minimum(p, kobj, 0.02, params, eq.state, digits=30)
    assert abs(eq.curvature - k) <= 1e-9 * abs(k)
    assert abs(eq.side_strain - s) <= 1e-9 * abs(s)


def test_near_the_fold_on_both_branches():
    """Loading and unloading a k~ = 1e-4 object near its folds, checked point by point at 30 digits."""
    params = ActuatorParams()
    up = [0.6, 0.65, 0.68]
    down = [0.68, 0.65, 0.62]
    eq = None
    for p in up + [0.75] + down:
        eq = solve_equilibrium(p, 1e-4, 0.02, params, initial=eq)
        k, s = reference_minimum(p, 1e-4, 0.02, params, eq.state, digits=30)
        assert abs(eq.curvature - k) <= 1e-9 * abs(k)
        assert abs(eq.side_strain - s) <= 1e-9 * abs(s)


def test_reference_at_zero_pressure_is_rest():
    assert reference_minimum(0.0, 1e-3, 0.02, ActuatorParams(), (1e-3, 1e-3)) == (0.0, 0.0)


def test_reference_path_polishes_every_point():
    ks, ss = reference_path([0.2, 0.5, 0.8], 1e-3, 0.02, ActuatorParams(), digits=30, refine=5)
    assert len(ks) == 3 and all(0.0 < k < 0.03 for k in ks)
