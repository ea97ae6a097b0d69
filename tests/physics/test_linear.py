"""The linearised model: the quadratic expansion of the energy about rest (supplement eqs. 15-17)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams, Equilibrium, solve_equilibrium
from pneunet_env.physics import mechanics
from pneunet_env.physics.linear import (
    LinearModel,
    linear_equilibrium,
    linear_error_estimate,
    linear_reach,
    linear_state,
)
from pneunet_env.physics.solver import STATUS_CONVERGED

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


def _state_error(a, b) -> float:
    return max(abs(a.curvature - b.curvature), abs(a.side_strain - b.side_strain))


def test_linear_equilibrium_is_the_closed_form_and_has_the_papers_slope(params):
    lm = LinearModel(params)
    for p in (1e-4, 0.05, 0.3, 1.0):
        eq = linear_equilibrium(p, params=params)
        k, s = lm.state(p)
        assert type(eq) is Equilibrium
        assert eq.converged and eq.iterations == 0 and eq.substeps == 0 and not eq.snapped
        assert eq.status == STATUS_CONVERGED and eq.message == "converged" and eq.gradient_norm == 0.0
        assert eq.curvature == pytest.approx(float(k), rel=1e-12)
        assert eq.side_strain == pytest.approx(float(s), rel=1e-12)
        assert eq.energy == pytest.approx(float(lm.energy(k, s, p)), rel=1e-12, abs=1e-15)
        assert eq.top_strain == pytest.approx(params.chamber_height * (1.0 + eq.side_strain) * eq.curvature)
        assert not eq.in_contact and eq.contact_force == 0.0 and eq.indentation == 0.0  # no object
    # Supplement eq. 17: kappa~/p~ -> 0.073171 at the defaults.
    assert linear_equilibrium(1e-6).curvature / 1e-6 == pytest.approx(0.073171, rel=1e-4)


def test_linear_equilibrium_rejects_bad_input(params):
    with pytest.raises(ValueError, match="pressure"):
        linear_equilibrium(float("nan"))
    with pytest.raises(ValueError, match="pressure"):
        linear_equilibrium(-0.1)
    with pytest.raises(ValueError, match="object_stiffness"):
        linear_equilibrium(0.1, object_stiffness=-1e-4)
    with pytest.raises(ValueError, match="object_curvature"):
        linear_equilibrium(0.1, object_stiffness=1e-4, object_curvature=4.0)


def test_linear_beyond_its_validity_raises(params):
    lm = LinearModel(params)
    assert 1.6 < lm.valid_until < 1.8
    with pytest.raises(ValueError, match="beyond the linear model's validity"):
        linear_equilibrium(lm.valid_until + 0.01, params=params)
    assert math.isnan(linear_state(lm.valid_until + 0.01, 0.0, 0.02, params)[0])


def test_linear_contact_minimises_the_piecewise_quadratic_energy(params):
    """In contact, the linear state is the minimiser of U_lin + (k/2)(kappa - ko)^2 / ko^4."""
    lm = LinearModel(params)
    p, kobj, ko = 0.6, 1e-4, 0.02
    eq = linear_equilibrium(p, kobj, ko, params)
    assert eq.in_contact and ko < eq.curvature < float(lm.curvature(p))
    assert eq.contact_force == pytest.approx(kobj * (1 / ko - 1 / eq.curvature), rel=1e-12)
    assert eq.indentation == pytest.approx(1 / ko - 1 / eq.curvature, rel=1e-12)

    def U(k, s):
        return float(lm.energy(k, s, p)) + 0.5 * kobj * (k - ko) ** 2 / ko**4

    k0, s0 = eq.state
    h = 1e-6
    gk = (U(k0 + h, s0) - U(k0 - h, s0)) / (2 * h)
    gs = (U(k0, s0 + h) - U(k0, s0 - h)) / (2 * h)
    assert abs(gk) < 1e-6 and abs(gs) < 1e-6
    assert U(k0, s0) == pytest.approx(eq.energy, rel=1e-12)
    # Out of contact the object term is skipped: the state is the free one.
    below = linear_equilibrium(0.1, kobj, ko, params)
    assert not below.in_contact and below.state == linear_equilibrium(0.1, 0.0, ko, params).state


@pytest.mark.parametrize("p", [0.01, 0.05, 0.08])
def test_error_estimate_is_the_true_error(params, p):
    k, s, *_ = linear_state(p, 0.0, 0.02, params)
    full = solve_equilibrium(p, params=params)
    true = max(abs(k - full.curvature), abs(s - full.side_strain))
    est = linear_error_estimate(k, s, p, 0.0, 0.02, params)
    assert est == pytest.approx(true, rel=0.02)


def test_error_estimate_refuses_bad_states(params):
    assert linear_error_estimate(-0.1, 0.0, 0.1, 0.0, 0.02, params) == math.inf  # outside the domain
    # The saddle between the two branches of k~ = 1e-4 at p~ = 0.65: Hessian not positive definite.
    assert linear_error_estimate(0.04478907, 0.77937997, 0.65, 1e-4, 0.02, params) == math.inf


def test_linear_reach_grows_with_the_tolerance_and_is_honest(params):
    reaches = [linear_reach(params, t) for t in (1e-5, 1e-4, 1e-3, 1e-2)]
    assert all(a < b for a, b in zip(reaches, reaches[1:], strict=False))
    for tol, p in zip((1e-4, 1e-3, 1e-2), reaches[1:], strict=True):
        eq = linear_equilibrium(p, params=params)
        assert _state_error(eq, solve_equilibrium(p, params=params)) <= tol
