"""The solver study's models: ``full``, ``linear`` and ``auto`` (pneunet_env.bench.models)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams, Equilibrium, solve_equilibrium
from pneunet_env.bench.models import (
    AUTO_TOLERANCE,
    MODELS,
    ModelAnswer,
    check_model,
    equilibrium_for_model,
)
from pneunet_env.physics.linear import linear_equilibrium, linear_reach


def _state_error(a: Equilibrium, b: Equilibrium) -> float:
    return max(abs(a.curvature - b.curvature), abs(a.side_strain - b.side_strain))


def test_check_model_names_the_bad_value():
    assert [check_model(m) for m in MODELS] == list(MODELS)
    for bad in ("Full", "quadratic", "", None, 3):
        with pytest.raises(ValueError, match="model must be one of"):
            check_model(bad)
    with pytest.raises(ValueError, match="model must be one of"):
        equilibrium_for_model("quadratic", 0.1)


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


def test_an_answer_wraps_a_plain_equilibrium():
    """One solved-state type: the answer holds an ``Equilibrium`` (not a second state shape) and the model's name."""
    assert ModelAnswer._fields == ("equilibrium", "model", "error_estimate")
    ans = equilibrium_for_model("auto", 0.05)
    assert ans.model == "linear"
    assert type(ans.equilibrium) is Equilibrium and not isinstance(ans, Equilibrium)
    # It can be handed back to the package's solver as the quasi-static history.
    nxt = solve_equilibrium(0.3, initial=ans.equilibrium)
    assert nxt.converged and _state_error(nxt, solve_equilibrium(0.3)) <= 1e-9


@pytest.mark.parametrize("p, k", [(0.05, 0.0), (0.5, 1e-4), (0.9, 1e-4), (1.4, 1e-2)])
def test_full_is_the_package_solver(p, k):
    ans = equilibrium_for_model("full", p, k)
    ref = solve_equilibrium(p, k)
    assert ans.model == "full" and ans.error_estimate == 0.0
    assert all(getattr(ans.equilibrium, f) == getattr(ref, f) for f in Equilibrium._fields)


@pytest.mark.parametrize("p, k", [(1e-4, 0.0), (0.05, 0.0), (0.6, 1e-4), (1.0, 0.0)])
def test_linear_is_the_linear_models_equilibrium(p, k):
    ans = equilibrium_for_model("linear", p, k)
    assert ans.model == "linear" and math.isnan(ans.error_estimate)  # not computed for model="linear"
    assert ans.equilibrium == linear_equilibrium(p, k)
    with pytest.raises(ValueError, match="beyond the linear model's validity"):
        equilibrium_for_model("linear", 1.8)


def _auto_along(pressures, k, tol=AUTO_TOLERANCE, params=None) -> list[ModelAnswer]:
    prev, out = None, []
    for p in pressures:
        ans = equilibrium_for_model("auto", float(p), k, 0.02, params, previous=prev, tolerance=tol)
        prev = ans.equilibrium
        out.append(ans)
    return out


def _full_along(pressures, k, params=None) -> list[Equilibrium]:
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
    errors = np.array([_state_error(a.equilibrium, f) for a, f in zip(auto, full, strict=True)])
    used = np.array([a.model == "linear" for a in auto])
    assert errors.max() <= AUTO_TOLERANCE
    assert used.any(), "auto never used the linear model: nothing was tested"
    assert np.all(ps[used] <= linear_reach(ActuatorParams(), AUTO_TOLERANCE) + 1e-12)
    assert not any(a.equilibrium.in_contact for a in auto if a.model == "linear")
    # Where auto used the full model, it is the package's solution (no error carried over from the linear one).
    assert errors[~used].max() <= 1e-9
    assert all(a.equilibrium.converged for a in auto)


def test_auto_never_uses_the_linear_branch_against_the_history():
    """On unloading in the fold's bistable window, the history is on the upper branch: auto must stay there,
    even with a tolerance so loose that the linear model would otherwise be accepted."""
    k = 1e-4
    ps = list(np.round(np.arange(1, 121) * 0.01, 10)) + [0.9, 0.8, 0.7, 0.65]
    loose = 0.5
    auto, full = _auto_along(ps, k, tol=loose), _full_along(ps, k)
    assert full[-1].curvature > 0.2  # upper branch
    assert auto[-1].model == "full"
    assert _state_error(auto[-1].equilibrium, full[-1]) <= 1e-9


def test_auto_uses_the_linear_model_only_where_cheap_and_accurate():
    low = equilibrium_for_model("auto", 0.02)
    assert low.model == "linear" and 0.0 < low.error_estimate <= AUTO_TOLERANCE
    assert low.equilibrium == linear_equilibrium(0.02)  # the linear model's own equilibrium, estimate aside
    assert equilibrium_for_model("auto", 0.5).model == "full"
    # No object term out of contact: with or without a (distant) object, the same state.
    assert equilibrium_for_model("auto", 0.02, 1e-2).equilibrium.state == low.equilibrium.state
    # A previous linear answer keeps auto on the linear branch.
    assert equilibrium_for_model("auto", 0.03, previous=low.equilibrium).model == "linear"
    # Deterministic.
    assert equilibrium_for_model("auto", 0.02) == low
