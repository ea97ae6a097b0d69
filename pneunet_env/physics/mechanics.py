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
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.physics.contact import make_contact
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.xp import identity, scalar_max, scalar_where

__all__ = [
    "Evaluation",
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


class Evaluation(NamedTuple):
    """The energy kernel at one point (or at N points, as arrays): what :func:`make_terms`' ``terms`` returns.

    ``ok`` is the domain flag; outside the domain ``energy`` is ``+inf`` and the rest is undefined (NaN or
    garbage): test ``ok`` first.
    """

    ok: Any  # in the domain
    energy: Any  # U / (mu t w^2)
    g_kappa: Any  # dU/dkappa~
    g_strain: Any  # dU/de_s
    h_kk: Any  # the Hessian's entries
    h_ks: Any
    h_ss: Any
    volume_change: Any  # (V1 - V0) / (w^2 t)
    v_kappa: Any  # dV/dkappa~
    v_strain: Any  # dV/de_s


def make_terms(log, tan, where, maximum, fabs, jit=identity):
    """Build the energy kernel from elementary operations (numpy ufuncs, or scalar ``math`` ones).

    ``jit`` decorates each built function (``numba.njit`` for the compiled scalar kernel).

    Returns ``(kcot, terms)``:

    * ``kcot(k) -> (c, c', c'')`` with ``c(k) = k cot(k/2)``;
    * ``terms(k, s, p, d, hb, hs, hm, eb, nu, J, kobj, ko) -> Evaluation``: the domain flag, the energy, its
      gradient and Hessian entries, and the volume change with its gradient (the predictor of pressure
      continuation needs ``dV/dx``). Arguments: curvature ``k = kappa~``, side strain ``s = e_s``, pressure
      ``p~``, the seven :class:`ActuatorParams` fields, the object's ``k~_obj`` and ``w kappa_obj``.

    Written for speed: every power and quotient of one number is a product of its reciprocal, taken once (nine
    divisions in all: ``1/(1 + e_s)``, ``1/(1 + e_m)``, ``1/J``, the two Gent factors ``1/(1 - (I1 - 3)/J)``, the
    bending stiffness, ``cot = 1/tan``, the indentation and ``1/max(kappa, kappa_obj)``), and ``cot(k/2)`` is one
    ``tan``. The results agree with the quotients written out to a few units in the last place (measured: the
    largest relative difference per evaluation is in ``docs/performance-solver.md``).
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
        cot = 1.0 / tan(half)  # 0 < |half| < pi: tan is finite and nonzero
        csc2 = 1.0 + cot * cot
        return (
            where(small, c_s, kd * cot),
            where(small, c1_s, cot - half * csc2),
            where(small, c2_s, csc2 * (half * cot - 1.0)),
        )

    @jit
    def gent(a, ia, J, ir, iJ):
        # Gent energy of an equibiaxial wall per unit reference volume, W/mu, with dW/de and d2W/de2, for a stretch
        # a = 1 + e with ia = 1/a, ir = 1/r (r = 1 - (I1 - 3)/J > 0) and iJ = 1/J.
        ia2 = ia * ia
        am4 = ia2 * ia2
        q1 = 4.0 * a - 4.0 * am4 * ia
        q2 = 4.0 + 20.0 * am4 * ia2
        w1 = 0.5 * q1 * ir
        return w1, 0.5 * q2 * ir + w1 * q1 * iJ * ir

    @jit
    def terms(k, s, p, d, hb, hs, hm, eb, nu, J, kobj, ko):
        # Domain, evaluated on safe arguments so that nothing divides by zero or takes log(<=0): the stretches
        # (1 + e_s and 1 + e_m >= 1 there) and the Gent factors r = 1 - (I1 - 3)/J, which must be positive.
        ok = (k >= 0.0) & (k < math.pi) & (s > -1.0)
        s1 = where(ok, 1.0 + s, 1.0)
        m1 = 1.0 + d * s1 * where(ok, k, 0.0)
        ia = 1.0 / s1
        ib = 1.0 / m1
        iJ = 1.0 / J
        ia2 = ia * ia
        ib2 = ib * ib
        r_s = 1.0 - (2.0 * s1 * s1 + ia2 * ia2 - 3.0) * iJ
        r_m = 1.0 - (2.0 * m1 * m1 + ib2 * ib2 - 3.0) * iJ
        ok = ok & (r_s > 0.0) & (r_m > 0.0)
        k = where(ok, k, 0.0)
        s = where(ok, s, 0.0)
        a = 1.0 + s  # = s1 in the domain
        b = where(ok, m1, 1.0)  # 1 + e_m
        ia = where(ok, ia, 1.0)
        ib = where(ok, ib, 1.0)
        r_s = where(ok, r_s, 1.0)
        r_m = where(ok, r_m, 1.0)
        ia2 = ia * ia
        ib2 = ib * ib

        # Chamber volume (supplement eq. 10, w = 1): V1 = (a/2) G, G = k r2^2 + 2 r2 q, q = kappa r1.
        B1, B2 = -2.0 * ib2 * ib, 6.0 * ib2 * ib2  # e_m-derivatives of (1+e_m)^-2
        r2 = d * a - 0.5 * hm * ib2 - 0.5 * hb
        r2_k = -0.5 * hm * B1 * d * a
        r2_s = d - 0.5 * hm * B1 * d * k
        r2_kk = -0.5 * hm * B2 * (d * a) ** 2
        r2_ks = -0.5 * hm * (B2 * d * a * d * k + B1 * d)
        r2_ss = -0.5 * hm * B2 * (d * k) ** 2
        c, c1, c2 = kcot(k)
        ia3 = ia2 * ia
        q = 1.0 + 0.5 * hb * k - 0.5 * hs * ia2 * c
        q_k = 0.5 * hb - 0.5 * hs * ia2 * c1
        q_s = hs * ia3 * c
        q_kk = -0.5 * hs * ia2 * c2
        q_ks = hs * ia3 * c1
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
        ws1, ws2 = gent(a, ia, J, 1.0 / r_s, iJ)
        wm1, wm2 = gent(b, ib, J, 1.0 / r_m, iJ)
        wall = -0.5 * J * (d * hs * log(r_s) + hm * log(r_m))  # d hs W(e_s) + hm W(e_m)
        kb = eb * hb**3 / (12.0 * (1.0 - nu * nu))
        kk = maximum(k, ko)
        ikk = 1.0 / kk
        ikk2 = ikk * ikk
        delta = indentation(k, ko)  # eq. 3.1: 1/ko - 1/k in contact, else 0
        contact = where(k > ko, 1.0, 0.0)

        U = -p * dv + 0.5 * kb * k * k + wall + 0.5 * kobj * delta * delta
        gk = -p * v_k + kb * k + hm * wm1 * d * a + kobj * delta * ikk2
        gs = -p * v_s + d * hs * ws1 + hm * wm1 * d * k
        hkk = -p * v_kk + kb + hm * wm2 * (d * a) ** 2 + kobj * ikk2 * (contact * ikk2 - 2.0 * delta * ikk)
        hks = -p * v_ks + hm * (wm2 * d * a * d * k + wm1 * d)
        hss = -p * v_ss + d * hs * ws2 + hm * wm2 * (d * k) ** 2
        return Evaluation(ok, where(ok, U, math.inf), gk, gs, hkk, hks, hss, dv, v_k, v_s)

    return kcot, terms


_np_kcot, _np_terms = make_terms(np.log, np.tan, np.where, np.maximum, np.abs)
scalar_terms = make_terms(math.log, math.tan, scalar_where, scalar_max, abs)[1]
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
    ev = _call(kappa, side_strain, pressure, params, object_stiffness, object_curvature)
    gk, gs, hkk, hks, hss = (np.where(ev.ok, v, np.nan) for v in (ev.g_kappa, ev.g_strain, ev.h_kk, ev.h_ks, ev.h_ss))
    grad = np.stack(np.broadcast_arrays(gk, gs), axis=-1)
    hess = np.stack(np.broadcast_arrays(hkk, hks, hks, hss), axis=-1).reshape(grad.shape[:-1] + (2, 2))
    return EnergyDerivatives(np.asarray(ev.energy, dtype=float), grad, hess)


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
    return np.asarray(_call(kappa, side_strain, 0.0, params, 0.0, 1.0).ok, dtype=bool)


def volume_change(kappa, side_strain, params: ActuatorParams):
    """The chamber's volume change ``(V1 - V0)/(w^2 t)`` (supplement eqs. 1 and 10); NaN outside the domain."""
    ev = _call(kappa, side_strain, 0.0, params, 0.0, 1.0)
    return np.where(ev.ok, ev.volume_change, np.nan)


def volume_gradient(kappa, side_strain, params: ActuatorParams):
    """``(dV/dkappa~, dV/de_s)`` in units of ``w^2 t``, shape ``(..., 2)``; NaN outside the domain."""
    ev = _call(kappa, side_strain, 0.0, params, 0.0, 1.0)
    return np.stack(np.broadcast_arrays(np.where(ev.ok, ev.v_kappa, np.nan), np.where(ev.ok, ev.v_strain, np.nan)),
                    axis=-1)


def kcot_half(k):
    """``c(k) = k cot(k/2)`` and its first two derivatives, exact at ``k = 0`` (``c(0) = 2``); ``|k| < 2 pi``."""
    return _np_kcot(np.asarray(k, dtype=float))


def first_invariant(e):
    """``I1(e) = 2 (1+e)^2 + (1+e)^-4`` of an incompressible, equibiaxially stretched wall (eq. 2.10)."""
    a = 1.0 + np.asarray(e, dtype=float)
    return 2.0 * a * a + a**-4
