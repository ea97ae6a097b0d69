"""The linearised model: the quadratic expansion of the energy about rest (supplement eqs. 15-17)."""

from __future__ import annotations

import numpy as np
import pytest

from pneunet_env import ActuatorParams, solve_equilibrium
from pneunet_env.physics import mechanics
from pneunet_env.physics.linear import LinearModel

GEOMETRIES = [{}, {"chamber_height": 1.3, "side_thickness": 0.3, "top_thickness": 0.7, "base_thickness": 0.4}]


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_quadratic_energy_is_the_taylor_expansion_of_the_full_energy(geometry):
    params = ActuatorParams(**geometry)
    lin = LinearModel(params)
    np.testing.assert_allclose(lin.volume_gradient, mechanics.volume_gradient(0.0, 0.0, params), rtol=1e-14)
    np.testing.assert_allclose(lin.stiffness, mechanics.hessian(0.0, 0.0, 0.0, params), rtol=1e-14, atol=1e-14)
    # The difference between the full and quadratic energies is third order in the state.
    rng = np.random.default_rng(1)
    direction = rng.normal(size=2)
    diffs = []
    for eps in (1e-2, 5e-3):
        k, s = eps * abs(direction[0]), eps * direction[1]
        diffs.append(abs(float(mechanics.energy(k, s, 0.7, params)) - float(lin.energy(k, s, 0.7))))
    assert diffs[0] / diffs[1] == pytest.approx(8.0, rel=0.15)


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_closed_form_minimises_the_quadratic_energy_and_has_eq17_slope(geometry):
    params = ActuatorParams(**geometry)
    lin = LinearModel(params)
    p = 0.3
    k, s = lin.state(p)
    h = 1e-6
    grad = [
        (lin.energy(k + h, s, p) - lin.energy(k - h, s, p)) / (2 * h),
        (lin.energy(k, s + h, p) - lin.energy(k, s - h, p)) / (2 * h),
    ]
    np.testing.assert_allclose(grad, 0.0, atol=1e-8)
    assert float(lin.curvature(1e-6)) / 1e-6 == pytest.approx(params.small_pressure_slope, rel=1e-5)


def test_linear_model_agrees_at_small_pressure_and_fails_at_the_balloon():
    params = ActuatorParams()
    lin = LinearModel(params)
    assert 0.5 < lin.valid_until < 5.0
    small = solve_equilibrium(0.05, params=params).curvature
    assert float(lin.curvature(0.05)) == pytest.approx(small, rel=0.01)
    balloon = solve_equilibrium(0.6, params=params).curvature
    assert abs(float(lin.curvature(0.6)) - balloon) > 0.3 * balloon
    assert np.isnan(lin.curvature(lin.valid_until + 0.1))
