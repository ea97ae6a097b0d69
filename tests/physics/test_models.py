"""Model selection: ``full``, ``linear`` and ``auto`` (pneunet_env.physics.models)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams, Equilibrium, solve_equilibrium
from pneunet_env.physics.linear import LinearModel
from pneunet_env.physics.models import (
    AUTO_TOLERANCE,
    MODELS,
    ModelEquilibrium,
    check_model,
    equilibrium_for_model,
    linear_equilibrium,
    linear_error_estimate,
    linear_reach,
    linear_state,
)


def _state_error(a, b) -> float:
    return max(abs(a.curvature - b.curvature), abs(a.side_strain - b.side_strain))


def test_check_model_names_the_bad_value():
    assert [check_model(m) for m in MODELS] == list(MODELS)
    for bad in ("Full", "quadratic", "", None, 3):
        with pytest.raises(ValueError, match="model must be one of"):
            check_model(bad)


@pytest.mark.parametrize("model", MODELS)
def test_bad_inputs_raise(model):
    with pytest.raises(ValueError, match="pressure"):
        equilibrium_for_model(model, float("nan"))
    with pytest.raises(ValueError, match="pressure"):
        equilibrium_for_model(model, -0.1)
    with pytest.raises(ValueError, match="object_stiffness"):
        equilibrium_for_model(model, 0.1, object_stiffness=-1e-4)
    with pytest.raises(ValueError, match="object_curvature"):
        equilibrium_for_model(model, 0.1, object_stiffness=1e-4, object_curvature=4.0)


@pytest.mark.parametrize("tol", [0.0, -1e-3, float("nan"), float("inf")])
def test_auto_rejects_a_bad_tolerance(tol):
    with pytest.raises(ValueError, match="tolerance"):
        equilibrium_for_model("auto", 0.05, tolerance=tol)


def test_model_equilibrium_is_an_equilibrium_with_two_more_fields():
    base = {f.name for f in dataclasses.fields(Equilibrium)}
    extra = {f.name for f in dataclasses.fields(ModelEquilibrium)} - base
    assert extra == {"model", "error_estimate"}
    eq = equilibrium_for_model("auto", 0.05)
    assert isinstance(eq, Equilibrium)
    # It can be handed back to the package's solver as the quasi-static history.
    nxt = solve_equilibrium(0.3, initial=eq)
    assert nxt.converged and _state_error(nxt, solve_equilibrium(0.3)) <= 1e-9


@pytest.mark.parametrize("p, k", [(0.05, 0.0), (0.5, 1e-4), (0.9, 1e-4), (1.4, 1e-2)])
def test_full_is_the_package_solver(p, k):
    eq = equilibrium_for_model("full", p, k)
    ref = solve_equilibrium(p, k)
    assert eq.model == "full" and eq.error_estimate == 0.0
    assert all(getattr(eq, f.name) == getattr(ref, f.name) for f in dataclasses.fields(Equilibrium))


def test_linear_is_the_closed_form_and_has_the_papers_slope(params):
    lm = LinearModel(params)
    for p in (1e-4, 0.05, 0.3, 1.0):
        eq = equilibrium_for_model("linear", p)
        k, s = lm.state(p)
        assert eq.model == "linear" and eq.converged and eq.iterations == 0
        assert eq.curvature == pytest.approx(float(k), rel=1e-12)
        assert eq.side_strain == pytest.approx(float(s), rel=1e-12)
        assert eq.energy == pytest.approx(float(lm.energy(k, s, p)), rel=1e-12, abs=1e-15)
    # Supplement eq. 17: kappa~/p~ -> 0.073171 at the defaults.
    assert equilibrium_for_model("linear", 1e-6).curvature / 1e-6 == pytest.approx(0.073171, rel=1e-4)


def test_linear_beyond_its_validity_raises(params):
    lm = LinearModel(params)
    assert 1.6 < lm.valid_until < 1.8
    with pytest.raises(ValueError, match="beyond the linear model's validity"):
        linear_equilibrium(lm.valid_until + 0.01, params=params)


def test_linear_contact_minimises_the_piecewise_quadratic_energy(params):
    """In contact, the linear state is the minimiser of U_lin + (k/2)(kappa - ko)^2 / ko^4."""
    lm = LinearModel(params)
    p, kobj, ko = 0.6, 1e-4, 0.02
    eq = linear_equilibrium(p, kobj, ko, params)
    assert eq.in_contact and ko < eq.curvature < float(lm.curvature(p))
    assert eq.contact_force == pytest.approx(kobj * (1 / ko - 1 / eq.curvature), rel=1e-12)

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


def _auto_along(pressures, k, tol=AUTO_TOLERANCE, params=None):
    prev, out = None, []
    for p in pressures:
        prev = equilibrium_for_model("auto", float(p), k, 0.02, params, previous=prev, tolerance=tol)
        out.append(prev)
    return out


def _full_along(pressures, k, params=None):
    prev, out = None, []
    for p in pressures:
        prev = solve_equilibrium(float(p), k, 0.02, params, initial=prev)
        out.append(prev)
    return out


@pytest.mark.parametrize("k", [0.0, 1e-5, 1e-4, 1e-2, 1.0])
def test_auto_agrees_with_full_to_its_bound_along_the_scenes(k):
    """Load to 1.2 (2.0 for stiff objects) and unload, in steps of 0.01: auto's error never exceeds its bound."""
    top = 2.0 if k >= 1e-2 else 1.2
    up = np.round(np.arange(1, int(round(top / 0.01)) + 1) * 0.01, 10)
    ps = np.concatenate([up, up[-2::-1]])
    auto, full = _auto_along(ps, k), _full_along(ps, k)
    errors = np.array([_state_error(a, f) for a, f in zip(auto, full, strict=True)])
    used = np.array([a.model == "linear" for a in auto])
    assert errors.max() <= AUTO_TOLERANCE
    assert used.any(), "auto never used the linear model: nothing was tested"
    assert np.all(ps[used] <= linear_reach(ActuatorParams()) + 1e-12)
    assert not any(a.in_contact for a in auto if a.model == "linear")
    # Where auto used the full model, it is the package's solution (no error carried over from the linear one).
    assert errors[~used].max() <= 1e-9
    assert all(a.converged for a in auto)


def test_auto_never_uses_the_linear_branch_against_the_history():
    """On unloading in the fold's bistable window, the history is on the upper branch: auto must stay there,
    even with a tolerance so loose that the linear model would otherwise be accepted."""
    k = 1e-4
    ps = list(np.round(np.arange(1, 121) * 0.01, 10)) + [0.9, 0.8, 0.7, 0.65]
    loose = 0.5
    auto, full = _auto_along(ps, k, tol=loose), _full_along(ps, k)
    assert full[-1].curvature > 0.2  # upper branch
    assert auto[-1].model == "full"
    assert _state_error(auto[-1], full[-1]) <= 1e-9


def test_auto_uses_the_linear_model_only_where_cheap_and_accurate():
    low = equilibrium_for_model("auto", 0.02)
    assert low.model == "linear" and 0.0 < low.error_estimate <= AUTO_TOLERANCE
    assert equilibrium_for_model("auto", 0.5).model == "full"
    # No object term out of contact: with or without a (distant) object, the same state.
    assert equilibrium_for_model("auto", 0.02, 1e-2).state == low.state
    # Deterministic.
    assert equilibrium_for_model("auto", 0.02) == low
