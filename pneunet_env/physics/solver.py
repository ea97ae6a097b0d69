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

Both are scalar code, written once in :func:`_make_parts` over any energy kernel with the signature
of :data:`pneunet_env.physics.mechanics.scalar_terms`; with numba installed they are compiled.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.physics import _jit, contact, mechanics, xp
from pneunet_env.physics._jit import njit, python_entry
from pneunet_env.physics.contact import scalar_contact
from pneunet_env.physics.mechanics import Evaluation
from pneunet_env.physics.params import ActuatorParams, check_finite, check_object
from pneunet_env.physics.xp import identity, scalar_max, scalar_where

__all__ = [
    "SolverOptions",
    "DEFAULT_OPTIONS",
    "Equilibrium",
    "ActuatorNumbers",
    "Minimum",
    "Descent",
    "Solve",
    "Continuation",
    "LoadPath",
    "STATUS_MESSAGES",
    "status_message",
    "make_sym2",
    "minimise_state",
    "solve_equilibrium",
    "load_path",
    "equilibrium",
    "sym2_eigvals",
    "sym2_eigvec",
    "step_state",
    "step_state_from",
    "evaluate_state",
    "params_tuple",
    "check_pressure",
    "ACCEPT_GTOL",
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
""":attr:`SolverOptions.step_control`'s values, by their code in :meth:`SolverOptions.as_tuple`."""

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


OPTION_BOUNDS: dict[str, tuple[float, float, str]] = {
    "gtol": (1e-16, ACCEPT_GTOL, "below 1e-16 no double-precision gradient can be resolved; above ACCEPT_GTOL a "
             "'converged' state would not have a zero gradient"),
    "max_iter": (1, 100_000, "a compiled int64 counter; a descent that needs more has failed anyway"),
    "corrector_max_iter": (1, 1_000, "a corrector that needs more than this is off its branch"),
    "max_step": (1e-6, 1.0, "the env's whole pressure range is p~ = 1.2; a sub-step under 1e-6 (0.05 Pa) measures "
                 "nothing"),
    "min_step": (1e-12, 1.0, "a fold located to better than 1e-12 in p~ (5e-8 Pa) is below round-off of the state"),
    "max_jump": (1e-5, 1.0, "the state (kappa~, e_s) is of order 0.01-1; smaller branch steps only cost sub-steps"),
    "eig_floor": (1e-16, 1e-2, "a relative floor on |lambda|: at most a percent, at least round-off"),
    "max_substeps": (1, 1_000_000, "the budget of sub-step attempts of one call: a call that spends it is flagged "
                     "unconverged, never hangs"),
}
"""``(low, high, why)`` of every :class:`SolverOptions` field: the bounds the physics and the arithmetic justify."""
MAX_ITERATIONS = int(OPTION_BOUNDS["max_iter"][1])

_INT_OPTIONS = ("max_iter", "corrector_max_iter", "max_substeps")


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances of the minimiser (dimensionless); each within :data:`OPTION_BOUNDS`.

    Attributes:
        gtol: Stop once ``|grad|_2 <= gtol`` and the Hessian is positive definite. (A state that stalls
            at round-off above ``gtol`` still counts as converged if ``|grad|_2 <= 1e-10``.)
        max_iter: Newton iterations allowed for a full descent (after a snap, or a cold start).
        corrector_max_iter: Newton iterations allowed for a continuation corrector before the
            sub-step is shrunk.
        max_step: Largest pressure sub-step ``dp~``.
        min_step: Smallest pressure sub-step; a branch that cannot be followed over it has ended (fold).
        max_jump: Largest state change ``max(|d kappa~|, |d e_s|)`` over one sub-step on the same branch (under
            ``step_control="branch"``: from the sub-step's predictor, its ends checked to lie on one branch); a fold
            whose jump is larger sets ``snapped``.
        eig_floor: Relative floor on the modified Hessian's eigenvalues.
        max_substeps: Sub-step attempts (accepted, shrunk or a fold) allowed in one call; when they are spent the
            call stops with status :data:`STATUS_BUDGET` (not converged). The env's steps take at most about 50.
        free_table: Whether the envs' compiled step (numba: the vector env's fused step, the single env's compiled
            call) takes a step that touches nothing along the free actuator's tabulated path
            (:mod:`pneunet_env.physics.free_table`): one or two energy evaluations instead of 4 to 11, the state a
            converged minimum as always, within the tolerance of the continuation's (not bit for bit). ``False``:
            the continuation for every step, bit for bit the array step's. The continuation's own calls
            (:func:`solve_equilibrium`, :func:`step_state`, the array step) do not read it; it is not part of
            :meth:`as_tuple`.
        step_control: How long a continuation sub-step may be. ``"jump"`` (the default until 0.12): a sub-step is
            accepted only if the state moved at most ``max_jump`` from its start, and sized so that the tangent
            predicts ``0.75 max_jump``. ``"branch"`` (the default): also a longer one (a predicted change up to
            :data:`BRANCH_PREDICTED_CHANGE`) whose corrector converged within ``max_jump`` of its predictor and whose
            two ends lie on one branch (the Newton correction at the middle of their cubic Hermite interpolant is
            at most :data:`BRANCH_MIDPOINT_FRACTION` ``max_jump``); folds are found and ``snapped`` set as before.
            About half the evaluations where the path is steep (contact: ``docs/studies/step-control``); the same
            minima to the tolerance, not bit for bit. Every backend has both (the scalar solver, compiled or plain
            Python, and the masked solver of numpy and torch make the same decisions).
    """

    gtol: float = 1e-11
    max_iter: int = 200
    corrector_max_iter: int = 12
    max_step: float = 0.05
    min_step: float = 1e-9
    max_jump: float = 0.02
    eig_floor: float = 1e-10
    max_substeps: int = 10_000
    free_table: bool = True
    step_control: str = "branch"

    def __post_init__(self) -> None:
        if not isinstance(self.step_control, str) or self.step_control not in STEP_CONTROLS:
            raise ValueError(f"SolverOptions.step_control must be one of {STEP_CONTROLS}, got {self.step_control!r}")
        if type(self.free_table).__name__ not in ("bool", "bool_"):
            raise ValueError(f"SolverOptions.free_table must be true or false, got {self.free_table!r}")
        object.__setattr__(self, "free_table", bool(self.free_table))
        for name, (lo, hi, why) in OPTION_BOUNDS.items():
            v = getattr(self, name)
            if name in _INT_OPTIONS:
                try:
                    i = int(v)
                except (TypeError, ValueError, OverflowError):
                    raise ValueError(f"SolverOptions.{name} must be an integer, got {v!r}") from None
                if isinstance(v, (bool, str, bytes)) or i != v:
                    raise ValueError(f"SolverOptions.{name} must be an integer, got {v!r}")
                v = i
            else:
                if isinstance(v, (bool, str, bytes)):
                    raise ValueError(f"SolverOptions.{name} must be a number, got {v!r}")
                v = check_finite(f"SolverOptions.{name}", v)
            if not lo <= v <= hi:
                raise ValueError(
                    f"SolverOptions.{name} must be in [{lo:g}, {hi:g}] ({why}), got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, v)
        if self.min_step > self.max_step:
            raise ValueError(f"SolverOptions.min_step={self.min_step!r} exceeds max_step={self.max_step!r}")

    def as_tuple(self) -> tuple:
        """The continuation's numbers in order, as the compiled solver takes them (all fields but ``free_table``;
        ``step_control`` as its index in :data:`STEP_CONTROLS`)."""
        return (
            float(self.gtol),
            int(self.max_iter),
            int(self.corrector_max_iter),
            float(self.max_step),
            float(self.min_step),
            float(self.max_jump),
            float(self.eig_floor),
            int(self.max_substeps),
            STEP_CONTROLS.index(self.step_control),
        )


DEFAULT_OPTIONS = SolverOptions()
_DEFAULT_OPTIONS_TUPLE = DEFAULT_OPTIONS.as_tuple()


# ---- The compiled solver's records (numba builds, returns and reads them by name) ----


class ActuatorNumbers(NamedTuple):
    """The dimensionless actuator as the compiled solver takes it (:func:`params_tuple`)."""

    chamber_height: float  # d
    base_thickness: float  # h_b
    side_thickness: float  # h_s
    top_thickness: float  # h_m
    base_modulus: float  # E_b
    poisson_ratio: float  # nu
    gent_limit: float  # J


class Minimum(NamedTuple):
    """A descent's result at fixed pressure (:func:`minimise_state`), with its work (energy evaluations, the start's
    included, and rejected line-search trials)."""

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
    """The continuation's result (:data:`step_state`), one env (scalars) or N (arrays, a batched back-end's)."""

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
    * ``follow_ev(k, s, p0, p1, prm, kobj, ko, opts) -> Solve``: the continuation (:data:`step_state`);
    * ``follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0) -> Continuation``: the same from a start whose
      evaluation is known;
    * ``descend(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor, ev, k0, s0, radius) -> Descent``: the Newton
      descent from a point whose evaluation ``ev`` is already known, returning the evaluation at its result too, so
      no point is evaluated twice (a finite ``radius`` makes it a corrector: see its body). The others are built on
      it; :mod:`pneunet_env.physics.free_table` uses it too. ``prm`` is
    :func:`params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`; ``status`` indexes :data:`STATUS_MESSAGES`.
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
# Compiled code (the batched and fused loops) calls the four above. Python calls the entries below: compiled once
# and cached on disk (a new process loads them instead of compiling the solver for seconds), they return the same
# records as plain tuples, which Python turns back into records (python_entry: a NamedTuple returned to Python can
# turn a Ctrl-C into a segmentation fault).


@njit
def _solve_numbers(r):
    """A :class:`Solve`'s fields (a :class:`Continuation`'s before its ``evaluation``) as a plain tuple."""
    return (r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.substeps, r.snapped,
            r.status, r.volume_change, r.evaluations, r.backtracks)


@njit
def _evaluation_numbers(e):
    """An :class:`Evaluation`'s fields as a plain tuple."""
    return (e.ok, e.energy, e.g_kappa, e.g_strain, e.h_kk, e.h_ks, e.h_ss, e.volume_change, e.v_kappa, e.v_strain)


def _make_entries(stamp: int):
    def plain_step_state(k, s, p0, p1, prm, kobj, ko, opts):
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        return _solve_numbers(_follow_ev(k, s, p0, p1, prm, kobj, ko, opts))

    def plain_evaluate(k, s, p, prm, kobj, ko):
        if stamp < 0:
            raise AssertionError
        return _evaluation_numbers(_evaluate(k, s, p, prm, kobj, ko))

    def plain_step_state_from(k, s, p0, p1, prm, kobj, ko, opts, ev0):
        if stamp < 0:
            raise AssertionError
        r = _follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0)
        return _solve_numbers(r) + (_evaluation_numbers(r.evaluation),)

    def plain_minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor):
        if stamp < 0:
            raise AssertionError
        r = _minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor)
        return (r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.status,
                r.evaluations, r.backtracks)

    return {"step_state": plain_step_state, "evaluate": plain_evaluate, "step_state_from": plain_step_state_from,
            "minimise": plain_minimise}


_SOURCES = (mechanics, contact, xp, _jit, sys.modules[__name__])
"""The sources the compiled solver is built from."""


def _entry(name: str, record: type, nested=None):
    return python_entry(_jit.njit_cached(lambda stamp: _make_entries(stamp)[name], _SOURCES), record, nested)


step_state = _entry("step_state", Solve)
step_state_from = _entry("step_state_from", Continuation, {"evaluation": Evaluation})
evaluate_state = _entry("evaluate", Evaluation)
"""``evaluate_state(kappa~, e_s, p, prm, k~_obj, w kappa_obj) -> Evaluation``: the energy kernel, from Python."""
_minimise_entry = _entry("minimise", Minimum)
# step_state_from(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts, ev0) -> Continuation: step_state from a start
# whose energy evaluation ev0 (the kernel's Evaluation at (kappa~, e_s, p0)) is known; returns step_state's fields and
# the evaluation at the answer, so that a caller can keep it for the next step (pneunet_env.fused caches it).
"""The fast entry point: ``step_state(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts)`` returns a :class:`Solve`
``(kappa~, e_s, U, |grad|, lam_min, iterations, substeps, snapped, status, volume_change, evaluations, backtracks)``.

It is the compiled continuation behind :func:`solve_equilibrium` (see :func:`_make_parts`), from an equilibrium
``(kappa~, e_s)`` at ``p0`` to ``p1``, with no validation and
no objects built: for callers on a hot path (an env's step), about a microsecond for a small pressure
step with numba. ``prm`` is :func:`params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`; ``status``
indexes :data:`STATUS_MESSAGES` (``<= 1``: converged); ``volume_change`` is ``(V1 - V0)/(w^2 t)`` at the
result (NaN only if the start was outside the domain). Inputs must already be valid (finite,
``p >= 0``, ``k~_obj >= 0``, ``0 < w kappa_obj < pi``, the start in the domain)."""


class Equilibrium(NamedTuple):
    """A quasi-static equilibrium: the one solved-state type of the package (all dimensionless: lengths / ``w``,
    stresses / ``mu``).

    Fields are Python scalars for one actuator (:func:`solve_equilibrium`, the single env) or numpy arrays of
    shape ``(N,)`` for a batch (:func:`pneunet_env.physics.batched.solve_batch`, the vector env).

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
        converged: ``gradient_norm <= 1e-10`` and ``min_eigenvalue > 0`` (``0 <= status <= 1``).
        iterations: Newton iterations spent (all sub-steps).
        substeps: pressure sub-steps taken.
        snapped: a fold was crossed: the previous branch's minimum vanished and the state jumped.
        status: the minimiser's code (:data:`STATUS_MESSAGES`; :attr:`message` gives the words).
        object_stiffness: ``k~_obj``.
        object_curvature: ``w kappa_obj``.
        evaluations: energy evaluations the solve made (its work: what a step costs is about this times one
            evaluation). A caller that already had the start's evaluation (the fused vector step's cache) makes one
            fewer, and none where the pressure did not change and the start is a converged minimum; 0 where
            nothing was solved (a rigid jaw, the linear model).
        backtracks: line-search trials the solve rejected (each halves the Newton step).
    """

    pressure: Any
    curvature: Any
    side_strain: Any
    top_strain: Any
    contact_force: Any
    indentation: Any
    in_contact: Any
    volume_change: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    converged: Any
    iterations: Any
    substeps: Any
    snapped: Any
    status: Any
    object_stiffness: Any
    object_curvature: Any
    evaluations: Any = 0
    backtracks: Any = 0

    @property
    def state(self) -> tuple[Any, Any]:
        """``(kappa~, e_s)``."""
        return (self.curvature, self.side_strain)

    @property
    def message(self):
        """What :attr:`status` means (:func:`status_message`)."""
        return status_message(self.status)


def check_pressure(pressure: float, name: str = "pressure") -> float:
    """``float(pressure)``; ``ValueError`` naming it unless finite and ``>= 0``."""
    p = check_finite(name, pressure)
    if p < 0.0:
        raise ValueError(f"{name} (p~ = p/mu) must be >= 0, got {pressure!r}")
    return p


_DEFAULT_PARAMS = ActuatorParams()


def params_tuple(params: ActuatorParams | None) -> ActuatorNumbers:
    """The :class:`ActuatorNumbers` ``(d, h_b, h_s, h_m, E_b, nu, J)`` of ``params`` (:meth:`ActuatorParams.as_tuple`
    without its deep copy); ``None``: the defaults."""
    if params is None:
        params = _DEFAULT_PARAMS
    return ActuatorNumbers(params.chamber_height, params.base_thickness, params.side_thickness, params.top_thickness,
                           params.base_modulus, params.poisson_ratio, params.gent_limit)


def equilibrium(pressure, raw: Solve, chamber_height, object_stiffness, object_curvature) -> Equilibrium:
    """The :class:`Equilibrium` of one :func:`step_state` result ``raw``."""
    k, s, status = raw.kappa, raw.side_strain, raw.status
    delta, force, touching = scalar_contact(k, object_stiffness, object_curvature)
    return Equilibrium(
        pressure, k, s, chamber_height * (1.0 + s) * k, force, delta, touching, raw.volume_change, raw.energy,
        raw.gradient_norm, raw.min_eigenvalue, STATUS_CONVERGED <= status <= STATUS_ROUNDOFF, raw.iterations,
        raw.substeps, raw.snapped, status, object_stiffness, object_curvature, raw.evaluations, raw.backtracks,
    )


def minimise_state(x0, pressure, params, object_stiffness=0.0, object_curvature=0.02, options=DEFAULT_OPTIONS):
    """Plain safeguarded descent from ``x0 = (kappa~, e_s)`` at fixed pressure (no continuation).

    Returns a :class:`Minimum` ``(kappa~, e_s, U, |grad|, lam_min, iterations, status)``.
    """
    o = options
    return _minimise_entry(float(x0[0]), float(x0[1]), float(pressure), params_tuple(params),
                           float(object_stiffness), float(object_curvature), o.gtol, o.max_iter, o.eig_floor)


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
        if not evaluate_state(x0[0], x0[1], 0.0, prm, 0.0, 1.0).ok:
            raise ValueError(f"initial state (curvature={x0[0]!r}, side_strain={x0[1]!r}) is outside the domain")
        if initial_pressure is not None:
            p0 = check_pressure(initial_pressure, "initial_pressure")
            out = step_state(x0[0], x0[1], p0, p, prm, kobj, kc, opts)
        else:
            o = options
            r = _minimise_entry(x0[0], x0[1], p, prm, kobj, kc, o.gtol, o.max_iter, o.eig_floor)
            snapped = max(abs(r.kappa - x0[0]), abs(r.side_strain - x0[1])) > o.max_jump
            dv = evaluate_state(r.kappa, r.side_strain, p, prm, kobj, kc).volume_change
            out = Solve(r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, 0, snapped,
                        r.status, dv, r.evaluations + 1, r.backtracks)
    return equilibrium(p, out, prm.chamber_height, kobj, kc)


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
