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
"""

from __future__ import annotations

import math

import numpy as np

from pneunet_env.physics import mechanics
from pneunet_env.physics.params import ActuatorParams

__all__ = ["LinearModel"]


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
