"""The solver study's models: ``"full"``, ``"linear"`` and ``"auto"`` (``pneunet-grasp bench solvers``).

* ``"full"`` — the nonlinear energy (:mod:`pneunet_env.physics.mechanics`), minimised by the package's
  safeguarded Newton solver with pressure continuation (:func:`pneunet_env.physics.solver.solve_equilibrium`).
* ``"linear"`` — the quadratic expansion of the energy about rest, solved in closed form, with the object's
  Winkler term linearised about first contact (:func:`pneunet_env.physics.linear.linear_equilibrium`).
* ``"auto"`` — the linear model wherever its error against the full model is below
  :data:`AUTO_TOLERANCE`, the full model elsewhere. The error is not guessed from the pressure: it is
  estimated at every call by one Newton step of the *full* energy from the linear state
  (:func:`pneunet_env.physics.linear.linear_error_estimate`, exact to second order in the error), which costs
  one evaluation of the energy's derivatives instead of a Newton solve with continuation. The linear state is
  also refused when the previous state is not on the branch the linear model describes (after a
  snap-through), or when the error estimate would straddle contact onset, where the Hessian jumps. Out of
  contact the object term is skipped: the linear model is then the free one. (The full model's object term is
  exactly zero out of contact and costs a few flops in the compiled kernel, so skipping it there would save
  nothing.)

The study measured that ``auto`` saves no time at this model's size (``docs/solvers.md``), so the environment
always solves the full model; the selection lives here, with its only user, as the template for a larger model.

An answer is a :class:`ModelAnswer`: the :class:`~pneunet_env.physics.solver.Equilibrium` (the package's one
solved-state type) with the model that produced it and that model's estimated error.

All quantities are dimensionless (lengths / ``w``, stresses and pressure / ``mu``, energy / ``mu t w^2``);
see :mod:`pneunet_env.physics.units` for physical units.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pneunet_env.physics.linear import (
    ESTIMATE_SAFETY,
    linear_equilibrium,
    linear_error_estimate,
    linear_reach,
    linear_state,
    linear_state_equilibrium,
)
from pneunet_env.physics.params import ActuatorParams, check_finite, check_object
from pneunet_env.physics.solver import (
    DEFAULT_OPTIONS,
    Equilibrium,
    SolverOptions,
    check_pressure,
    solve_equilibrium,
)

__all__ = ["MODELS", "AUTO_TOLERANCE", "ModelAnswer", "check_model", "equilibrium_for_model"]

MODELS = ("full", "linear", "auto")
"""The model names :func:`equilibrium_for_model` accepts."""

AUTO_TOLERANCE = 1e-3
"""Largest state error ``max(|d kappa~|, |d e_s|)`` that ``auto`` accepts from the linear model.

Derived from ``pneunet-grasp bench solvers`` (``solvers_details.json``, key ``auto``; paper defaults):

* the linear model's error against the full model grows like ``0.112 p~^2`` (least-squares fit for
  ``p~ <= 0.05``; the side strain is the worse of the two components), so a tolerance buys the pressure
  range ``p~ <~ 3 sqrt(tol)``: measured ``p~ <= 0.030`` for 1e-4, ``0.089`` for 1e-3, ``0.236`` for 1e-2;
* as a pressure error (the pressure change that would move the full model's state as much:
  ``error / |dx/dp~|``), the linear model's error at the end of that range is ``4.4e-4`` for 1e-4,
  ``3.9e-3`` for 1e-3 and ``2.6e-2`` for 1e-2, i.e. 0.02, 0.19 and 1.3 kPa at ``mu = 50 kPa``.

1e-3 is the loosest decade whose pressure-equivalent error (0.19 kPa) stays below 0.5 % of the
environment's 60 kPa range (0.3 kPa), the accuracy class of a common proportional pressure regulator:
an error the real actuator's supply could not resolve. 1e-2 (1.3 kPa, over 2 % of the range, and a
range reaching the contact onset at ``p~ ~ 0.27``) would not.
"""

_DEFAULT_PARAMS = ActuatorParams()


class ModelAnswer(NamedTuple):
    """What :func:`equilibrium_for_model` answers: an :class:`Equilibrium` and the model that produced it.

    Attributes:
        equilibrium: the state (pass it back as ``previous``, or to the package's solver as ``initial``). For the
            linear model, ``energy``, ``volume_change``, ``gradient_norm`` and ``min_eigenvalue`` are those of
            the quadratic model (:func:`pneunet_env.physics.linear.linear_equilibrium`).
        model: ``"full"`` or ``"linear"``: the model actually used (``auto`` picks one per call).
        error_estimate: estimated state error ``max(|d kappa~|, |d e_s|)`` against the full model's
            equilibrium: 0 for the full model, one full-Newton step's length for the linear one under ``auto``,
            NaN (not computed) for ``model="linear"``.
    """

    equilibrium: Equilibrium
    model: str
    error_estimate: float


def check_model(model: str) -> str:
    """Return ``model`` if it is one of :data:`MODELS`; ``ValueError`` naming it otherwise."""
    if not isinstance(model, str) or model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    return model


def equilibrium_for_model(
    model: str,
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    previous: Equilibrium | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
    tolerance: float = AUTO_TOLERANCE,
) -> ModelAnswer:
    """The equilibrium at ``p~`` under ``model`` (``"full"``, ``"linear"`` or ``"auto"``).

    Args:
        model: one of :data:`MODELS`.
        pressure: ``p~ = p/mu >= 0``.
        object_stiffness: ``k~ = k_obj w/mu >= 0`` (0: no object).
        object_curvature: ``w kappa_obj`` in ``(0, pi)``.
        params: the actuator; paper defaults if ``None``.
        previous: the previous step's equilibrium (quasi-static history); ``None`` loads from rest.
        options: the full model's solver tolerances.
        tolerance: ``auto`` only: the largest estimated state error accepted from the linear model
            (default :data:`AUTO_TOLERANCE`, derived from the solver study).

    Returns:
        A :class:`ModelAnswer` ``(equilibrium, model, error_estimate)``.
    """
    model = check_model(model)
    params = _DEFAULT_PARAMS if params is None else params
    p = check_pressure(pressure)
    kobj, ko = check_object(object_stiffness, object_curvature)
    if model == "linear":
        return ModelAnswer(linear_equilibrium(p, kobj, ko, params), "linear", math.nan)
    if model == "auto":
        tol = check_finite("tolerance", tolerance)
        if tol <= 0.0:
            raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
        state = linear_state(p, kobj, ko, params) if p <= linear_reach(params, tol) else None
        if state is not None and not math.isnan(state[0]) and _on_linear_branch(previous, kobj, ko, params, tol):
            k, s = state[0], state[1]
            # Skip the object term when the linear state is out of contact (it is exactly zero there).
            kt = kobj if (kobj > 0.0 and k > ko) else 0.0
            est = linear_error_estimate(k, s, p, kt, ko, params)
            if kt == 0.0 and kobj > 0.0 and k + est >= ko:
                est = math.inf  # the full equilibrium might be in contact: let the full model decide
            if est <= ESTIMATE_SAFETY * tol:
                return ModelAnswer(linear_state_equilibrium(p, state, kobj, ko, params), "linear", est)
    return ModelAnswer(solve_equilibrium(p, kobj, ko, params, initial=previous, options=options), "full", 0.0)


def _on_linear_branch(previous: Equilibrium | None, kobj: float, ko: float, params: ActuatorParams,
                      tol: float) -> bool:
    """Whether the quasi-static history is on the (unique) branch the linear model describes.

    A previous linear answer (same object) is on it by construction: its state is ``linear_state`` at its pressure.
    """
    if previous is None:
        return True  # loading from rest follows the linear branch while the linear model is accurate
    k, s, *_ = linear_state(previous.pressure, kobj, ko, params)
    return not math.isnan(k) and max(abs(previous.curvature - k), abs(previous.side_strain - s)) <= 2.0 * tol

