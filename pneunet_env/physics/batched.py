"""The quasi-static solve for N independent actuators at once (the engine of a natively batched vector env).

:func:`solve_batch` advances N states ``(kappa~_i, e_s_i)``, each an equilibrium at its pressure
``p0_i``, to the pressures ``p1_i``, with the algorithm of :mod:`pneunet_env.physics.solver` (safeguarded
modified Newton with an Armijo line search that never leaves the domain, tangent-predictor pressure
continuation with sub-step control, fold detection and snap). Its answers are those of
:func:`pneunet_env.physics.solver.step_state` called env by env (to round-off), with two back-ends:

* ``"numba"`` (numba installed): one compiled loop over the envs calling the compiled scalar
  continuation itself, optionally split over the CPU's cores (``numba.prange``). About a tenth to
  half a microsecond per env for a small pressure step.
* ``"numpy"`` (always available; what ``"auto"`` picks when numba is absent or ``PNEUNET_DISABLE_NUMBA=1``):
  the same control flow, vectorised. Every env carries its own program position (which descent,
  which Newton iteration, which line-search trial, its own sub-step size); each round evaluates the
  energy once for every env that needs an evaluation (:func:`pneunet_env.physics.mechanics.make_terms`'s
  numpy instantiation, the same formulas), then advances each env's control flow with masks. Envs
  that have finished are out of every later round. No Python loop over envs.

All quantities are dimensionless (lengths / ``w``, stresses and pressure / ``mu``), as in
:mod:`pneunet_env.physics.solver`.
"""

from __future__ import annotations

import hashlib
import math
import os
import sys
import threading
from pathlib import Path
from typing import NamedTuple

import numpy as np

from pneunet_env.physics import _jit, contact, mechanics
from pneunet_env.physics import solver as _solver
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import (
    ACCEPT_GTOL,
    ARMIJO,
    DEFAULT_OPTIONS,
    EASY_CORRECTOR_ITERATIONS,
    ENERGY_ROUNDOFF,
    ESCAPE_GRADIENT,
    ESCAPE_STEP,
    GROW,
    LAST_STEP_SLACK,
    MIN_STEP_LENGTH,
    PREDICTED_JUMP_FRACTION,
    SHRINK,
    STATUS_BUDGET,
    STATUS_CONVERGED,
    STATUS_INACTIVE,
    STATUS_LINE_SEARCH,
    STATUS_MAX_ITER,
    STATUS_OUTSIDE,
    STATUS_ROUNDOFF,
    STATUS_STALLED,
    STEP_AFTER_FOLD,
    Equilibrium,
    SolverOptions,
    make_sym2,
    params_tuple,
    step_state,
)

__all__ = ["BACKENDS", "PARALLEL_MIN_ENVS", "solve_batch", "solve_batch_numba", "solve_batch_numpy"]

BACKENDS = ("auto", "numba", "numpy")


class _Raw(NamedTuple):
    """The per-env outputs of a back-end, before :func:`_result` builds the :class:`Equilibrium`."""

    kappa: np.ndarray
    side_strain: np.ndarray
    energy: np.ndarray
    gradient_norm: np.ndarray
    min_eigenvalue: np.ndarray
    iterations: np.ndarray
    substeps: np.ndarray
    snapped: np.ndarray
    status: np.ndarray
    volume_change: np.ndarray


# --------------------------------------------------------------------------------------------------
# Input handling


def _column(name: str, value) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be real numbers, got {value!r}") from None
    if a.ndim > 1:
        raise ValueError(f"{name} must be a scalar or one-dimensional, got shape {a.shape}")
    return a


def _first_bad(name: str, a: np.ndarray, bad: np.ndarray, rule: str) -> None:
    if bad.any():
        i = int(np.flatnonzero(bad)[0]) if a.ndim else 0
        where = f"{name}[{i}]" if a.ndim else name
        v = a[i] if a.ndim else a[()]
        raise ValueError(f"{where} {rule}, got {float(v)!r}")


def _prepare(kappa, side_strain, p0, p1, object_stiffness, object_curvature, active, validate):
    cols = {
        "kappa": kappa,
        "side_strain": side_strain,
        "p0": p0,
        "p1": p1,
        "object_stiffness": object_stiffness,
        "object_curvature": object_curvature,
    }
    arrays = {name: _column(name, v) for name, v in cols.items()}
    if validate:
        for name, a in arrays.items():
            _first_bad(name, a, ~np.isfinite(a), "must be finite")
        _first_bad("p0", arrays["p0"], arrays["p0"] < 0.0, "(p~ = p/mu) must be >= 0")
        _first_bad("p1", arrays["p1"], arrays["p1"] < 0.0, "(p~ = p/mu) must be >= 0")
        _first_bad("object_stiffness", arrays["object_stiffness"], arrays["object_stiffness"] < 0.0,
                   "(k~_obj = k_obj w/mu) must be >= 0")
        ko = arrays["object_curvature"]
        _first_bad("object_curvature", ko, ~((ko > 0.0) & (ko < math.pi)), "(w kappa_obj) must be in (0, pi)")
    try:
        shape = np.broadcast_shapes(*(a.shape for a in arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k}: {a.shape}" for k, a in arrays.items())
        raise ValueError(f"inputs must broadcast to one shape (N,), got {shapes}") from None
    if shape == ():
        shape = (1,)
    out = [np.ascontiguousarray(np.broadcast_to(a, shape)) for a in arrays.values()]
    if active is None:
        act = np.ones(shape, dtype=bool)
    else:
        act = np.asarray(active)
        if act.dtype != bool:
            raise ValueError(f"active must be a boolean mask, got dtype {act.dtype}")
        if act.shape != shape:
            raise ValueError(f"active has shape {act.shape}, expected {shape}")
        act = np.ascontiguousarray(act)
    return out, act


def _check_domain(result: Equilibrium, kappa: np.ndarray, side_strain: np.ndarray) -> None:
    bad = result.status == STATUS_OUTSIDE
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"start state {i} (kappa[{i}]={float(kappa[i])!r}, side_strain[{i}]={float(side_strain[i])!r}) "
            "is outside the domain"
        )


def solve_batch(
    kappa,
    side_strain,
    p0,
    p1,
    object_stiffness=0.0,
    object_curvature=0.02,
    params: ActuatorParams | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
    *,
    active=None,
    backend: str = "auto",
    validate: bool = True,
    parallel: bool | None = None,
) -> Equilibrium:
    """Follow N equilibria from pressures ``p0`` to ``p1`` (quasi-static loading), all at once.

    Args:
        kappa: ``kappa~_i = w kappa``: start curvatures, shape ``(N,)`` (or a scalar, broadcast).
        side_strain: ``e_s`` of the start states.
        p0: the pressures ``p~ = p/mu >= 0`` at which the start states are equilibria (they are
            polished there first, as :func:`pneunet_env.physics.solver.solve_equilibrium` does).
        p1: the target pressures ``p~ >= 0``.
        object_stiffness: ``k~_obj = k_obj w/mu >= 0`` per env (0: free actuator).
        object_curvature: ``w kappa_obj`` in ``(0, pi)`` per env.
        params: the actuator (shared by all envs); paper defaults if ``None``.
        options: solver tolerances (shared).
        active: optional boolean mask ``(N,)``; inactive envs are not solved: they keep their input state, with
            NaN energy, gradient norm, eigenvalue and volume change, zero counts, ``converged`` false and
            ``status`` -1 (``STATUS_INACTIVE``).
        backend: ``"auto"`` (numba if available, else numpy), ``"numba"`` or ``"numpy"``.
        validate: check the inputs (finite, signs, ranges) and raise ``ValueError`` naming the first
            bad value. A start state outside the domain always raises.
        parallel: numba back-end only: split the envs over the cores (numba's threads). ``None``: from
            :data:`PARALLEL_MIN_ENVS` envs on. ``False`` where the cores are busy with other work (numba's
            OpenMP threads wait actively and lose badly when oversubscribed).

    Returns:
        An :class:`~pneunet_env.physics.solver.Equilibrium` of ``(N,)`` arrays (fresh each call); entry ``i``
        equals ``solve_equilibrium(p1[i], ..., initial=(kappa[i], side_strain[i]), initial_pressure=p0[i])``.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numba" and not HAVE_NUMBA:
        raise ValueError("backend='numba' needs numba (pip install pneunet-env[fast]; PNEUNET_DISABLE_NUMBA unset)")
    (k, s, a0, a1, kobj, ko), act = _prepare(kappa, side_strain, p0, p1, object_stiffness, object_curvature,
                                             active, validate)
    prm = params_tuple(params)
    opts = options.as_tuple()
    if backend == "numpy" or (backend == "auto" and not HAVE_NUMBA):
        result = solve_batch_numpy(k, s, a0, a1, kobj, ko, prm, opts, act)
    else:
        result = solve_batch_numba(k, s, a0, a1, kobj, ko, prm, opts, act, parallel)
    _check_domain(result, k, s)
    return result


def _result(raw: _Raw, p1, kobj, ko, chamber_height: float) -> Equilibrium:
    """The :class:`Equilibrium` of a back-end's outputs: eq. 3.1 and ``e_m`` from the state, as the scalar
    :func:`pneunet_env.physics.solver.equilibrium` computes them."""
    with np.errstate(divide="ignore", invalid="ignore"):
        delta, force, touching = contact.contact(raw.kappa, kobj, ko)
    status = raw.status
    return Equilibrium(
        p1.copy(), raw.kappa, raw.side_strain, chamber_height * (1.0 + raw.side_strain) * raw.kappa, force, delta,
        touching, raw.volume_change, raw.energy, raw.gradient_norm, raw.min_eigenvalue,
        (status >= STATUS_CONVERGED) & (status <= STATUS_ROUNDOFF), raw.iterations, raw.substeps, raw.snapped,
        status, kobj.copy(), ko.copy(),
    )


def _allocate(k, s) -> _Raw:
    n = k.shape[0]
    return _Raw(
        kappa=k.copy(),
        side_strain=s.copy(),
        energy=np.full(n, np.nan),
        gradient_norm=np.full(n, np.nan),
        min_eigenvalue=np.full(n, np.nan),
        iterations=np.zeros(n, dtype=np.int64),
        substeps=np.zeros(n, dtype=np.int64),
        snapped=np.zeros(n, dtype=bool),
        status=np.full(n, STATUS_INACTIVE, dtype=np.int64),
        volume_change=np.full(n, np.nan),
    )


# --------------------------------------------------------------------------------------------------
# Compiled back-end: a loop over envs around the compiled scalar continuation.

_PARALLEL_LOCK = threading.Lock()

PARALLEL_MIN_ENVS = 256
"""Below this many envs the serial compiled loop is used (thread start-up costs more than it saves)."""

def _source_stamp() -> int | None:
    """A hash of the sources the compiled loop is built from (numba's cache only watches this file); None if
    they cannot be read (then the loop is not cached)."""
    h = hashlib.sha256()
    try:
        for module in (mechanics, contact, _solver, _jit, sys.modules[__name__]):
            h.update(Path(module.__file__).read_bytes())
    except (OSError, TypeError):
        return None
    return int(h.hexdigest()[:15], 16)


def _make_loop(stamp: int, variant: int):
    # ``stamp`` and ``variant`` are closure variables, so they are part of the key of numba's on-disk cache:
    # an edit of the solver or the energy recompiles the loop instead of loading a stale one, and the
    # serial and parallel loops (same code, same name) get separate entries.
    def _loop(k, s, p0, p1, kobj, ko, prm, opts, active, ok, os_, oU, og, ol, oit, osub, osnap, ost, odv):
        if stamp < 0 or variant < 0:
            return
        for i in numba.prange(k.shape[0]):
            if active[i]:
                r = step_state(k[i], s[i], p0[i], p1[i], prm, kobj[i], ko[i], opts)
                ok[i] = r[0]
                os_[i] = r[1]
                oU[i] = r[2]
                og[i] = r[3]
                ol[i] = r[4]
                oit[i] = r[5]
                osub[i] = r[6]
                osnap[i] = r[7]
                ost[i] = r[8]
                odv[i] = r[9]

    return _loop


if HAVE_NUMBA:
    import numba

    if "NUMBA_THREADING_LAYER" not in os.environ and numba.config.THREADING_LAYER == "default":
        # GNU OpenMP (numba's usual pick) kills any child forked after a parallel loop ran: Gymnasium's
        # AsyncVectorEnv and multiprocessing pools fork by default on Linux. "forksafe" picks tbb if installed,
        # else the built-in workqueue, which is not thread-safe: _PARALLEL_LOCK serialises the parallel calls.
        numba.config.THREADING_LAYER = "forksafe"

    _stamp = _source_stamp()
    # Cached on disk (compiling the parallel loop takes seconds); the scalar solver's closures are not
    # cacheable (numba keys them by their pickled closure, which differs in every process).
    _cache = _stamp is not None
    _loop_serial = numba.njit(_make_loop(_stamp or 0, 0), nogil=True, cache=_cache)
    _loop_parallel = numba.njit(_make_loop(_stamp or 0, 1), nogil=True, parallel=True, cache=_cache)


def solve_batch_numba(k, s, p0, p1, kobj, ko, prm, opts, active, parallel: bool | None = None) -> Equilibrium:
    """The compiled back-end on prepared float64 arrays (no validation; see :func:`solve_batch`).

    ``prm`` is :func:`pneunet_env.physics.solver.params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`.
    ``parallel``: split the envs over the cores (``None``: when there are at least
    :data:`PARALLEL_MIN_ENVS`; the threads are numba's, ``NUMBA_NUM_THREADS``).
    """
    if not HAVE_NUMBA:
        raise RuntimeError("the numba back-end needs numba")
    out = _allocate(k, s)
    if parallel is None:
        parallel = k.shape[0] >= PARALLEL_MIN_ENVS
    args = (k, s, p0, p1, kobj, ko, prm, opts, active, out.kappa, out.side_strain, out.energy, out.gradient_norm,
            out.min_eigenvalue, out.iterations, out.substeps, out.snapped, out.status, out.volume_change)
    if parallel:
        with _PARALLEL_LOCK:  # one parallel loop at a time (the workqueue layer aborts on concurrent use)
            _loop_parallel(*args)
    else:
        _loop_serial(*args)
    return _result(out, p1, kobj, ko, prm[0])


# --------------------------------------------------------------------------------------------------
# Vectorised back-end: the scalar control flow of solver.descend / solver.follow_ev, one program
# position per env.

# Positions that need an energy evaluation at an env's pending point (xk, xs, xp) ...
_E_START = 1  # the start of a descent
_E_PRED = 2  # the tangent predictor of a corrector (falls back on the branch point if outside the domain)
_E_TRIAL = 3  # a line-search trial
# ... and positions that only branch.
_D_CHECK = 4  # top of a Newton iteration
_D_END = 5  # a descent has finished
_F_LOOP = 6  # top of the continuation loop
_DONE = 7

# Which descent an env is in.
_POLISH, _CORRECTOR, _FOLD = 0, 1, 2


_sym2_eigvals, _sym2_eigvec = make_sym2(np.hypot, np.arctan2, np.cos, np.sin, np.where)


class _Machine:
    """Registers of the vectorised solver: one entry per env, all float64/int64/bool arrays of shape (N,)."""

    # Iterate (current point of the running descent) and its evaluation.
    _FLOAT = ("k", "s", "U", "g0", "g1", "gn", "lmin", "lmax", "hkk", "hks", "hss", "vk", "vs", "dv",
              # Line search.
              "d0", "d1", "slope", "t", "kn", "sn",
              # Descent settings.
              "k0", "s0", "radius",
              # Accepted branch state (the continuation's current equilibrium) and its evaluation.
              "bk", "bs", "bU", "bgn", "blmin", "bhkk", "bhks", "bhss", "bvk", "bvs", "bdv",
              # Continuation.
              "p", "pt", "h", "sign",
              # Pending evaluation point.
              "xk", "xs", "xp")
    _INT = ("pos", "mode", "it", "maxit", "dstatus", "bstatus", "iters", "substeps", "attempts")
    _BOOL = ("ok", "bok", "snapped")

    def __init__(self, n: int):
        for name in self._FLOAT:
            setattr(self, name, np.zeros(n))
        for name in self._INT:
            setattr(self, name, np.zeros(n, dtype=np.int64))
        for name in self._BOOL:
            setattr(self, name, np.zeros(n, dtype=bool))


def solve_batch_numpy(k, s, p0, p1, kobj, ko, prm, opts, active) -> Equilibrium:
    """The vectorised (numpy-only) back-end on prepared float64 arrays (no validation; see :func:`solve_batch`).

    ``prm`` is :func:`pneunet_env.physics.solver.params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`.
    """
    gtol, max_iter, corr_iter, max_step, min_step, max_jump, eig_floor, max_substeps = opts
    n = k.shape[0]
    out = _allocate(k, s)
    m = _Machine(n)
    m.pos[:] = _DONE
    idx = np.flatnonzero(active)
    # follow_ev: polish the start (a full descent at p0), then continue.
    m.xk[idx], m.xs[idx], m.xp[idx] = k[idx], s[idx], p0[idx]
    m.k0[idx], m.s0[idx], m.radius[idx] = k[idx], s[idx], np.inf
    m.mode[idx] = _POLISH
    m.maxit[idx] = max_iter
    m.p[idx] = p0[idx]
    m.h[idx] = np.minimum(np.abs(p1[idx] - p0[idx]), max_step)
    m.sign[idx] = np.where(p1[idx] >= p0[idx], 1.0, -1.0)
    m.pos[idx] = _E_START

    with np.errstate(all="ignore"):
        while True:
            need = np.flatnonzero((m.pos == _E_START) | (m.pos == _E_PRED) | (m.pos == _E_TRIAL))
            if need.size == 0:
                break
            ev = mechanics._np_terms(m.xk[need], m.xs[need], m.xp[need], *prm, kobj[need], ko[need])
            _after_evaluation(m, need, ev)
            # Branch until every live env waits for an evaluation again.
            while True:
                moved = _descend_check(m, gtol, eig_floor)
                moved |= _descend_end(m, p1, max_iter, min_step, max_step, max_jump)
                moved |= _follow_loop(m, p1, corr_iter, min_step, max_jump, max_substeps)
                if not moved:
                    break

    a = idx
    out.kappa[a], out.side_strain[a], out.energy[a] = m.bk[a], m.bs[a], m.bU[a]
    out.gradient_norm[a], out.min_eigenvalue[a] = m.bgn[a], m.blmin[a]
    out.iterations[a], out.substeps[a], out.snapped[a] = m.iters[a], m.substeps[a], m.snapped[a]
    out.status[a] = m.bstatus[a]
    out.volume_change[a] = np.where(m.bok[a], m.bdv[a], np.nan)
    return _result(out, p1, kobj, ko, prm[0])


def _set_iterate(m: _Machine, i, kk, ss, ev_i) -> None:
    """Make (kk, ss) with evaluation ``ev_i`` (terms' tuple, already indexed) the iterate of envs ``i``."""
    ok, U, g0, g1, hkk, hks, hss, dv, vk, vs = ev_i
    m.k[i], m.s[i], m.ok[i], m.U[i], m.g0[i], m.g1[i] = kk, ss, ok, U, g0, g1
    m.hkk[i], m.hks[i], m.hss[i], m.dv[i], m.vk[i], m.vs[i] = hkk, hks, hss, dv, vk, vs
    m.gn[i] = np.hypot(g0, g1)
    m.lmin[i], m.lmax[i] = _sym2_eigvals(hkk, hks, hss)


def _after_evaluation(m: _Machine, need: np.ndarray, ev) -> None:
    pos = m.pos[need]
    ok = np.asarray(ev[0], dtype=bool)

    # A predictor outside the domain: the corrector starts from the branch point instead (another evaluation).
    sel = (pos == _E_PRED) & ~ok
    i = need[sel]
    m.xk[i], m.xs[i] = m.bk[i], m.bs[i]
    m.pos[i] = _E_START

    # The start of a descent (a predictor in the domain is one).
    sel = ((pos == _E_START) | (pos == _E_PRED)) & ~((pos == _E_PRED) & ~ok)
    i = need[sel]
    _set_iterate(m, i, m.xk[i], m.xs[i], tuple(np.asarray(v)[sel] for v in ev))
    m.it[i] = 0
    m.dstatus[i] = STATUS_MAX_ITER
    bad = ~ok[sel]
    j = i[bad]  # start outside the domain: descend returns (k, s, inf, inf, -inf, 0, 5)
    m.U[j], m.gn[j], m.lmin[j], m.dstatus[j] = np.inf, np.inf, -np.inf, STATUS_OUTSIDE
    m.pos[j] = _D_END
    m.pos[i[~bad]] = _D_CHECK

    # A line-search trial.
    sel = pos == _E_TRIAL
    if not sel.any():
        return
    i = need[sel]
    evs = tuple(np.asarray(v)[sel] for v in ev)
    tok = ok[sel]
    Un = evs[1]
    nnorm = np.hypot(evs[2], evs[3])
    U, t, gn = m.U[i], m.t[i], m.gn[i]
    armijo = (Un <= U + ARMIJO * t * m.slope[i]) | (
        (np.abs(Un - U) <= ENERGY_ROUNDOFF * np.maximum(1.0, np.abs(U))) & (nnorm < gn))
    acc = tok & armijo
    # Rejected: halve the step, or give up (status 3).
    r = i[~acc]
    m.t[r] *= 0.5
    more = m.t[r] > MIN_STEP_LENGTH
    rr = r[more]
    _trial_point(m, rr)
    m.pos[rr] = _E_TRIAL
    rf = r[~more]
    m.dstatus[rf] = STATUS_LINE_SEARCH
    m.pos[rf] = _D_END
    # Accepted: the trial becomes the iterate.
    a = i[acc]
    if a.size:
        moved = np.abs(m.kn[a] - m.k[a]) + np.abs(m.sn[a] - m.s[a])
        _set_iterate(m, a, m.kn[a], m.sn[a], tuple(v[acc] for v in evs))
        stalled = moved == 0.0
        m.dstatus[a[stalled]] = STATUS_STALLED
        far = np.maximum(np.abs(m.k[a] - m.k0[a]), np.abs(m.s[a] - m.s0[a])) > m.radius[a]
        guarded = (m.radius[a] < np.inf) & ((m.lmin[a] <= 0.0) | far)
        m.pos[a] = np.where(stalled | guarded, _D_END, _D_CHECK)


def _trial_point(m: _Machine, i: np.ndarray) -> None:
    t = m.t[i]
    kn = m.k[i] + t * m.d0[i]
    sn = m.s[i] + t * m.d1[i]
    kn = np.where(kn < 0.0, 0.0, kn)  # projected onto the domain's edge kappa~ = 0 (see solver.descend)
    m.kn[i], m.sn[i] = kn, sn
    m.xk[i], m.xs[i] = kn, sn


def _descend_check(m: _Machine, gtol: float, eig_floor: float) -> bool:
    i = np.flatnonzero(m.pos == _D_CHECK)
    if i.size == 0:
        return False
    gn, lmin, lmax = m.gn[i], m.lmin[i], m.lmax[i]
    conv = (gn <= gtol) & (lmin > 0.0)
    m.dstatus[i[conv]] = STATUS_CONVERGED
    limit = ~conv & (m.it[i] >= m.maxit[i])
    m.pos[i[conv | limit]] = _D_END
    go = ~(conv | limit)
    i = i[go]
    if i.size == 0:
        return True
    gn, lmin, lmax = gn[go], lmin[go], lmax[go]
    m.it[i] += 1
    g0, g1, hkk, hks, hss = m.g0[i], m.g1[i], m.hkk[i], m.hks[i], m.hss[i]
    scale = np.maximum(np.maximum(np.abs(lmin), np.abs(lmax)), 1.0)
    # Newton where the Hessian is safely positive definite, else on the eigenbasis (see solver.descend).
    det = hkk * hss - hks * hks
    newton = lmin >= eig_floor * scale
    ct, st = _sym2_eigvec(hkk, hks, hss)
    l1 = np.maximum(np.abs(lmin), eig_floor * scale)
    l2 = np.maximum(np.abs(lmax), eig_floor * scale)
    a2 = g0 * ct + g1 * st
    a1 = -g0 * st + g1 * ct
    d0 = np.where(newton, (hks * g1 - hss * g0) / det, -(a2 / l2) * ct + (a1 / l1) * st)
    d1 = np.where(newton, (hks * g0 - hkk * g1) / det, -(a2 / l2) * st - (a1 / l1) * ct)
    slope = g0 * d0 + g1 * d1
    neg = (lmin <= 0.0) & (gn <= ESCAPE_GRADIENT * gtol)
    if neg.any():
        v0, v1 = -st, ct
        step = ESCAPE_STEP * np.maximum(1.0, np.abs(m.k[i]))
        step = np.where(g0 * v0 + g1 * v1 > 0.0, -step, step)
        nd0, nd1 = step * v0, step * v1
        d0 = np.where(neg, nd0, d0)
        d1 = np.where(neg, nd1, d1)
        slope = np.where(neg, np.minimum(g0 * nd0 + g1 * nd1, 0.0), slope)
    m.d0[i], m.d1[i], m.slope[i] = d0, d1, slope
    m.t[i] = 1.0
    _trial_point(m, i)
    m.pos[i] = _E_TRIAL
    return True


def _descend_end(m: _Machine, p1, max_iter, min_step, max_step, max_jump) -> bool:
    i = np.flatnonzero(m.pos == _D_END)
    if i.size == 0:
        return False
    # descend's epilogue.
    floor = (m.dstatus[i] != STATUS_CONVERGED) & (m.gn[i] <= ACCEPT_GTOL) & (m.lmin[i] > 0.0)
    m.dstatus[i[floor]] = STATUS_ROUNDOFF
    mode = m.mode[i]
    m.iters[i] += m.it[i]

    # The polish at p0: its result is the branch state.
    a = i[mode == _POLISH]
    _accept(m, a)
    m.pos[a] = _F_LOOP

    # A corrector: accept the sub-step on the same branch, else shrink it, else a fold.
    c = i[mode == _CORRECTOR]
    jump = np.maximum(np.abs(m.k[c] - m.bk[c]), np.abs(m.s[c] - m.bs[c]))
    acc = (m.dstatus[c] <= STATUS_ROUNDOFF) & (jump <= max_jump)
    ca = c[acc]
    m.p[ca] = m.pt[ca]
    _accept(m, ca)
    m.substeps[ca] += 1
    grow = ca[m.it[ca] <= EASY_CORRECTOR_ITERATIONS]
    m.h[grow] = np.minimum(GROW * m.h[grow], max_step)
    m.pos[ca] = _F_LOOP
    cr = c[~acc]
    shrink = m.h[cr] > min_step
    cs = cr[shrink]
    m.h[cs] = np.maximum(SHRINK * m.h[cs], min_step)
    m.pos[cs] = _F_LOOP
    cf = cr[~shrink]  # the branch ends: descend fully from the branch point at pt
    m.xk[cf], m.xs[cf], m.xp[cf] = m.bk[cf], m.bs[cf], m.pt[cf]
    m.k0[cf], m.s0[cf], m.radius[cf] = m.bk[cf], m.bs[cf], np.inf
    m.maxit[cf] = max_iter
    m.mode[cf] = _FOLD
    m.pos[cf] = _E_START

    # After a fold.
    f = i[mode == _FOLD]
    m.substeps[f] += 1
    m.snapped[f] |= np.maximum(np.abs(m.k[f] - m.bk[f]), np.abs(m.s[f] - m.bs[f])) > max_jump
    m.p[f] = m.pt[f]
    _accept(m, f)
    m.h[f] = STEP_AFTER_FOLD * max_step
    m.pos[f] = _F_LOOP
    return True


def _accept(m: _Machine, i: np.ndarray) -> None:
    """The iterate of envs ``i`` becomes their branch state."""
    m.bk[i], m.bs[i], m.bU[i], m.bgn[i], m.blmin[i], m.bstatus[i] = m.k[i], m.s[i], m.U[i], m.gn[i], m.lmin[i], \
        m.dstatus[i]
    m.bok[i], m.bhkk[i], m.bhks[i], m.bhss[i] = m.ok[i], m.hkk[i], m.hks[i], m.hss[i]
    m.bvk[i], m.bvs[i], m.bdv[i] = m.vk[i], m.vs[i], m.dv[i]


def _follow_loop(m: _Machine, p1, corr_iter, min_step, max_jump, max_substeps) -> bool:
    i = np.flatnonzero(m.pos == _F_LOOP)
    if i.size == 0:
        return False
    done = (m.p[i] == p1[i]) | (m.bstatus[i] > STATUS_ROUNDOFF)
    m.pos[i[done]] = _DONE
    i = i[~done]
    spent = m.attempts[i] >= max_substeps  # the sub-step budget (see solver.follow_ev)
    m.bstatus[i[spent]] = STATUS_BUDGET
    m.pos[i[spent]] = _DONE
    i = i[~spent]
    m.attempts[i] += 1
    if i.size == 0:
        return True
    hkk, hks, hss, vk, vs = m.bhkk[i], m.bhks[i], m.bhss[i], m.bvk[i], m.bvs[i]
    det = hkk * hss - hks * hks
    tangent = (hkk > 0.0) & (det > 0.0)
    tk = np.where(tangent, (hss * vk - hks * vs) / det, 0.0)
    ts = np.where(tangent, (hkk * vs - hks * vk) / det, 0.0)
    rate = np.maximum(np.abs(tk), np.abs(ts))
    h = m.h[i]
    limit = tangent & (h * rate > PREDICTED_JUMP_FRACTION * max_jump)
    h = np.where(limit, np.maximum(PREDICTED_JUMP_FRACTION * max_jump / np.where(limit, rate, 1.0), min_step), h)
    m.h[i] = h
    p = m.p[i]
    remaining = np.abs(p1[i] - p)
    pt = np.where(h >= remaining * (1.0 - LAST_STEP_SLACK), p1[i], p + m.sign[i] * h)
    m.pt[i] = pt
    bk, bs = m.bk[i], m.bs[i]
    m.xk[i] = np.where(tangent, bk + (pt - p) * tk, bk)
    m.xs[i] = np.where(tangent, bs + (pt - p) * ts, bs)
    m.xp[i] = pt
    m.k0[i], m.s0[i], m.radius[i] = bk, bs, max_jump
    m.maxit[i] = corr_iter
    m.mode[i] = _CORRECTOR
    m.pos[i] = np.where(tangent, _E_PRED, _E_START)
    return True
