"""The minimiser's algorithm, as compiled scalar code: a safeguarded Newton descent with pressure continuation.

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

Both are scalar code, written once in :func:`_make_parts` over any energy kernel with the signature
of :data:`pneunet_env.physics.mechanics.scalar_terms`; with numba installed they are compiled.

This module holds the algorithm's constants and status codes (:data:`STATUS_MESSAGES`), the records the compiled
code builds, returns and reads (:class:`ActuatorNumbers`, :class:`Minimum`, :class:`Descent`, :class:`Solve`,
:class:`Continuation`), its scalar helpers (the 2x2 eigen helpers of :func:`make_sym2`, :func:`hessian_solve`, the
step control's :func:`predicted_change_limit` and :func:`hermite_midpoint`), :func:`_make_parts` and its compiled
instance ``_evaluate, _minimise, _follow_ev, _follow_from, _descend`` (what the batched and fused loops call). The
Python API over it (the options, the cached entry points, ``Equilibrium``, ``solve_equilibrium``, ``load_path``) is
:mod:`pneunet_env.physics.solver`, which re-exports these names.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.physics import mechanics
from pneunet_env.physics._jit import njit
from pneunet_env.physics.mechanics import Evaluation
from pneunet_env.physics.xp import identity, scalar_max, scalar_where

__all__ = [
    "ACCEPT_GTOL",
    "ARMIJO",
    "MIN_STEP_LENGTH",
    "ENERGY_ROUNDOFF",
    "ESCAPE_GRADIENT",
    "ESCAPE_STEP",
    "PREDICTED_JUMP_FRACTION",
    "EASY_CORRECTOR_ITERATIONS",
    "GROW",
    "SHRINK",
    "STEP_AFTER_FOLD",
    "LAST_STEP_SLACK",
    "BRANCH_PREDICTED_CHANGE",
    "BRANCH_MIDPOINT_FRACTION",
    "STEP_CONTROLS",
    "STATUS_INACTIVE",
    "STATUS_CONVERGED",
    "STATUS_ROUNDOFF",
    "STATUS_MAX_ITER",
    "STATUS_LINE_SEARCH",
    "STATUS_STALLED",
    "STATUS_OUTSIDE",
    "STATUS_BUDGET",
    "STATUS_MESSAGES",
    "status_message",
    "ActuatorNumbers",
    "Minimum",
    "Descent",
    "Solve",
    "Continuation",
    "make_sym2",
    "sym2_eigvals",
    "sym2_eigvec",
    "hessian_solve",
    "predicted_change_limit",
    "hermite_midpoint",
]

# ---- The algorithm's constants, defined once (the compiled scalar form and the masked array form in
# :mod:`pneunet_env.physics.batched` both read them; numba freezes them at compile time).

ACCEPT_GTOL = 1e-10
"""Every state reported ``converged`` has ``|grad|_2`` at most this and a positive-definite Hessian."""
ARMIJO = 1e-4
"""Armijo's sufficient-decrease constant: a trial step ``t d`` is accepted if ``U <= U0 + ARMIJO t g.d``."""
MIN_STEP_LENGTH = 1e-14
"""The line search halves ``t`` while ``t > MIN_STEP_LENGTH``; then it has failed (status 3)."""
ENERGY_ROUNDOFF = 1e-13
"""Relative energy change below which the energy cannot rank two points: the line search then takes ``|grad|``."""
ESCAPE_GRADIENT = 1e3
"""A state with ``|grad| <= ESCAPE_GRADIENT gtol`` and a Hessian that is not positive definite is (near) a
saddle: the descent leaves it along the negative-curvature direction."""
ESCAPE_STEP = 1e-3
"""Length of that escape step, relative to ``max(1, |kappa~|)``."""
PREDICTED_JUMP_FRACTION = 0.75
"""A sub-step is sized so that the tangent predicts a state change of at most this fraction of ``max_jump``."""
EASY_CORRECTOR_ITERATIONS = 4
"""A corrector that converges within this many iterations doubles the next sub-step (up to ``max_step``)."""
GROW = 2.0
"""Sub-step growth after an easy corrector."""
SHRINK = 0.25
"""Sub-step shrink after a failed corrector (down to ``min_step``)."""
STEP_AFTER_FOLD = 0.1
"""After a snap-through the next sub-step is this fraction of ``max_step``."""
LAST_STEP_SLACK = 1e-12
"""A sub-step within this relative slack of the remaining pressure lands exactly on the target."""
BRANCH_PREDICTED_CHANGE = 0.1
"""``step_control="branch"``: a sub-step is sized so that the tangent predicts a state change of at most this (the
state is of order 0.01-1), or ``PREDICTED_JUMP_FRACTION * max_jump`` where that is more."""
BRANCH_MIDPOINT_FRACTION = 0.25
"""``step_control="branch"``: the Newton correction at the middle of a long sub-step's Hermite interpolant must be at
most this fraction of ``max_jump`` (one branch: between two branches the interpolant's middle is far from both)."""
STEP_CONTROLS = ("jump", "branch")
""":attr:`~pneunet_env.physics.solver.SolverOptions.step_control`'s values, by their code in
:meth:`~pneunet_env.physics.solver.SolverOptions.as_tuple`."""

STATUS_INACTIVE = -1
STATUS_CONVERGED = 0
STATUS_ROUNDOFF = 1
STATUS_MAX_ITER = 2
STATUS_LINE_SEARCH = 3
STATUS_STALLED = 4
STATUS_OUTSIDE = 5
STATUS_BUDGET = 6
STATUS_MESSAGES = {
    STATUS_INACTIVE: "not solved (inactive)",
    STATUS_CONVERGED: "converged",
    STATUS_ROUNDOFF: "converged at the round-off floor",
    STATUS_MAX_ITER: "iteration limit reached",
    STATUS_LINE_SEARCH: "line search failed",
    STATUS_STALLED: "stalled",
    STATUS_OUTSIDE: "start point outside the domain",
    STATUS_BUDGET: "sub-step budget spent (max_substeps)",
}
"""What each ``status`` code means; ``status <= STATUS_ROUNDOFF`` (and ``>= 0``) is converged. ``-1``: an env of a
batch that was not solved (masked out)."""
_STATUS_ARRAY = np.array([STATUS_MESSAGES[c] for c in range(-1, max(STATUS_MESSAGES) + 1)], dtype=object)


def status_message(status):
    """The message of a ``status`` code (a string), or of an array of codes (an object array of strings); the codes
    are those of :data:`STATUS_MESSAGES`, ``-1 .. 6``."""
    return _STATUS_ARRAY[status + 1]


# ---- The compiled solver's records (numba builds, returns and reads them by name) ----


class ActuatorNumbers(NamedTuple):
    """The dimensionless actuator as the compiled solver takes it (:func:`~pneunet_env.physics.solver.params_tuple`)."""

    chamber_height: float  # d
    base_thickness: float  # h_b
    side_thickness: float  # h_s
    top_thickness: float  # h_m
    base_modulus: float  # E_b
    poisson_ratio: float  # nu
    gent_limit: float  # J


class Minimum(NamedTuple):
    """A descent's result at fixed pressure (:func:`~pneunet_env.physics.solver.minimise_state`), with its work (energy
    evaluations, the start's included, and rejected line-search trials)."""

    kappa: Any
    side_strain: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    iterations: Any
    status: Any
    evaluations: Any
    backtracks: Any


class Descent(NamedTuple):
    """A descent's result, with the energy evaluation at it (so that no point is evaluated twice) and its work: the
    energy evaluations it made (its line-search trials; the start's is the caller's) and the trials it rejected
    (backtracks: each halves the step)."""

    kappa: Any
    side_strain: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    iterations: Any
    status: Any
    evaluation: Evaluation
    evaluations: Any
    backtracks: Any


class Solve(NamedTuple):
    """The continuation's result (:data:`~pneunet_env.physics.solver.step_state`), one env (scalars) or N (arrays, a
    batched back-end's)."""

    kappa: Any
    side_strain: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    iterations: Any
    substeps: Any
    snapped: Any
    status: Any
    volume_change: Any  # NaN only if the start was outside the domain
    evaluations: Any  # energy evaluations made (the work counters: see Equilibrium)
    backtracks: Any  # line-search trials rejected


class Continuation(NamedTuple):
    """:class:`Solve`'s fields and the energy evaluation at the answer (``step_state_from``: a cache keeps it).
    ``evaluations`` does not count the start's (``ev0``, the caller's)."""

    kappa: Any
    side_strain: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    iterations: Any
    substeps: Any
    snapped: Any
    status: Any
    volume_change: Any
    evaluations: Any
    backtracks: Any
    evaluation: Evaluation


def make_sym2(hypot, atan2, cos, sin, where, jit=identity):
    """Build ``(eigvals, eigvec)`` of the symmetric 2x2 matrix ``[[a, b], [b, c]]`` from elementary operations.

    Written once, instantiated twice: on floats (:func:`sym2_eigvals`, :func:`sym2_eigvec`, compiled with numba)
    and on numpy arrays (for :mod:`pneunet_env.physics.batched`). ``eigvals -> (lam_min, lam_max)``: the smaller
    one of a well-conditioned definite matrix is taken as ``det / lam_max`` (no cancellation). ``eigvec -> (cos t,
    sin t)``, the eigenvector of ``lam_max``; ``(-sin t, cos t)`` is that of ``lam_min``.
    """

    @jit
    def eigvals(a, b, c):
        m = 0.5 * (a + c)
        r = hypot(0.5 * (a - c), b)
        lmax = m + r
        lmin = m - r
        det = a * c - b * b
        pos = (m > 0.0) & (lmax > 0.0)
        neg = (m < 0.0) & (lmin < 0.0)  # excludes pos (m > 0 there), so lmin is still m - r here
        lmin2 = where(pos, det / where(pos, lmax, 1.0), lmin)
        lmax2 = where(neg, det / where(neg, lmin, 1.0), lmax)
        return lmin2, lmax2

    @jit
    def eigvec(a, b, c):
        t = 0.5 * atan2(2.0 * b, a - c)
        return cos(t), sin(t)

    return eigvals, eigvec


sym2_eigvals, sym2_eigvec = make_sym2(math.hypot, math.atan2, math.cos, math.sin, njit(scalar_where), njit)


@njit
def hessian_solve(e, a, b):
    """``H^-1 (a, b)`` with ``H`` the Hessian of the :class:`Evaluation` ``e``, where ``H`` is positive definite:
    ``(True, x0, x1)``; ``(False, 0.0, 0.0)`` elsewhere. With ``e``'s ``dV/dx`` it is the continuation's tangent
    ``dx/dp``, with its gradient the Newton correction."""
    det = e.h_kk * e.h_ss - e.h_ks * e.h_ks
    if not (e.h_kk > 0.0 and det > 0.0):
        return False, 0.0, 0.0
    return True, (e.h_ss * a - e.h_ks * b) / det, (e.h_kk * b - e.h_ks * a) / det


@njit
def predicted_change_limit(max_jump, control):
    """The largest state change ``max(|d kappa~|, |d e_s|)`` a sub-step's tangent may predict (the sub-step is sized
    to it): ``PREDICTED_JUMP_FRACTION max_jump`` under ``step_control="jump"`` (``control`` 0), at least
    :data:`BRANCH_PREDICTED_CHANGE` under ``"branch"`` (1)."""
    limit = PREDICTED_JUMP_FRACTION * max_jump
    if control == 1:
        limit = max(BRANCH_PREDICTED_CHANGE, limit)
    return limit


@njit
def hermite_midpoint(k0, s0, tk0, ts0, k1, s1, tk1, ts1, dp):
    """The middle of the cubic Hermite interpolant between two states ``(k0, s0)`` and ``(k1, s1)`` a pressure ``dp``
    apart, with tangents ``dx/dp`` ``(tk0, ts0)`` and ``(tk1, ts1)``: ``(x0 + x1) / 2 + dp (t0 - t1) / 8``
    (``step_control="branch"``'s test of one branch; the free table interpolates its nodes the same way)."""
    return 0.5 * (k0 + k1) + dp / 8.0 * (tk0 - tk1), 0.5 * (s0 + s1) + dp / 8.0 * (ts0 - ts1)


def _make_parts(terms, jit=njit):
    """The solver's pieces over an energy kernel ``terms`` (:func:`pneunet_env.physics.mechanics.make_terms`'s),
    compiled by ``jit``: ``(evaluate, minimise, follow_ev, follow_from, descend)``.

    * ``evaluate(k, s, p, prm, kobj, ko) -> Evaluation``: the kernel on the packed :class:`ActuatorNumbers`;
    * ``minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor) -> Minimum``: the safeguarded descent at fixed
      pressure;
    * ``follow_ev(k, s, p0, p1, prm, kobj, ko, opts) -> Solve``: the continuation
      (:data:`~pneunet_env.physics.solver.step_state`);
    * ``follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0) -> Continuation``: the same from a start whose
      evaluation is known;
    * ``descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, ev, k0, s0, radius) -> Descent``: the Newton
      descent from a point whose evaluation ``ev`` is already known, returning the evaluation at its result too, so
      no point is evaluated twice (a finite ``radius`` makes it a corrector: see its body). The others are built on
      it; :mod:`pneunet_env.physics.free_table` uses it too. ``prm`` is
    :func:`~pneunet_env.physics.solver.params_tuple`, ``opts``
    :meth:`~pneunet_env.physics.solver.SolverOptions.as_tuple`; ``status`` indexes :data:`STATUS_MESSAGES`.
    """

    @jit
    def evaluate(k, s, p, prm, kobj, ko):
        return terms(k, s, p, prm.chamber_height, prm.base_thickness, prm.side_thickness, prm.top_thickness,
                     prm.base_modulus, prm.poisson_ratio, prm.gent_limit, kobj, ko)

    @jit
    def descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, ev, k0, s0, radius):
        # A finite radius marks a corrector: it gives up (status 2) once an iterate is farther than radius
        # from (k0, s0) or has a Hessian that is not positive definite.
        ok, U, g0, g1, hkk, hks, hss, _, _, _ = ev
        if not ok:
            return Descent(k, s, math.inf, math.inf, -math.inf, 0, STATUS_OUTSIDE, ev, 0, 0)
        gnorm = math.hypot(g0, g1)
        lmin, lmax = sym2_eigvals(hkk, hks, hss)
        it = 0
        n_eval = 0  # the work: energy evaluations (line-search trials) and rejected trials
        n_back = 0
        status = STATUS_MAX_ITER
        while True:
            if gnorm <= gtol and lmin > 0.0:
                status = STATUS_CONVERGED
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
                ct, st = sym2_eigvec(hkk, hks, hss)
                l1 = max(abs(lmin), eig_floor * scale)
                l2 = max(abs(lmax), eig_floor * scale)
                a2 = g0 * ct + g1 * st
                a1 = -g0 * st + g1 * ct
                d0 = -(a2 / l2) * ct + (a1 / l1) * st
                d1 = -(a2 / l2) * st - (a1 / l1) * ct
                slope = g0 * d0 + g1 * d1
                if lmin <= 0.0 and gnorm <= ESCAPE_GRADIENT * gtol:
                    # (Near-)stationary but not a minimum: leave along the negative-curvature direction.
                    v0, v1 = -st, ct
                    step = ESCAPE_STEP * max(1.0, abs(k))
                    if g0 * v0 + g1 * v1 > 0.0:
                        step = -step
                    d0, d1 = step * v0, step * v1
                    slope = min(g0 * d0 + g1 * d1, 0.0)
            t = 1.0
            accepted = False
            kn, sn, nnorm, evn = k, s, gnorm, ev
            while t > MIN_STEP_LENGTH:
                kn = k + t * d0
                sn = s + t * d1
                if kn < 0.0:
                    # Project onto the domain's edge kappa~ = 0, where the rest state (p~ = 0) lies: else every
                    # Newton step towards it overshoots and is halved, and the descent only converges linearly.
                    kn = 0.0
                evn = evaluate(kn, sn, p, prm, kobj, ko)
                n_eval += 1
                if evn.ok:
                    nnorm = math.hypot(evn.g_kappa, evn.g_strain)
                    # Armijo; at round-off level the energy cannot rank points, so fall back on |grad|.
                    if evn.energy <= U + ARMIJO * t * slope or (
                        abs(evn.energy - U) <= ENERGY_ROUNDOFF * max(1.0, abs(U)) and nnorm < gnorm
                    ):
                        accepted = True
                        break
                t *= 0.5
                n_back += 1
            if not accepted:
                status = STATUS_LINE_SEARCH
                break
            moved = abs(kn - k) + abs(sn - s)
            ev = evn
            k, s, gnorm = kn, sn, nnorm
            U, g0, g1, hkk, hks, hss = evn.energy, evn.g_kappa, evn.g_strain, evn.h_kk, evn.h_ks, evn.h_ss
            lmin, lmax = sym2_eigvals(hkk, hks, hss)
            if moved == 0.0:
                status = STATUS_STALLED
                break
            if radius < math.inf and (lmin <= 0.0 or max(abs(k - k0), abs(s - s0)) > radius):
                break  # a corrector that leaves the branch's convex neighbourhood: the sub-step was too long
        if status != STATUS_CONVERGED and gnorm <= ACCEPT_GTOL and lmin > 0.0:
            status = STATUS_ROUNDOFF
        return Descent(k, s, U, gnorm, lmin, it, status, ev, n_eval, n_back)

    @jit
    def minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor):
        r = descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, evaluate(k, s, p, prm, kobj, ko), k, s, math.inf)
        return Minimum(r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.status,
                       1 + r.evaluations, r.backtracks)

    @jit
    def _one_branch(k, s, tk, ts, p, r, pt, prm, kobj, ko, max_jump):
        # Whether a long sub-step's ends, (k, s) at p with tangent (tk, ts) and r's state at pt, lie on one branch:
        # the Newton correction at the middle of their cubic Hermite interpolant is at most
        # BRANCH_MIDPOINT_FRACTION max_jump (both Hessians positive definite). Returns (accept, evaluations).
        e1 = r.evaluation
        pd1, t1k, t1s = hessian_solve(e1, e1.v_kappa, e1.v_strain)
        if not pd1:
            return False, 0
        km, sm = hermite_midpoint(k, s, tk, ts, r.kappa, r.side_strain, t1k, t1s, pt - p)
        em = evaluate(km, sm, 0.5 * (p + pt), prm, kobj, ko)
        if not em.ok:
            return False, 1
        pdm, ck, cs = hessian_solve(em, em.g_kappa, em.g_strain)
        return pdm and max(abs(ck), abs(cs)) <= BRANCH_MIDPOINT_FRACTION * max_jump, 1

    @jit
    def follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0):
        # follow_ev from a start whose evaluation ev0 = evaluate(k, s, p0, ...) is known (a cache of the previous
        # step's last one); returns follow_ev's tuple and the evaluation at the answer.
        gtol, max_iter, corr_iter, max_step, min_step, max_jump, eig_floor, max_substeps, control = opts
        # control 1 ("branch"): a predicted change up to BRANCH_PREDICTED_CHANGE, accepted when one branch (below)
        predicted_limit = predicted_change_limit(max_jump, control)
        # Polish the start so that the tangent is taken at an equilibrium (at an equilibrium: one evaluation).
        k, s, U, gn, lmin, iters, status, ev, n_eval, n_back = descend(k, s, p0, prm, kobj, ko, gtol, max_iter,
                                                                       eig_floor, ev0, k, s, math.inf)
        substeps = 0
        snapped = False
        p = p0
        h = min(abs(p1 - p0), max_step)
        sign = 1.0 if p1 >= p0 else -1.0
        attempts = 0
        while p != p1 and status <= STATUS_ROUNDOFF:
            if attempts >= max_substeps:
                status = STATUS_BUDGET  # never hang: a call that spends its budget is flagged unconverged
                break
            attempts += 1
            # Tangent dx/dp = H^{-1} dV/dx at the current equilibrium, where the Hessian is positive definite.
            tangent, tk, ts = hessian_solve(ev, ev.v_kappa, ev.v_strain)
            if tangent:
                rate = max(abs(tk), abs(ts))
                # Size the sub-step so that the predicted change stays well inside max_jump (or the long limit).
                if h * rate > predicted_limit:
                    h = max(predicted_limit / rate, min_step)
            remaining = abs(p1 - p)
            pt = p1 if h >= remaining * (1.0 - LAST_STEP_SLACK) else p + sign * h
            started = False
            if tangent:
                kc = k + (pt - p) * tk
                sc = s + (pt - p) * ts
                evc = evaluate(kc, sc, pt, prm, kobj, ko)
                n_eval += 1
                if evc.ok:
                    # the corrector kept within max_jump of the start ("jump") or of the predictor ("branch")
                    k0, s0 = (k, s) if control == 0 else (kc, sc)
                    r = descend(kc, sc, pt, prm, kobj, ko, gtol, corr_iter, eig_floor, evc, k0, s0, max_jump)
                    started = True
            if not started:
                evs = evaluate(k, s, pt, prm, kobj, ko)
                n_eval += 1
                r = descend(k, s, pt, prm, kobj, ko, gtol, corr_iter, eig_floor, evs, k, s, max_jump)
            iters += r.iterations
            n_eval += r.evaluations
            n_back += r.backtracks
            jump = max(abs(r.kappa - k), abs(r.side_strain - s))
            accept = r.status <= STATUS_ROUNDOFF and jump <= max_jump
            if control == 1 and started and not accept and r.status <= STATUS_ROUNDOFF and max(
                    abs(r.kappa - kc), abs(r.side_strain - sc)) <= max_jump:
                accept, n_mid = _one_branch(k, s, tk, ts, p, r, pt, prm, kobj, ko, max_jump)
                n_eval += n_mid
            if accept:
                p = pt
                k, s, U, gn, lmin, status, ev = r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, \
                    r.status, r.evaluation
                substeps += 1
                if r.iterations <= EASY_CORRECTOR_ITERATIONS:
                    h = min(GROW * h, max_step)
                continue
            if h > min_step:
                h = max(SHRINK * h, min_step)
                continue
            # The branch ends within min_step of pressure: a fold. Descend to the minimum that remains.
            evs = evaluate(k, s, pt, prm, kobj, ko)
            r = descend(k, s, pt, prm, kobj, ko, gtol, max_iter, eig_floor, evs, k, s, math.inf)
            iters += r.iterations
            n_eval += 1 + r.evaluations
            n_back += r.backtracks
            substeps += 1
            if max(abs(r.kappa - k), abs(r.side_strain - s)) > max_jump:
                snapped = True
            p = pt
            k, s, U, gn, lmin, status, ev = r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, \
                r.status, r.evaluation
            h = STEP_AFTER_FOLD * max_step
        return Continuation(k, s, U, gn, lmin, iters, substeps, snapped, status,
                            ev.volume_change if ev.ok else math.nan, n_eval, n_back, ev)

    @jit
    def follow_ev(k, s, p0, p1, prm, kobj, ko, opts):
        r = follow_from(k, s, p0, p1, prm, kobj, ko, opts, evaluate(k, s, p0, prm, kobj, ko))
        return Solve(r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.substeps,
                     r.snapped, r.status, r.volume_change, 1 + r.evaluations, r.backtracks)

    return evaluate, minimise, follow_ev, follow_from, descend


_evaluate, _minimise, _follow_ev, _follow_from, _descend = _make_parts(mechanics.make_terms(
    math.log, math.tan, njit(scalar_where), njit(scalar_max), abs, jit=njit
)[1])
# Compiled code (the batched and fused loops) calls the five above; Python calls them through the disk-cached entries
# of :mod:`pneunet_env.physics.solver`.
