"""The dimensionless energy of one pneu-net chamber, with its analytic gradient and Hessian.

This module is the one place the physics lives (``docs/physics.md`` gives the equations). Lengths are
in units of the chamber width ``w``, moduli and pressure in units of the elastomer shear modulus
``mu``, energy in units of ``mu t w^2``. The state is ``x = (kappa~, e_s)``: the base curvature
``kappa~ = w kappa`` and the side-wall strain ``e_s``.

    U(x; p) = -p (V1 - V0) + U_b + U_s + U_m + U_obj          (eq. 2.3)

The formulas are written once, in :func:`make_terms`, against a handful of elementary operations.
They are instantiated twice: with numpy ufuncs (the public functions here, which broadcast over
arrays, as the batched vector env needs) and with scalar ``math`` operations (:data:`scalar_terms`,
which the solver compiles with numba when it is installed). Tests check both against finite
differences and against each other.

The ``1/kappa`` cancellation of the paper's volume (supplement eq. 10) is removed with
``csc x + cot x = cot(x/2)``; ``kappa cot(kappa/2)`` is evaluated by its Taylor series near 0, so
everything is exact and smooth at ``kappa = 0``.

Domain: ``0 <= kappa~ < pi``, ``1 + e > 0`` and ``I1(e) - 3 < J`` for ``e = e_s`` and ``e = e_m``.
Outside it the energy is ``+inf`` (never NaN); the gradient and Hessian are undefined there and are
returned as NaN, so callers test :func:`in_domain` (or a finite energy) first, as the solver does.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from pneunet_env.physics.contact import make_contact
from pneunet_env.physics.params import ActuatorParams

__all__ = [
    "EnergyDerivatives",
    "energy",
    "energy_grad_hess",
    "gradient",
    "hessian",
    "in_domain",
    "volume_change",
    "volume_gradient",
    "first_invariant",
    "kcot_half",
    "make_terms",
    "scalar_terms",
    "KCOT_SERIES_RADIUS",
]

KCOT_SERIES_RADIUS = 0.1
"""Below this ``|kappa~|``, ``kappa cot(kappa/2)`` and its derivatives use their Taylor series."""

# k cot(k/2) = sum_n C_n k^(2n), C_n = 2 a_n / 4^n where x cot x = sum a_n x^(2n). Truncation < 1e-17 for |k| < 0.1.
_C0, _C1, _C2, _C3, _C4, _C5 = 2.0, -1.0 / 6.0, -1.0 / 360.0, -1.0 / 15120.0, -1.0 / 604800.0, -1.0 / 23950080.0


def _identity(fn):
    return fn


def make_terms(log, sin, cos, where, maximum, fabs, jit=_identity):
    """Build the energy kernel from elementary operations (numpy ufuncs, or scalar ``math`` ones).

    ``jit`` decorates each built function (``numba.njit`` for the compiled scalar kernel).

    Returns ``(kcot, terms)``:

    * ``kcot(k) -> (c, c', c'')`` with ``c(k) = k cot(k/2)``;
    * ``terms(k, s, p, d, hb, hs, hm, eb, nu, J, kobj, ko) -> (ok, U, g_k, g_s, H_kk, H_ks, H_ss, dV, V_k, V_s)``:
      the domain flag, the energy, its gradient and Hessian entries, and the volume change with its
      gradient (the predictor of pressure continuation needs ``dV/dx``). Arguments: curvature
      ``k = kappa~``, side strain ``s = e_s``, pressure ``p~``, the seven :class:`ActuatorParams`
      fields, the object's ``k~_obj`` and ``w kappa_obj``.
    """

    indentation = make_contact(maximum, where, jit)[0]

    @jit
    def kcot(k):
        small = fabs(k) < KCOT_SERIES_RADIUS
        k2 = k * k
        c_s = _C0 + k2 * (_C1 + k2 * (_C2 + k2 * (_C3 + k2 * (_C4 + k2 * _C5))))
        c1_s = k * (2 * _C1 + k2 * (4 * _C2 + k2 * (6 * _C3 + k2 * (8 * _C4 + k2 * 10 * _C5))))
        c2_s = 2 * _C1 + k2 * (12 * _C2 + k2 * (30 * _C3 + k2 * (56 * _C4 + k2 * 90 * _C5)))
        kd = where(small, 1.0, k)  # a safe argument for the direct branch
        half = 0.5 * kd
        cot = cos(half) / sin(half)
        csc2 = 1.0 + cot * cot
        return (
            where(small, c_s, kd * cot),
            where(small, c1_s, cot - half * csc2),
            where(small, c2_s, csc2 * (half * cot - 1.0)),
        )

    @jit
    def gent(e, J):
        # Gent energy of an equibiaxial wall per unit reference volume, W/mu, with dW/de and d2W/de2.
        a = 1.0 + e
        a2 = a * a
        am4 = 1.0 / (a2 * a2)
        q = 2.0 * a2 + am4 - 3.0  # I1 - 3
        q1 = 4.0 * a - 4.0 * am4 / a
        q2 = 4.0 + 20.0 * am4 / a2
        r = 1.0 - q / J
        return -0.5 * J * log(r), 0.5 * q1 / r, 0.5 * (q2 / r + q1 * q1 / (J * r * r))

    @jit
    def terms(k, s, p, d, hb, hs, hm, eb, nu, J, kobj, ko):
        # Domain, evaluated on safe arguments so that nothing divides by zero or takes log(<0).
        ok = (k >= 0.0) & (k < math.pi) & (s > -1.0)
        s1 = where(ok, 1.0 + s, 1.0)
        m1 = 1.0 + d * s1 * where(ok, k, 0.0)
        ok = ok & (2.0 * s1 * s1 + s1**-4 - 3.0 < J) & (2.0 * m1 * m1 + m1**-4 - 3.0 < J)
        k = where(ok, k, 0.0)
        s = where(ok, s, 0.0)
        a = 1.0 + s
        em = d * a * k

        # Chamber volume (supplement eq. 10, w = 1): V1 = (a/2) G, G = k r2^2 + 2 r2 q, q = kappa r1.
        b = 1.0 + em
        B1, B2 = -2.0 * b**-3, 6.0 * b**-4  # e_m-derivatives of (1+e_m)^-2
        r2 = d * a - 0.5 * hm * b**-2 - 0.5 * hb
        r2_k = -0.5 * hm * B1 * d * a
        r2_s = d - 0.5 * hm * B1 * d * k
        r2_kk = -0.5 * hm * B2 * (d * a) ** 2
        r2_ks = -0.5 * hm * (B2 * d * a * d * k + B1 * d)
        r2_ss = -0.5 * hm * B2 * (d * k) ** 2
        c, c1, c2 = kcot(k)
        ia2 = a**-2
        q = 1.0 + 0.5 * hb * k - 0.5 * hs * ia2 * c
        q_k = 0.5 * hb - 0.5 * hs * ia2 * c1
        q_s = hs * ia2 / a * c
        q_kk = -0.5 * hs * ia2 * c2
        q_ks = hs * ia2 / a * c1
        q_ss = -3.0 * hs * ia2 * ia2 * c
        G = k * r2 * r2 + 2.0 * r2 * q
        G_k = r2 * r2 + 2.0 * k * r2 * r2_k + 2.0 * r2_k * q + 2.0 * r2 * q_k
        G_s = 2.0 * k * r2 * r2_s + 2.0 * r2_s * q + 2.0 * r2 * q_s
        G_kk = 4.0 * r2 * r2_k + 2.0 * k * (r2_k * r2_k + r2 * r2_kk) + 2.0 * r2_kk * q + 4.0 * r2_k * q_k
        G_kk = G_kk + 2.0 * r2 * q_kk
        G_ks = 2.0 * r2 * r2_s + 2.0 * k * (r2_s * r2_k + r2 * r2_ks) + 2.0 * r2_ks * q + 2.0 * r2_s * q_k
        G_ks = G_ks + 2.0 * r2_k * q_s + 2.0 * r2 * q_ks
        G_ss = 2.0 * k * (r2_s * r2_s + r2 * r2_ss) + 2.0 * r2_ss * q + 4.0 * r2_s * q_s + 2.0 * r2 * q_ss
        dv = 0.5 * a * G - (1.0 - hs) * (d - 0.5 * hm - 0.5 * hb)
        v_k, v_s = 0.5 * a * G_k, 0.5 * G + 0.5 * a * G_s
        v_kk, v_ks, v_ss = 0.5 * a * G_kk, 0.5 * G_k + 0.5 * a * G_ks, G_s + 0.5 * a * G_ss

        # Walls (eqs. 2.6-2.8) and object on a Winkler foundation (eqs. 2.9, 2.11).
        ws, ws1, ws2 = gent(s, J)
        wm, wm1, wm2 = gent(em, J)
        kb = eb * hb**3 / (12.0 * (1.0 - nu * nu))
        kk = maximum(k, ko)
        delta = indentation(k, ko)  # eq. 3.1: 1/ko - 1/k in contact, else 0
        contact = where(k > ko, 1.0, 0.0)

        U = -p * dv + 0.5 * kb * k * k + d * hs * ws + hm * wm + 0.5 * kobj * delta * delta
        gk = -p * v_k + kb * k + hm * wm1 * d * a + kobj * delta / (kk * kk)
        gs = -p * v_s + d * hs * ws1 + hm * wm1 * d * k
        hkk = -p * v_kk + kb + hm * wm2 * (d * a) ** 2 + kobj * (contact / kk**4 - 2.0 * delta / kk**3)
        hks = -p * v_ks + hm * (wm2 * d * a * d * k + wm1 * d)
        hss = -p * v_ss + d * hs * ws2 + hm * wm2 * (d * k) ** 2
        return ok, where(ok, U, math.inf), gk, gs, hkk, hks, hss, dv, v_k, v_s

    return kcot, terms


def _swhere(c, a, b):
    return a if c else b


def _smax(a, b):
    return a if a > b else b


_np_kcot, _np_terms = make_terms(np.log, np.sin, np.cos, np.where, np.maximum, np.abs)
scalar_terms = make_terms(math.log, math.sin, math.cos, _swhere, _smax, abs)[1]
"""``scalar_terms``: the energy kernel on Python floats (pure ``math``; the solver may numba-compile it)."""


class EnergyDerivatives(NamedTuple):
    """The energy and its analytic first and second derivatives with respect to ``(kappa~, e_s)``."""

    energy: np.ndarray
    gradient: np.ndarray  # shape (..., 2)
    hessian: np.ndarray  # shape (..., 2, 2)


def _call(kappa, side_strain, pressure, params: ActuatorParams, object_stiffness, object_curvature):
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _np_terms(
            np.asarray(kappa, dtype=float),
            np.asarray(side_strain, dtype=float),
            np.asarray(pressure, dtype=float),
            *params.as_tuple(),
            np.asarray(object_stiffness, dtype=float),
            np.asarray(object_curvature, dtype=float),
        )


def energy_grad_hess(
    kappa, side_strain, pressure, params: ActuatorParams, object_stiffness=0.0, object_curvature=0.02
) -> EnergyDerivatives:
    """The energy ``U/(mu t w^2)``, its gradient and its Hessian in ``(kappa~, e_s)``; broadcasts.

    Args:
        kappa: ``kappa~ = w kappa``, base curvature.
        side_strain: ``e_s``.
        pressure: ``p~ = p / mu``.
        params: the actuator.
        object_stiffness: ``k~_obj = k_obj w / mu`` (0: no object).
        object_curvature: ``w kappa_obj``.

    Outside the domain the energy is ``+inf`` and the derivatives NaN.
    """
    ok, U, gk, gs, hkk, hks, hss, *_ = _call(kappa, side_strain, pressure, params, object_stiffness, object_curvature)
    gk, gs, hkk, hks, hss = (np.where(ok, v, np.nan) for v in (gk, gs, hkk, hks, hss))
    grad = np.stack(np.broadcast_arrays(gk, gs), axis=-1)
    hess = np.stack(np.broadcast_arrays(hkk, hks, hks, hss), axis=-1).reshape(grad.shape[:-1] + (2, 2))
    return EnergyDerivatives(np.asarray(U, dtype=float), grad, hess)


def energy(kappa, side_strain, pressure, params: ActuatorParams, object_stiffness=0.0, object_curvature=0.02):
    """The energy ``U/(mu t w^2)``; ``+inf`` outside the domain. See :func:`energy_grad_hess`."""
    return energy_grad_hess(kappa, side_strain, pressure, params, object_stiffness, object_curvature).energy


def gradient(kappa, side_strain, pressure, params: ActuatorParams, object_stiffness=0.0, object_curvature=0.02):
    """``(dU/dkappa~, dU/de_s)``, shape ``(..., 2)``. See :func:`energy_grad_hess`."""
    return energy_grad_hess(kappa, side_strain, pressure, params, object_stiffness, object_curvature).gradient


def hessian(kappa, side_strain, pressure, params: ActuatorParams, object_stiffness=0.0, object_curvature=0.02):
    """The 2x2 Hessian in ``(kappa~, e_s)``, shape ``(..., 2, 2)``. See :func:`energy_grad_hess`."""
    return energy_grad_hess(kappa, side_strain, pressure, params, object_stiffness, object_curvature).hessian


def in_domain(kappa, side_strain, params: ActuatorParams):
    """Whether ``(kappa~, e_s)`` lies where the energy is finite (boolean array)."""
    return np.asarray(_call(kappa, side_strain, 0.0, params, 0.0, 1.0)[0], dtype=bool)


def volume_change(kappa, side_strain, params: ActuatorParams):
    """The chamber's volume change ``(V1 - V0)/(w^2 t)`` (supplement eqs. 1 and 10); NaN outside the domain."""
    out = _call(kappa, side_strain, 0.0, params, 0.0, 1.0)
    return np.where(out[0], out[7], np.nan)


def volume_gradient(kappa, side_strain, params: ActuatorParams):
    """``(dV/dkappa~, dV/de_s)`` in units of ``w^2 t``, shape ``(..., 2)``; NaN outside the domain."""
    out = _call(kappa, side_strain, 0.0, params, 0.0, 1.0)
    return np.stack(np.broadcast_arrays(np.where(out[0], out[8], np.nan), np.where(out[0], out[9], np.nan)), axis=-1)


def kcot_half(k):
    """``c(k) = k cot(k/2)`` and its first two derivatives, exact at ``k = 0`` (``c(0) = 2``); ``|k| < 2 pi``."""
    return _np_kcot(np.asarray(k, dtype=float))


def first_invariant(e):
    """``I1(e) = 2 (1+e)^2 + (1+e)^-4`` of an incompressible, equibiaxially stretched wall (eq. 2.10)."""
    a = 1.0 + np.asarray(e, dtype=float)
    return 2.0 * a * a + a**-4
