"""A model no bigger than the scene needs: ``"full"``, ``"linear"`` or ``"auto"``.

* ``"full"`` — the nonlinear energy (:mod:`pneunet_env.physics.mechanics`), minimised by the package's
  safeguarded Newton solver with pressure continuation (:func:`pneunet_env.physics.solver.solve_equilibrium`).
* ``"linear"`` — the quadratic expansion of the energy about rest (:class:`pneunet_env.physics.linear.LinearModel`,
  supplement eqs. 15-17), solved in closed form. With an object in contact, the Winkler term
  ``(k~/2)(1/kappa_obj - 1/kappa)^2`` is replaced by its own quadratic expansion about first contact,
  ``(k~/2)(kappa - kappa_obj)^2 / kappa_obj^4``, so the model stays one 2x2 linear solve (the contact
  is found by solving without the object first: the model is piecewise linear). Without contact the
  object term is skipped.
* ``"auto"`` — the linear model wherever its error against the full model is below
  :data:`AUTO_TOLERANCE`, the full model elsewhere. The error is not guessed from the pressure: it is
  estimated at every call by one Newton step of the *full* energy from the linear state
  (``|H^-1 grad U|``, exact to second order in the error), which costs one evaluation of the energy's
  derivatives instead of a Newton solve with continuation. The linear state is also refused when the
  previous state is not on the branch the linear model describes (after a snap-through), or when the
  error estimate would straddle contact onset, where the Hessian jumps. Out of contact the object term
  is skipped: the linear model is then the free one. (The full model's object term is exactly zero out of
  contact and costs a few flops in the compiled kernel, so skipping it there would save nothing.)

All quantities are dimensionless (lengths / ``w``, stresses and pressure / ``mu``, energy / ``mu t w^2``);
see :mod:`pneunet_env.physics.units` for physical units. ``pneunet-grasp bench solvers`` measures what
``auto`` saves and costs (``docs/solvers.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache

from pneunet_env.physics import mechanics
from pneunet_env.physics.linear import LinearModel
from pneunet_env.physics.params import ActuatorParams, check_finite, check_object
from pneunet_env.physics.solver import (
    DEFAULT_OPTIONS,
    Equilibrium,
    SolverOptions,
    check_pressure,
    params_tuple,
    solve_equilibrium,
)

try:  # the solver's compiled energy kernel (numba when installed): ~0.3 us per evaluation instead of ~5 us
    from pneunet_env.physics.solver import _evaluate as _kernel
except ImportError:  # pragma: no cover - an older solver module: the same formulas in plain Python

    def _kernel(k, s, p, prm, kobj, ko):
        return mechanics.scalar_terms(k, s, p, *prm, kobj, ko)

__all__ = [
    "MODELS",
    "AUTO_TOLERANCE",
    "ModelEquilibrium",
    "check_model",
    "linear_state",
    "linear_equilibrium",
    "linear_error_estimate",
    "linear_reach",
    "equilibrium_for_model",
]

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


_ESTIMATE_SAFETY = 0.9
"""``auto`` accepts the linear state when the estimated error is below this fraction of the tolerance.

The one-Newton-step estimate is exact to second order and slightly low: at the paper's defaults it
under-estimates the true error by 0.2 % at 1e-3 and 2.3 % at 1e-2 (free actuator), so 0.9 keeps the
accepted error below the tolerance with room to spare.
"""


def check_model(model: str) -> str:
    """Return ``model`` if it is one of :data:`MODELS`; ``ValueError`` naming it otherwise."""
    if not isinstance(model, str) or model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    return model


@dataclass(frozen=True)
class ModelEquilibrium(Equilibrium):
    """An :class:`~pneunet_env.physics.solver.Equilibrium` with the model that produced it.

    It can be passed back as ``previous`` / ``initial`` wherever an ``Equilibrium`` is accepted.

    Attributes (beyond :class:`~pneunet_env.physics.solver.Equilibrium`'s):
        model: ``"full"`` or ``"linear"``: the model actually used (``auto`` picks one per call).
        error_estimate: estimated state error ``max(|d kappa~|, |d e_s|)`` against the full model's
            equilibrium: 0 for the full model, one full-Newton step's length for the linear one.

    For the linear model, ``energy``, ``volume_change``, ``gradient_norm`` and ``min_eigenvalue`` are those
    of the quadratic model (its gradient vanishes at its minimiser); ``contact_force`` and ``indentation``
    follow eq. 3.1 from the state, as for the full model.
    """

    model: str = "full"
    error_estimate: float = 0.0


def _wrap(eq: Equilibrium, model: str, error_estimate: float) -> ModelEquilibrium:
    """``eq`` as a :class:`ModelEquilibrium` (a field copy; ``ModelEquilibrium(**fields)`` costs 5x more)."""
    new = object.__new__(ModelEquilibrium)
    new.__dict__.update(eq.__dict__)
    new.__dict__["model"] = model
    new.__dict__["error_estimate"] = error_estimate
    return new


_DEFAULT_PARAMS = ActuatorParams()
_MODEQ_FIELDS = tuple(f.name for f in fields(ModelEquilibrium))


@lru_cache(maxsize=128)
def _linear_coefficients(params: ActuatorParams) -> tuple[float, ...]:
    lm = LinearModel(params)
    K, Q, g = lm.stiffness, lm.volume_hessian, lm.volume_gradient
    return (float(K[0, 0]), float(K[0, 1]), float(K[1, 1]), float(Q[0, 0]), float(Q[0, 1]), float(Q[1, 1]),
            float(g[0]), float(g[1]))


def _solve2(a: float, b: float, c: float, r0: float, r1: float) -> tuple[float, float, float]:
    """Solve ``[[a, b], [b, c]] x = r``; also return the matrix's smallest eigenvalue (x NaN unless PD)."""
    m = 0.5 * (a + c)
    lmin = m - math.hypot(0.5 * (a - c), b)
    det = a * c - b * b
    if not (lmin > 0.0 and det > 0.0):
        return math.nan, math.nan, lmin
    return (c * r0 - b * r1) / det, (a * r1 - b * r0) / det, lmin


def linear_state(
    pressure: float, object_stiffness: float, object_curvature: float, params: ActuatorParams
) -> tuple[float, float, float, float, float]:
    """The linear model's minimiser at ``p~`` (floats, no validation).

    Returns ``(kappa~, e_s, lam_min, energy, volume_change)`` of the quadratic model (with the object's
    linearised Winkler term when the free linear state is past ``object_curvature``). ``kappa~`` and
    ``e_s`` are NaN where the model's Hessian is not positive definite (beyond
    :attr:`LinearModel.valid_until <pneunet_env.physics.linear.LinearModel.valid_until>`).
    """
    K11, K12, K22, Q11, Q12, Q22, g0, g1 = _linear_coefficients(params)
    p = pressure
    a, b, c = K11 - p * Q11, K12 - p * Q12, K22 - p * Q22
    k, s, lmin = _solve2(a, b, c, p * g0, p * g1)
    cw = 0.0
    if object_stiffness > 0.0 and k > object_curvature:
        # In contact: add the Winkler term expanded about first contact, (c/2)(k - ko)^2, c = k_obj / ko^4.
        ko = object_curvature
        cw = object_stiffness / ko**4
        k, s, lmin = _solve2(a + cw, b, c, p * g0 + cw * ko, p * g1)
    if math.isnan(k):
        return math.nan, math.nan, lmin, math.nan, math.nan
    vol = g0 * k + g1 * s + 0.5 * (Q11 * k * k + 2.0 * Q12 * k * s + Q22 * s * s)
    el = 0.5 * (K11 * k * k + 2.0 * K12 * k * s + K22 * s * s)
    if cw > 0.0:
        el += 0.5 * cw * (k - object_curvature) ** 2
    return k, s, lmin, el - p * vol, vol


def _equilibrium_from_linear(p, k, s, lmin, energy, vol, kobj, ko, params, error_estimate) -> ModelEquilibrium:
    delta = (k - ko) / (k * ko) if k > ko else 0.0
    eq = object.__new__(ModelEquilibrium)  # as ModelEquilibrium(...) (frozen, no __post_init__), 5x cheaper
    eq.__dict__.update(zip(_MODEQ_FIELDS, (
        p, k, s, params.chamber_height * (1.0 + s) * k, kobj * delta, delta, kobj > 0.0 and k > ko, vol, energy,
        0.0,  # gradient_norm: the closed form is the quadratic model's exact minimiser
        lmin, True, 0, 0, False, "linear model (closed form)", kobj, ko, "linear", error_estimate,
    ), strict=True))
    return eq


def linear_equilibrium(
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
) -> ModelEquilibrium:
    """The linear model's equilibrium at ``p~`` (closed form, history-free).

    Raises ``ValueError`` for invalid input, and for a pressure at or beyond the linear model's
    validity (:attr:`LinearModel.valid_until <pneunet_env.physics.linear.LinearModel.valid_until>`, ``p~ ~ 1.71`` at the
    paper's defaults) where its energy has no minimum. ``error_estimate`` is left NaN (not computed):
    see :func:`linear_error_estimate`.
    """
    params = _DEFAULT_PARAMS if params is None else params
    p = check_pressure(pressure)
    kobj, ko = check_object(object_stiffness, object_curvature)
    k, s, lmin, en, vol = linear_state(p, kobj, ko, params)
    if math.isnan(k):
        raise ValueError(
            f"pressure p~={p!r} is beyond the linear model's validity (its Hessian is not positive definite "
            f"there; valid below p~={LinearModel(params).valid_until:.4g} without contact)"
        )
    return _equilibrium_from_linear(p, k, s, lmin, en, vol, kobj, ko, params, math.nan)


def linear_error_estimate(
    kappa: float, side_strain: float, pressure: float, object_stiffness: float, object_curvature: float,
    params: ActuatorParams,
) -> float:
    """Estimated distance ``max(|d kappa~|, |d e_s|)`` from ``(kappa~, e_s)`` to the full model's equilibrium.

    One Newton step of the full energy: ``|H^-1 grad U|_inf`` (error of the estimate: second order in the
    distance). ``inf`` if the state is outside the domain, the full Hessian there is not positive
    definite, or the step crosses contact onset (where the Hessian jumps and the estimate is unreliable).
    """
    ok, _, gk, gs, hkk, hks, hss, *_ = _kernel(
        float(kappa), float(side_strain), float(pressure), params_tuple(params), float(object_stiffness),
        float(object_curvature),
    )
    if not ok:
        return math.inf
    dk, ds, lmin = _solve2(hkk, hks, hss, gk, gs)
    if not lmin > 0.0 or math.isnan(dk):
        return math.inf
    if object_stiffness > 0.0 and (kappa - object_curvature) * (kappa - dk - object_curvature) < 0.0:
        return math.inf
    return max(abs(dk), abs(ds))


@lru_cache(maxsize=256)
def linear_reach(params: ActuatorParams, tolerance: float = AUTO_TOLERANCE, step: float = 1e-3) -> float:
    """The largest pressure up to which the free actuator's linear state is within ``tolerance`` of the full one.

    (Within ``0.9 tolerance`` by the error estimate, the margin ``auto`` applies.)

    Scans ``p~ = step, 2 step, ...`` with :func:`linear_error_estimate` (no full solve; a few ms, cached per
    ``(params, tolerance)``). ``auto`` does not try the linear model above this pressure, so a scene at high
    pressure pays nothing for it.
    """
    valid = LinearModel(params).valid_until
    i = 0
    while (i + 1) * step < valid:
        p = (i + 1) * step
        k, s, *_ = linear_state(p, 0.0, 1.0, params)
        if math.isnan(k) or linear_error_estimate(k, s, p, 0.0, 1.0, params) > _ESTIMATE_SAFETY * tolerance:
            break
        i += 1
    return i * step


def equilibrium_for_model(
    model: str,
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    previous: Equilibrium | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
    tolerance: float = AUTO_TOLERANCE,
) -> ModelEquilibrium:
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
        A :class:`ModelEquilibrium` (an ``Equilibrium`` with ``model`` and ``error_estimate``).
    """
    model = check_model(model)
    params = _DEFAULT_PARAMS if params is None else params
    p = check_pressure(pressure)
    kobj, ko = check_object(object_stiffness, object_curvature)
    if model == "linear":
        return linear_equilibrium(p, kobj, ko, params)
    if model == "auto":
        tol = check_finite("tolerance", tolerance)
        if tol <= 0.0:
            raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
        if p <= linear_reach(params, tol):
            k, s, lmin, en, vol = linear_state(p, kobj, ko, params)
        else:
            k = math.nan
        if not math.isnan(k) and _on_linear_branch(previous, kobj, ko, params, tol):
            # Skip the object term when the linear state is out of contact (it is exactly zero there).
            kt = kobj if (kobj > 0.0 and k > ko) else 0.0
            est = linear_error_estimate(k, s, p, kt, ko, params)
            if kt == 0.0 and kobj > 0.0 and k + est >= ko:
                est = math.inf  # the full equilibrium might be in contact: let the full model decide
            if est <= _ESTIMATE_SAFETY * tol:
                return _equilibrium_from_linear(p, k, s, lmin, en, vol, kobj, ko, params, est)
    return _wrap(solve_equilibrium(p, kobj, ko, params, initial=previous, options=options), "full", 0.0)


def _on_linear_branch(previous: Equilibrium | None, kobj: float, ko: float, params: ActuatorParams,
                      tol: float) -> bool:
    """Whether the quasi-static history is on the (unique) branch the linear model describes."""
    if previous is None:
        return True  # loading from rest follows the linear branch while the linear model is accurate
    if isinstance(previous, ModelEquilibrium) and previous.model == "linear":
        return True
    k, s, *_ = linear_state(previous.pressure, kobj, ko, params)
    return not math.isnan(k) and max(abs(previous.curvature - k), abs(previous.side_strain - s)) <= 2.0 * tol
