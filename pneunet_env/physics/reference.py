"""An independent high-precision reference for the equilibrium (mpmath, 30+ digits).

Written directly from ``docs/physics.md`` (the paper's eqs. 2.1-2.11 and supplement eq. 10), with none of
:mod:`pneunet_env.physics.mechanics`'s code: the volume keeps the paper's ``csc + cot`` form (its ``1/kappa``
cancellation is harmless at this precision), and the gradient and Hessian come from mpmath's numerical
differentiation at high precision, not from the hand-derived formulas. It is slow (milliseconds per
evaluation) and exists to check the fast solver: tests and ``pneunet-grasp bench solvers`` use it.

Requires ``mpmath`` (in the ``dev`` extra).
"""

from __future__ import annotations

import numpy as np

from pneunet_env.physics.params import ActuatorParams, check_object

__all__ = ["reference_energy", "reference_minimum", "reference_path", "ReferenceError"]


class ReferenceError(RuntimeError):
    """The high-precision Newton iteration did not reach a strict minimum."""


def _mp():
    try:
        import mpmath
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("pneunet_env.physics.reference needs mpmath: pip install 'pneunet-env[dev]'") from exc
    return mpmath


def reference_energy(mp, kappa, side_strain, pressure, params: ActuatorParams, object_stiffness, object_curvature):
    """The energy ``U/(mu t w^2)`` in mpmath arithmetic (``+inf`` outside the domain), from model.md."""
    d, hb, hs, hm, eb, nu, J = (mp.mpf(v) for v in params.as_tuple())
    k, s, p = mp.mpf(kappa), mp.mpf(side_strain), mp.mpf(pressure)
    kobj, ko = mp.mpf(object_stiffness), mp.mpf(object_curvature)
    em = d * (1 + s) * k  # eq. 2.2 (w = 1)

    def i1(e):  # eq. 2.10
        return 2 * (1 + e) ** 2 + (1 + e) ** -4

    if not (0 <= k < mp.pi) or s <= -1 or em <= -1 or i1(s) - 3 >= J or i1(em) - 3 >= J:
        return mp.inf

    def gent(e):  # eq. 2.1, per unit mu
        return -J / 2 * mp.log(1 - (i1(e) - 3) / J)

    v0 = (1 - hs) * (d - hm / 2 - hb / 2)  # supplement eq. 1
    r2 = d * (1 + s) - hm / 2 * (1 + em) ** -2 - hb / 2  # supplement eq. 6
    if k == 0:
        v1 = (1 + s) * r2 * (1 - hs * (1 + s) ** -2)  # the kappa -> 0 limit of eq. 10
    else:
        lam = hs / 2 * (1 + s) ** -2 * (mp.csc(k) + mp.cot(k))  # supplement eq. 9
        r1 = 1 / k + hb / 2 - lam  # supplement eq. 5
        v1 = (1 + s) * k / 2 * r2 * (r2 + 2 * r1)  # supplement eq. 4
    u_p = -p * (v1 - v0)  # eq. 2.4
    u_b = eb * hb**3 * k**2 / (24 * (1 - nu**2))  # eq. 2.6
    u_s = d * hs * gent(s)  # eq. 2.7
    u_m = hm * gent(em)  # eq. 2.8
    u_obj = kobj / 2 * (1 / ko - 1 / k) ** 2 if k > ko else mp.mpf(0)  # eq. 2.11
    return u_p + u_b + u_s + u_m + u_obj


def reference_minimum(
    pressure: float,
    object_stiffness: float,
    object_curvature: float,
    params: ActuatorParams,
    x0: tuple[float, float],
    digits: int = 30,
    max_iter: int = 60,
) -> tuple[float, float]:
    """Newton's method at ``digits`` digits from a nearby ``x0 = (kappa~, e_s)``; returns ``(kappa~, e_s)``.

    Raises :class:`ReferenceError` unless it converges (step below ``10^-(digits-8)``) to a point whose
    Hessian is positive definite.
    """
    kobj, ko = check_object(object_stiffness, object_curvature)
    if float(pressure) == 0.0:
        # Every term but the pressure work is >= 0 and vanishes only at rest: the rest state is the exact minimum.
        return 0.0, 0.0
    mp = _mp()
    with mp.workdps(digits + 10):
        f = lambda k, s: reference_energy(mp, k, s, pressure, params, kobj, ko)  # noqa: E731
        x = [mp.mpf(x0[0]), mp.mpf(x0[1])]
        tol = mp.mpf(10) ** (-(digits - 8))
        for _ in range(max_iter):
            g = [mp.diff(f, x, (1, 0)), mp.diff(f, x, (0, 1))]
            hkk, hks, hss = mp.diff(f, x, (2, 0)), mp.diff(f, x, (1, 1)), mp.diff(f, x, (0, 2))
            det = hkk * hss - hks * hks
            dk = -(hss * g[0] - hks * g[1]) / det
            ds = -(hkk * g[1] - hks * g[0]) / det
            x = [x[0] + dk, x[1] + ds]
            if abs(dk) + abs(ds) < tol:
                break
        else:
            raise ReferenceError(f"no convergence at p~={pressure}, k~={object_stiffness} from x0={x0}")
        hkk, hks, hss = mp.diff(f, x, (2, 0)), mp.diff(f, x, (1, 1)), mp.diff(f, x, (0, 2))
        if not (hkk > 0 and hkk * hss - hks * hks > 0):
            raise ReferenceError(f"stationary point at p~={pressure} is not a minimum (Hessian not positive definite)")
        return float(x[0]), float(x[1])


def reference_path(
    pressures,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    digits: int = 30,
    refine: int = 20,
) -> tuple[np.ndarray, np.ndarray]:
    """High-precision equilibria along a quasi-static path: arrays ``(kappa~, e_s)``, one per pressure.

    The branch is chosen by following the path with the package's continuation on a grid ``refine``
    times finer than ``pressures`` (so every fold is localised finely); each requested point is then
    polished independently by :func:`reference_minimum`.
    """
    from pneunet_env.physics.solver import load_path

    params = ActuatorParams() if params is None else params
    ps = np.asarray(pressures, dtype=float)
    fine = [ps[0]]
    for a, b in zip(ps[:-1], ps[1:], strict=True):
        fine.extend(np.linspace(a, b, refine + 1)[1:])
    path = load_path(np.asarray(fine), object_stiffness, object_curvature, params)
    idx = np.arange(len(ps)) * refine
    ks = np.empty(len(ps))
    ss = np.empty(len(ps))
    for j, i in enumerate(idx):
        ks[j], ss[j] = reference_minimum(
            ps[j], object_stiffness, object_curvature, params, (path.curvature[i], path.side_strain[i]), digits
        )
    return ks, ss
