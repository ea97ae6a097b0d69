"""The linearised model: the quadratic expansion of the energy about rest (supplement eqs. 15-17).

About the rest state ``x = (kappa~, e_s) = 0`` the energy at pressure ``p~`` is, to second order in ``x``,

    U_lin(x; p) = -p (g . x + x.Q.x / 2) + x.K.x / 2

with ``K`` the walls' and base's stiffness at rest, ``g = dV/dx`` and ``Q = d2V/dx2`` the volume's
gradient and Hessian at rest (supplement eq. 15 keeps exactly these terms). Its minimiser is the
closed form (eq. 16)

    x(p) = p (K - p Q)^{-1} g,

whose leading order ``kappa~ = p g_k / K_kk`` is supplement eq. 17 (``K_ks = 0`` at rest). It holds
while ``K - p Q`` is positive definite (``p < valid_until``); before that, the balloon instability of the
full model (a nonlinear effect) already makes it wrong, which the solver study measures.

``K`` and ``g`` are closed-form; ``Q`` is the exact second derivative of the model's chamber volume at
rest, evaluated from :mod:`pneunet_env.physics.mechanics`.

With an object in contact, the Winkler term ``(k~/2)(1/kappa_obj - 1/kappa)^2`` is replaced by its own quadratic
expansion about first contact, ``(k~/2)(kappa - kappa_obj)^2 / kappa_obj^4``, so the model stays one 2x2 linear
solve (:func:`linear_state`; the contact is found by solving without the object first: the model is piecewise
linear). :func:`linear_equilibrium` returns that state as an :class:`~pneunet_env.physics.solver.Equilibrium`;
:func:`linear_error_estimate` estimates its distance to the full model's equilibrium by one Newton step of the
full energy, and :func:`linear_reach` the pressure up to which the free actuator's linear state is within a
tolerance. (The solver study's ``auto`` model, :mod:`pneunet_env.bench.models`, is built on these.)
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from pneunet_env.physics import mechanics
from pneunet_env.physics.contact import scalar_contact
from pneunet_env.physics.params import ActuatorParams, check_object
from pneunet_env.physics.solver import STATUS_CONVERGED, Equilibrium, check_pressure, params_tuple
from pneunet_env.physics.solver import evaluate_state as _kernel  # the energy kernel (compiled when numba is there)

__all__ = [
    "LinearModel",
    "ESTIMATE_SAFETY",
    "linear_state",
    "linear_equilibrium",
    "linear_state_equilibrium",
    "linear_error_estimate",
    "linear_reach",
]

ESTIMATE_SAFETY = 0.9
"""A linear state counts as within ``tol`` of the full one when its estimated error is below this fraction of ``tol``.

The one-Newton-step estimate (:func:`linear_error_estimate`) is exact to second order and slightly low: at the
paper's defaults it under-estimates the true error by 0.2 % at 1e-3 and 2.3 % at 1e-2 (free actuator), so 0.9
keeps the accepted error below the tolerance with room to spare.
"""


class LinearModel:
    """The quadratic (linearised) energy of an actuator, without an object.

    Attributes:
        stiffness: ``K``, 2x2, the energy's Hessian at rest at zero pressure (units ``mu t w^2``).
        volume_gradient: ``g = dV/d(kappa~, e_s)`` at rest (units ``w^2 t``).
        volume_hessian: ``Q``, the volume's Hessian at rest.
        valid_until: the smallest ``p~ > 0`` where ``K - p Q`` stops being positive definite (``inf`` if never).
    """

    def __init__(self, params: ActuatorParams | None = None) -> None:
        self.params = ActuatorParams() if params is None else params
        d, hb, hs, hm, _, _, _ = self.params.as_tuple()
        # K: base bending (eq. 2.6) and Gent walls at small strain (W ~ 6 mu e^2 per unit volume, eqs. 2.7-2.8).
        self.stiffness = np.array([[self.params.bending_stiffness, 0.0], [0.0, 12.0 * d * hs]])
        # g: the volume's gradient at rest (supplement eq. 10 differentiated at kappa = e_s = 0).
        r2 = d - 0.5 * hm - 0.5 * hb
        g_k = self.params.small_pressure_slope * self.params.bending_stiffness
        g_s = (r2 + d) * (1.0 - hs) + 2.0 * hs * r2
        self.volume_gradient = np.array([g_k, g_s])
        H0 = mechanics.hessian(0.0, 0.0, 0.0, self.params)
        H1 = mechanics.hessian(0.0, 0.0, 1.0, self.params)
        self.volume_hessian = H0 - H1  # the pressure work is -p V
        A, B, C = self.volume_hessian[0, 0], self.volume_hessian[0, 1], self.volume_hessian[1, 1]
        K1, K2 = self.stiffness[0, 0], self.stiffness[1, 1]
        # det(K - pQ) = (AC - B^2) p^2 - (K1 C + K2 A) p + K1 K2; the first positive root, if any.
        a, b, c = A * C - B * B, -(K1 * C + K2 * A), K1 * K2
        roots = np.roots([a, b, c]) if abs(a) > 1e-300 else np.array([-c / b]) if b != 0.0 else np.array([])
        real = [float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0.0]
        diag = [K1 / A if A > 0.0 else math.inf, K2 / C if C > 0.0 else math.inf]
        self.valid_until = min(real + diag) if real or np.isfinite(diag).any() else math.inf

    def energy(self, kappa, side_strain, pressure):
        """``U_lin / (mu t w^2)`` (broadcasts)."""
        x = np.stack(np.broadcast_arrays(np.asarray(kappa, float), np.asarray(side_strain, float)), axis=-1)
        p = np.asarray(pressure, dtype=float)
        gx = x @ self.volume_gradient
        xQx = np.einsum("...i,ij,...j->...", x, self.volume_hessian, x)
        xKx = np.einsum("...i,ij,...j->...", x, self.stiffness, x)
        return -p * (gx + 0.5 * xQx) + 0.5 * xKx

    def state(self, pressure):
        """The minimiser ``(kappa~, e_s)`` at ``p~`` (eq. 16); NaN at or beyond :attr:`valid_until`."""
        p = np.asarray(pressure, dtype=float)
        K, Q, g = self.stiffness, self.volume_hessian, self.volume_gradient
        a = K[0, 0] - p * Q[0, 0]
        b = -p * Q[0, 1]
        c = K[1, 1] - p * Q[1, 1]
        det = a * c - b * b
        ok = (p >= 0.0) & (p < self.valid_until)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(ok, p * (c * g[0] - b * g[1]) / det, np.nan)
            s = np.where(ok, p * (a * g[1] - b * g[0]) / det, np.nan)
        return k, s

    def curvature(self, pressure):
        """Closed-form ``kappa~(p~)`` of the quadratic energy; ``p g_k / K_kk + O(p^2)`` (eq. 17)."""
        return self.state(pressure)[0]


_DEFAULT_PARAMS = ActuatorParams()


@lru_cache(maxsize=128)
def _linear_coefficients(params: ActuatorParams) -> tuple[float, ...]:
    """``(K11, K12, K22, Q11, Q12, Q22, g0, g1)`` of :class:`LinearModel` as floats (cached per actuator)."""
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
    ``e_s`` are NaN where the model's Hessian is not positive definite (beyond :attr:`LinearModel.valid_until`).
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


def linear_equilibrium(
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
) -> Equilibrium:
    """The linear model's equilibrium at ``p~`` (closed form, history-free), as an :class:`Equilibrium`.

    ``energy``, ``volume_change`` and ``min_eigenvalue`` are those of the quadratic model, ``gradient_norm`` is 0
    (the closed form is its exact minimiser), ``status`` is ``STATUS_CONVERGED`` with no iterations or sub-steps;
    ``contact_force`` and ``indentation`` follow eq. 3.1 from the state, as for the full model. Its distance to
    the full model's equilibrium is not part of it: see :func:`linear_error_estimate`.

    Raises ``ValueError`` for invalid input, and for a pressure at or beyond the linear model's validity
    (:attr:`LinearModel.valid_until`, ``p~ ~ 1.71`` at the paper's defaults) where its energy has no minimum.
    """
    params = _DEFAULT_PARAMS if params is None else params
    p = check_pressure(pressure)
    kobj, ko = check_object(object_stiffness, object_curvature)
    k, s, lmin, energy, vol = linear_state(p, kobj, ko, params)
    if math.isnan(k):
        raise ValueError(
            f"pressure p~={p!r} is beyond the linear model's validity (its Hessian is not positive definite "
            f"there; valid below p~={LinearModel(params).valid_until:.4g} without contact)"
        )
    return linear_state_equilibrium(p, (k, s, lmin, energy, vol), kobj, ko, params)


def linear_state_equilibrium(
    pressure: float, state: tuple[float, float, float, float, float], object_stiffness: float,
    object_curvature: float, params: ActuatorParams,
) -> Equilibrium:
    """The :class:`Equilibrium` of a finite :func:`linear_state` result ``state`` (no validation; see
    :func:`linear_equilibrium`)."""
    k, s, lmin, energy, vol = state
    delta, force, touching = scalar_contact(k, object_stiffness, object_curvature)
    return Equilibrium(
        pressure, k, s, params.chamber_height * (1.0 + s) * k, force, delta, touching, vol, energy,
        0.0,  # gradient_norm: the closed form is the quadratic model's exact minimiser
        lmin, True, 0, 0, False, STATUS_CONVERGED, object_stiffness, object_curvature,
    )


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
def linear_reach(params: ActuatorParams, tolerance: float, step: float = 1e-3) -> float:
    """The largest pressure up to which the free actuator's linear state is within ``tolerance`` of the full one.

    (Within ``ESTIMATE_SAFETY * tolerance`` by the error estimate: :data:`ESTIMATE_SAFETY`.)

    Scans ``p~ = step, 2 step, ...`` with :func:`linear_error_estimate` (no full solve; a few ms, cached per
    ``(params, tolerance)``).
    """
    valid = LinearModel(params).valid_until
    i = 0
    while (i + 1) * step < valid:
        p = (i + 1) * step
        k, s, *_ = linear_state(p, 0.0, 1.0, params)
        if math.isnan(k) or linear_error_estimate(k, s, p, 0.0, 1.0, params) > ESTIMATE_SAFETY * tolerance:
            break
        i += 1
    return i * step
