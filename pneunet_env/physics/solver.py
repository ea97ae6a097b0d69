"""The quasi-static minimiser: a safeguarded Newton descent with pressure continuation.

An equilibrium at pressure ``p`` is the local minimum of the energy (:mod:`pneunet_env.physics.mechanics`)
reached from the previous state. The pieces, from the inside out:

* **minimise** — Newton's method on the 2-unknown energy, with the Hessian's eigenvalues replaced by
  ``max(|lambda|, floor)`` (so every direction is a descent direction, and saddles and maxima are
  left along negative curvature), an Armijo backtracking line search on the energy that rejects any
  trial point where the energy is not finite (so no iterate ever leaves the domain), and a stopping
  test that demands ``|grad| <= gtol`` *and* a positive-definite Hessian.
* **continue** — pressure continuation from an equilibrium ``(x0, p0)`` to ``p1``: sub-steps with a
  tangent predictor ``dx/dp = H^{-1} dV/dx`` and the Newton corrector. A sub-step is accepted only if
  the corrector converges within ``max_jump`` of the previous state (same branch); otherwise it is
  shrunk. If the branch cannot be followed even over ``min_step`` of pressure, its minimum has
  vanished at a fold: the state descends to the minimum that remains and ``snapped`` is reported.
  So the result does not depend on how the caller spaces its pressures, except at a fold (located
  to within ``min_step``).

Both are scalar code, written once in :func:`make_solver` over any energy kernel with the signature
of :data:`pneunet_env.physics.mechanics.scalar_terms`; with numba installed they are compiled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pneunet_env.physics import mechanics
from pneunet_env.physics._jit import njit
from pneunet_env.physics.params import ActuatorParams, check_finite, check_object

__all__ = [
    "SolverOptions",
    "Equilibrium",
    "LoadPath",
    "STATUS_MESSAGES",
    "make_solver",
    "minimise_state",
    "solve_equilibrium",
    "load_path",
    "sym2_eig",
    "sym2_eigvals",
    "ACCEPT_GTOL",
    "step_state",
    "params_tuple",
    "PREDICTED_JUMP_FRACTION",
]

ACCEPT_GTOL = 1e-10
"""Every state reported ``converged`` has ``|grad|_2`` at most this and a positive-definite Hessian."""

STATUS_MESSAGES = {
    0: "converged",
    1: "converged at the round-off floor",
    2: "iteration limit reached",
    3: "line search failed",
    4: "stalled",
    5: "start point outside the domain",
}


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances of the minimiser (dimensionless).

    Attributes:
        gtol: Stop once ``|grad|_2 <= gtol`` and the Hessian is positive definite. (A state that stalls
            at round-off above ``gtol`` still counts as converged if ``|grad|_2 <= 1e-10``.)
        max_iter: Newton iterations allowed for a full descent (after a snap, or a cold start).
        corrector_max_iter: Newton iterations allowed for a continuation corrector before the
            sub-step is shrunk.
        max_step: Largest pressure sub-step ``dp~``.
        min_step: Smallest pressure sub-step; a branch that cannot be followed over it has ended (fold).
        max_jump: Largest state change ``max(|d kappa~|, |d e_s|)`` over one sub-step on the same branch.
        eig_floor: Relative floor on the modified Hessian's eigenvalues.
    """

    gtol: float = 1e-11
    max_iter: int = 200
    corrector_max_iter: int = 12
    max_step: float = 0.05
    min_step: float = 1e-9
    max_jump: float = 0.02
    eig_floor: float = 1e-10

    def __post_init__(self) -> None:
        for name in ("gtol", "max_step", "min_step", "max_jump", "eig_floor"):
            v = check_finite(name, getattr(self, name))
            if v <= 0.0:
                raise ValueError(f"SolverOptions.{name} must be > 0, got {v!r}")
        for name in ("max_iter", "corrector_max_iter"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"SolverOptions.{name} must be >= 1, got {getattr(self, name)!r}")
        if self.min_step > self.max_step:
            raise ValueError(f"SolverOptions.min_step={self.min_step!r} exceeds max_step={self.max_step!r}")

    def as_tuple(self) -> tuple:
        return (
            float(self.gtol),
            int(self.max_iter),
            int(self.corrector_max_iter),
            float(self.max_step),
            float(self.min_step),
            float(self.max_jump),
            float(self.eig_floor),
        )


DEFAULT_OPTIONS = SolverOptions()
_DEFAULT_OPTIONS_TUPLE = DEFAULT_OPTIONS.as_tuple()


@njit
def sym2_eig(a, b, c):
    """Eigen-decomposition of the symmetric 2x2 matrix ``[[a, b], [b, c]]``.

    Returns ``(lam_min, lam_max, cos t, sin t)``: ``(cos t, sin t)`` is the eigenvector of ``lam_max``
    and ``(-sin t, cos t)`` that of ``lam_min``.
    """
    m = 0.5 * (a + c)
    r = math.hypot(0.5 * (a - c), b)
    lmax = m + r
    lmin = m - r
    if m > 0.0 and lmax > 0.0:
        lmin = (a * c - b * b) / lmax  # no cancellation when the matrix is ill-conditioned
    elif m < 0.0 and lmin < 0.0:
        lmax = (a * c - b * b) / lmin
    t = 0.5 * math.atan2(2.0 * b, a - c)
    return lmin, lmax, math.cos(t), math.sin(t)


@njit
def sym2_eigvals(a, b, c):
    """``(lam_min, lam_max)`` of ``[[a, b], [b, c]]``, as :func:`sym2_eig` computes them (no eigenvectors)."""
    m = 0.5 * (a + c)
    r = math.hypot(0.5 * (a - c), b)
    lmax = m + r
    lmin = m - r
    if m > 0.0 and lmax > 0.0:
        lmin = (a * c - b * b) / lmax
    elif m < 0.0 and lmin < 0.0:
        lmax = (a * c - b * b) / lmin
    return lmin, lmax


PREDICTED_JUMP_FRACTION = 0.75
"""A sub-step is sized so that the tangent predicts a state change of at most this fraction of ``max_jump``."""


def _make_parts(terms, jit=njit):
    """The solver's compiled pieces over ``terms``; see :func:`make_solver`.

    Besides ``minimise`` and ``follow`` this returns ``evaluate`` (the kernel on a packed parameter
    tuple), ``descend`` (the Newton descent from a point whose evaluation is already known, returning
    the evaluation at its result too, so no point is evaluated twice) and ``follow_ev`` (``follow``
    plus that final evaluation, from which the volume change is read).
    """

    @jit
    def evaluate(k, s, p, prm, kobj, ko):
        return terms(k, s, p, prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], kobj, ko)

    @jit
    def descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, ev, k0, s0, radius):
        # A finite radius marks a corrector: it gives up (status 2) once an iterate is farther than radius
        # from (k0, s0) or has a Hessian that is not positive definite.
        ok, U, g0, g1, hkk, hks, hss, _, _, _ = ev
        if not ok:
            return k, s, math.inf, math.inf, -math.inf, 0, 5, ev
        gnorm = math.hypot(g0, g1)
        lmin, lmax = sym2_eigvals(hkk, hks, hss)
        it = 0
        status = 2
        while True:
            if gnorm <= gtol and lmin > 0.0:
                status = 0
                break
            if it >= max_iter:
                break
            it += 1
            # Modified Newton direction -|H|^{-1} g, |H| with eigenvalues max(|lambda|, floor): where H is
            # safely positive definite that is the Newton direction itself, solved directly; elsewhere it is
            # built on the eigenbasis.
            scale = max(abs(lmin), abs(lmax), 1.0)
            if lmin >= eig_floor * scale:
                det = hkk * hss - hks * hks
                d0 = (hks * g1 - hss * g0) / det
                d1 = (hks * g0 - hkk * g1) / det
                slope = g0 * d0 + g1 * d1
            else:
                _, _, ct, st = sym2_eig(hkk, hks, hss)
                l1 = max(abs(lmin), eig_floor * scale)
                l2 = max(abs(lmax), eig_floor * scale)
                a2 = g0 * ct + g1 * st
                a1 = -g0 * st + g1 * ct
                d0 = -(a2 / l2) * ct + (a1 / l1) * st
                d1 = -(a2 / l2) * st - (a1 / l1) * ct
                slope = g0 * d0 + g1 * d1
                if lmin <= 0.0 and gnorm <= 1e3 * gtol:
                    # (Near-)stationary but not a minimum: leave along the negative-curvature direction.
                    v0, v1 = -st, ct
                    step = 1e-3 * max(1.0, abs(k))
                    if g0 * v0 + g1 * v1 > 0.0:
                        step = -step
                    d0, d1 = step * v0, step * v1
                    slope = min(g0 * d0 + g1 * d1, 0.0)
            t = 1.0
            accepted = False
            kn, sn, nnorm, evn = k, s, gnorm, ev
            while t > 1e-14:
                kn = k + t * d0
                sn = s + t * d1
                if kn < 0.0:
                    # Project onto the domain's edge kappa~ = 0, where the rest state (p~ = 0) lies: else every
                    # Newton step towards it overshoots and is halved, and the descent only converges linearly.
                    kn = 0.0
                evn = evaluate(kn, sn, p, prm, kobj, ko)
                if evn[0]:
                    nnorm = math.hypot(evn[2], evn[3])
                    # Armijo; at round-off level the energy cannot rank points, so fall back on |grad|.
                    if evn[1] <= U + 1e-4 * t * slope or (
                        abs(evn[1] - U) <= 1e-13 * max(1.0, abs(U)) and nnorm < gnorm
                    ):
                        accepted = True
                        break
                t *= 0.5
            if not accepted:
                status = 3
                break
            moved = abs(kn - k) + abs(sn - s)
            ev = evn
            k, s, U, g0, g1, hkk, hks, hss, gnorm = kn, sn, evn[1], evn[2], evn[3], evn[4], evn[5], evn[6], nnorm
            lmin, lmax = sym2_eigvals(hkk, hks, hss)
            if moved == 0.0:
                status = 4
                break
            if radius < math.inf and (lmin <= 0.0 or max(abs(k - k0), abs(s - s0)) > radius):
                break  # a corrector that leaves the branch's convex neighbourhood: the sub-step was too long
        if status != 0 and gnorm <= 1e-10 and lmin > 0.0:
            status = 1
        return k, s, U, gnorm, lmin, it, status, ev

    @jit
    def minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor):
        r = descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, evaluate(k, s, p, prm, kobj, ko), k, s, math.inf)
        return r[0], r[1], r[2], r[3], r[4], r[5], r[6]

    @jit
    def follow_ev(k, s, p0, p1, prm, kobj, ko, opts):
        gtol, max_iter, corr_iter, max_step, min_step, max_jump, eig_floor = opts
        # Polish the start so that the tangent is taken at an equilibrium (at an equilibrium: one evaluation).
        k, s, U, gn, lmin, iters, status, ev = descend(
            k, s, p0, prm, kobj, ko, gtol, max_iter, eig_floor, evaluate(k, s, p0, prm, kobj, ko), k, s, math.inf
        )
        substeps = 0
        snapped = False
        p = p0
        h = min(abs(p1 - p0), max_step)
        sign = 1.0 if p1 >= p0 else -1.0
        while p != p1 and status <= 1:
            # Tangent dx/dp = H^{-1} dV/dx at the current equilibrium, where the Hessian is positive definite.
            hkk, hks, hss, vk, vs = ev[4], ev[5], ev[6], ev[8], ev[9]
            det = hkk * hss - hks * hks
            tangent = hkk > 0.0 and det > 0.0
            tk = ts = 0.0
            if tangent:
                tk = (hss * vk - hks * vs) / det
                ts = (hkk * vs - hks * vk) / det
                rate = max(abs(tk), abs(ts))
                # Size the sub-step so that the predicted change stays well inside max_jump.
                if h * rate > PREDICTED_JUMP_FRACTION * max_jump:
                    h = max(PREDICTED_JUMP_FRACTION * max_jump / rate, min_step)
            remaining = abs(p1 - p)
            pt = p1 if h >= remaining * (1.0 - 1e-12) else p + sign * h
            started = False
            if tangent:
                kc = k + (pt - p) * tk
                sc = s + (pt - p) * ts
                evc = evaluate(kc, sc, pt, prm, kobj, ko)
                if evc[0]:
                    r = descend(kc, sc, pt, prm, kobj, ko, gtol, corr_iter, eig_floor, evc, k, s, max_jump)
                    started = True
            if not started:
                evs = evaluate(k, s, pt, prm, kobj, ko)
                r = descend(k, s, pt, prm, kobj, ko, gtol, corr_iter, eig_floor, evs, k, s, max_jump)
            iters += r[5]
            jump = max(abs(r[0] - k), abs(r[1] - s))
            if r[6] <= 1 and jump <= max_jump:
                p = pt
                k, s, U, gn, lmin, status, ev = r[0], r[1], r[2], r[3], r[4], r[6], r[7]
                substeps += 1
                if r[5] <= 4:
                    h = min(2.0 * h, max_step)
                continue
            if h > min_step:
                h = max(0.25 * h, min_step)
                continue
            # The branch ends within min_step of pressure: a fold. Descend to the minimum that remains.
            evs = evaluate(k, s, pt, prm, kobj, ko)
            r = descend(k, s, pt, prm, kobj, ko, gtol, max_iter, eig_floor, evs, k, s, math.inf)
            iters += r[5]
            substeps += 1
            if max(abs(r[0] - k), abs(r[1] - s)) > max_jump:
                snapped = True
            p = pt
            k, s, U, gn, lmin, status, ev = r[0], r[1], r[2], r[3], r[4], r[6], r[7]
            h = 0.1 * max_step
        return k, s, U, gn, lmin, iters, substeps, snapped, status, ev[7] if ev[0] else math.nan

    @jit
    def follow(k, s, p0, p1, prm, kobj, ko, opts):
        r = follow_ev(k, s, p0, p1, prm, kobj, ko, opts)
        return r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]

    return evaluate, descend, minimise, follow_ev, follow


def make_solver(terms, jit=njit):
    """Build ``(minimise, follow)`` for an energy kernel ``terms`` (see :func:`~.mechanics.make_terms`).

    ``minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor) -> (k, s, U, |g|, lam_min, iters, status)``
    ``follow(k, s, p0, p1, prm, kobj, ko, opts) -> (k, s, U, |g|, lam_min, iters, substeps, snapped, status)``

    ``prm`` is :meth:`ActuatorParams.as_tuple`, ``opts`` is :meth:`SolverOptions.as_tuple`; ``status``
    indexes :data:`STATUS_MESSAGES`.
    """
    parts = _make_parts(terms, jit)
    return parts[2], parts[4]


_evaluate, _descend, _minimise, _follow_ev, _follow = _make_parts(mechanics.make_terms(
    math.log, math.sin, math.cos, njit(mechanics._swhere), njit(mechanics._smax), abs, jit=njit
)[1])
step_state = _follow_ev
"""The fast entry point: ``step_state(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts)`` returns
``(kappa~, e_s, U, |grad|, lam_min, iterations, substeps, snapped, status, volume_change)``.

It is the compiled continuation behind :func:`solve_equilibrium` (same arguments as ``follow``, see
:func:`make_solver`), from an equilibrium ``(kappa~, e_s)`` at ``p0`` to ``p1``, with no validation and
no objects built: for callers on a hot path (an env's step), about a microsecond for a small pressure
step with numba. ``prm`` is :func:`params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`; ``status``
indexes :data:`STATUS_MESSAGES` (``<= 1``: converged); ``volume_change`` is ``(V1 - V0)/(w^2 t)`` at the
result (NaN only if the start was outside the domain). Inputs must already be valid (finite,
``p >= 0``, ``k~_obj >= 0``, ``0 < w kappa_obj < pi``, the start in the domain)."""


@dataclass(frozen=True)
class Equilibrium:
    """A quasi-static equilibrium (all dimensionless: lengths / ``w``, stresses / ``mu``).

    Attributes:
        pressure: ``p~ = p/mu``.
        curvature: ``kappa~ = w kappa`` of the base.
        side_strain: ``e_s``.
        top_strain: ``e_m = d (1 + e_s) kappa~``.
        contact_force: traction on the object ``F~ = F/mu`` (eq. 3.1); 0 out of contact.
        indentation: ``delta~ = w (1/kappa_obj - 1/kappa)`` in contact, else 0.
        in_contact: whether the actuator presses on the object (``kappa > kappa_obj``, ``k~_obj > 0``).
        volume_change: ``(V1 - V0)/(w^2 t)``.
        energy: ``U/(mu t w^2)``.
        gradient_norm: ``|grad U|_2`` at the returned state.
        min_eigenvalue: the Hessian's smallest eigenvalue there.
        converged: ``gradient_norm <= 1e-10`` and ``min_eigenvalue > 0``.
        iterations: Newton iterations spent (all sub-steps).
        substeps: pressure sub-steps taken.
        snapped: a fold was crossed: the previous branch's minimum vanished and the state jumped.
        status: what the minimiser reported (see :data:`STATUS_MESSAGES`).
        object_stiffness: ``k~_obj``.
        object_curvature: ``w kappa_obj``.
    """

    pressure: float
    curvature: float
    side_strain: float
    top_strain: float
    contact_force: float
    indentation: float
    in_contact: bool
    volume_change: float
    energy: float
    gradient_norm: float
    min_eigenvalue: float
    converged: bool
    iterations: int
    substeps: int
    snapped: bool
    status: str
    object_stiffness: float
    object_curvature: float

    @property
    def state(self) -> tuple[float, float]:
        """``(kappa~, e_s)``."""
        return (self.curvature, self.side_strain)


def check_pressure(pressure: float, name: str = "pressure") -> float:
    """``float(pressure)``; ``ValueError`` naming it unless finite and ``>= 0``."""
    p = check_finite(name, pressure)
    if p < 0.0:
        raise ValueError(f"{name} (p~ = p/mu) must be >= 0, got {pressure!r}")
    return p


_DEFAULT_PARAMS = ActuatorParams()


def params_tuple(params: ActuatorParams | None) -> tuple[float, ...]:
    """:meth:`ActuatorParams.as_tuple` ``(d, h_b, h_s, h_m, E_b, nu, J)`` without its deep copy; ``None``: defaults."""
    if params is None:
        params = _DEFAULT_PARAMS
    return (params.chamber_height, params.base_thickness, params.side_thickness, params.top_thickness,
            params.base_modulus, params.poisson_ratio, params.gent_limit)


def _equilibrium(p, out, d, kobj, kc) -> Equilibrium:
    """Build the :class:`Equilibrium` of a :func:`step_state` result (``d`` = chamber height)."""
    k, s, U, gn, lmin, iters, substeps, snapped, status, dv = out
    delta = (k - kc) / (k * kc) if (k > kc and kobj > 0.0) else 0.0  # no object (k~ = 0): no indentation
    return Equilibrium(
        p, k, s, d * (1.0 + s) * k, kobj * delta, delta, kobj > 0.0 and k > kc, dv, U, gn, lmin, status <= 1,
        iters, substeps, snapped, STATUS_MESSAGES[status], kobj, kc,
    )


def minimise_state(x0, pressure, params, object_stiffness=0.0, object_curvature=0.02, options=DEFAULT_OPTIONS):
    """Plain safeguarded descent from ``x0 = (kappa~, e_s)`` at fixed pressure (no continuation).

    Returns ``(kappa~, e_s, U, |grad|, lam_min, iterations, status)``.
    """
    o = options
    return _minimise(float(x0[0]), float(x0[1]), float(pressure), params_tuple(params), float(object_stiffness),
                     float(object_curvature), o.gtol, o.max_iter, o.eig_floor)


def solve_equilibrium(
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    initial: Equilibrium | tuple[float, float] | None = None,
    initial_pressure: float | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
) -> Equilibrium:
    """The quasi-static equilibrium at ``pressure`` (dimensionless throughout).

    Args:
        pressure: ``p~ = p/mu >= 0``.
        object_stiffness: ``k~ = k_obj w/mu >= 0``; 0 is the free actuator.
        object_curvature: ``w kappa_obj`` in ``(0, pi)``.
        params: the actuator; paper defaults if ``None``.
        initial: where to start. ``None``: quasi-static loading from rest (``p~ = 0``). An
            :class:`Equilibrium`: continue its branch from its pressure. A ``(kappa~, e_s)`` pair:
            continue from it at ``initial_pressure`` if given, else descend from it at ``pressure``.
        initial_pressure: the pressure at which a ``(kappa~, e_s)`` ``initial`` was in equilibrium.
        options: solver tolerances.

    Returns:
        An :class:`Equilibrium`. ``converged`` is false only if the minimiser failed; the state is
        then the last iterate (finite, in the domain), never NaN.

    A hot loop that needs no :class:`Equilibrium` can call the compiled :func:`step_state` directly.
    """
    prm = params_tuple(params)
    p = check_pressure(pressure)
    kobj, kc = check_object(object_stiffness, object_curvature)
    opts = _DEFAULT_OPTIONS_TUPLE if options is DEFAULT_OPTIONS else options.as_tuple()
    if initial is None:
        out = step_state(0.0, 0.0, 0.0, p, prm, kobj, kc, opts)
    elif isinstance(initial, Equilibrium):
        out = step_state(initial.curvature, initial.side_strain, initial.pressure, p, prm, kobj, kc, opts)
    else:
        try:
            x0 = (check_finite("initial curvature", initial[0]), check_finite("initial side_strain", initial[1]))
        except (TypeError, IndexError):
            raise ValueError(
                f"initial must be None, an Equilibrium or a (curvature, side_strain) pair, got {initial!r}"
            ) from None
        if not _evaluate(x0[0], x0[1], 0.0, prm, 0.0, 1.0)[0]:
            raise ValueError(f"initial state (curvature={x0[0]!r}, side_strain={x0[1]!r}) is outside the domain")
        if initial_pressure is not None:
            p0 = check_pressure(initial_pressure, "initial_pressure")
            out = step_state(x0[0], x0[1], p0, p, prm, kobj, kc, opts)
        else:
            o = options
            r = _minimise(x0[0], x0[1], p, prm, kobj, kc, o.gtol, o.max_iter, o.eig_floor)
            snapped = max(abs(r[0] - x0[0]), abs(r[1] - x0[1])) > o.max_jump
            dv = _evaluate(r[0], r[1], p, prm, kobj, kc)[7]
            out = (r[0], r[1], r[2], r[3], r[4], r[5], 0, snapped, r[6], dv)
    return _equilibrium(p, out, prm[0], kobj, kc)


@dataclass(frozen=True)
class LoadPath:
    """A quasi-static loading path: one entry per requested pressure (numpy arrays)."""

    pressure: np.ndarray
    curvature: np.ndarray
    side_strain: np.ndarray
    contact_force: np.ndarray
    indentation: np.ndarray
    energy: np.ndarray
    converged: np.ndarray
    snapped: np.ndarray
    iterations: np.ndarray
    gradient_norm: np.ndarray
    min_eigenvalue: np.ndarray
    equilibria: tuple[Equilibrium, ...]


def load_path(
    pressures,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
) -> LoadPath:
    """Follow ``pressures`` in order, from rest at ``p~ = 0``; pressures may decrease (unloading)."""
    params = ActuatorParams() if params is None else params
    ps = np.atleast_1d(np.asarray(pressures, dtype=float))
    if ps.ndim != 1:
        raise ValueError(f"pressures must be one-dimensional, got shape {ps.shape}")
    for i, p in enumerate(ps):
        check_pressure(p, f"pressures[{i}]")
    kobj, kc = check_object(object_stiffness, object_curvature)
    eqs: list[Equilibrium] = []
    prev: Equilibrium | None = None
    for p in ps:
        prev = solve_equilibrium(float(p), kobj, kc, params, initial=prev, options=options)
        eqs.append(prev)

    def col(name, dtype=float):
        return np.array([getattr(e, name) for e in eqs], dtype=dtype)

    return LoadPath(
        pressure=ps.copy(),
        curvature=col("curvature"),
        side_strain=col("side_strain"),
        contact_force=col("contact_force"),
        indentation=col("indentation"),
        energy=col("energy"),
        converged=col("converged", bool),
        snapped=col("snapped", bool),
        iterations=col("iterations", int),
        gradient_norm=col("gradient_norm"),
        min_eigenvalue=col("min_eigenvalue"),
        equilibria=tuple(eqs),
    )
