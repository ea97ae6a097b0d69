"""The batched quasi-static solve with masks in place of branches: one algorithm for numpy and torch arrays.

:func:`solve_masked` advances N equilibria ``(kappa~_i, e_s_i)`` from pressures ``p0_i`` to ``p1_i`` with the
algorithm of :mod:`pneunet_env.physics.solver` (safeguarded modified Newton, an Armijo line search that rejects
non-finite energies and never leaves the domain, tangent-predictor continuation with sub-step control, fold
detection and snap), env for env the same decisions as the compiled scalar continuation
(:func:`pneunet_env.physics.solver.step_state`), so the answers agree to round-off.

Each env carries its own program position (which descent, which Newton iteration, which line-search trial, its
own sub-step size). A *round* evaluates the energy once at every live env's pending point
(:func:`pneunet_env.physics.mechanics.make_terms` on the namespace's operations, the same formulas) and then
advances every env's control flow by three masked phases (the end of a Newton iteration, the end of a descent,
the continuation's loop). Every register update is a ``where``: no Python branch depends on an env's values, no
env is gathered, so a round is a fixed sequence of array operations (what a GPU and ``torch.compile`` want).

Between rounds the driver may drop the envs that have finished (``compact``: a gather, which changes N), or, for a
round of fixed N (``torch.compile``'s), only check every ``check_every`` rounds whether any env is still live (on a
GPU each check is a host sync). ``max_rounds`` bounds the
work: an env still running then ends with ``STATUS_BUDGET`` (unconverged, flagged), never a hang.

Written once, against :class:`pneunet_env.physics.xp.Ops`: :data:`pneunet_env.physics.xp.NUMPY` is the
``"numpy"`` back-end of :func:`pneunet_env.physics.batched.solve_batch`, :func:`pneunet_env.physics.xp.torch_ops`
its ``"torch"`` back-end on a CPU or a GPU.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

from pneunet_env.physics import mechanics
from pneunet_env.physics.contact import make_contact
from pneunet_env.physics.continuation import (
    ACCEPT_GTOL,
    ARMIJO,
    BRANCH_MIDPOINT_FRACTION,
    EASY_CORRECTOR_ITERATIONS,
    ENERGY_ROUNDOFF,
    ESCAPE_GRADIENT,
    ESCAPE_STEP,
    GROW,
    LAST_STEP_SLACK,
    MIN_STEP_LENGTH,
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
    Solve,
    hermite_midpoint,
    make_sym2,
    predicted_change_limit,
)
from pneunet_env.physics.xp import Ops, copy

__all__ = ["solve_masked", "kernels", "Kernels", "OUTPUTS"]

# Program positions. Those that wait for an energy evaluation at the env's pending point (xk, xs, xp) ...
_E_START = 1  # the start of a descent
_E_PRED = 2  # the tangent predictor of a corrector (falls back on the branch point if outside the domain)
_E_TRIAL = 3  # a line-search trial
_E_MID = 4  # step_control "branch": the Hermite midpoint of a long sub-step (its ends on one branch?)
# ... those that only branch (resolved within the round) ...
_D_CHECK = 5  # top of a Newton iteration
_D_END = 6  # a descent has finished
_M_END = 7  # the midpoint's test is done (its answer in "mid_ok")
_F_LOOP = 8  # top of the continuation loop
# ... and the end.
_DONE = 9

# Which descent an env is in.
_POLISH, _CORRECTOR, _FOLD = 0, 1, 2

_FLOAT = ("k", "s", "U", "g0", "g1", "gn", "lmin", "lmax", "hkk", "hks", "hss", "vk", "vs", "dv",
          "d0", "d1", "slope", "t", "kn", "sn", "k0", "s0", "radius",
          "bk", "bs", "bU", "bgn", "blmin", "bhkk", "bhks", "bhss", "bvk", "bvs", "bdv",
          "p", "pt", "h", "sign", "xk", "xs", "xp", "tk", "ts")
_INT = ("pos", "mode", "it", "maxit", "dstatus", "bstatus", "iters", "substeps", "attempts", "evals", "backs")
_BOOL = ("ok", "bok", "snapped", "pred", "mid_ok")

OUTPUTS = Solve._fields
"""The per-env outputs of :func:`solve_masked`, in order (:class:`pneunet_env.physics.solver.Solve`'s fields)."""

class Kernels(NamedTuple):
    """The package's formulas on one namespace (:func:`kernels`)."""

    terms: Callable  # the energy kernel (:func:`pneunet_env.physics.mechanics.make_terms`)
    eigvals: Callable  # the 2x2 eigen helpers (:func:`pneunet_env.physics.solver.make_sym2`)
    eigvec: Callable
    contact: Callable  # eq. 3.1 (:func:`pneunet_env.physics.contact.make_contact`)


_KERNELS: dict[str, Kernels] = {}


def kernels(ops: Ops) -> Kernels:
    """The energy kernel, the 2x2 eigen helpers and eq. 3.1 on the namespace ``ops``, each the package's one
    formula."""
    key = f"{ops.name}:{ops.device}"
    if key not in _KERNELS:
        _, terms = mechanics.make_terms(ops.log, ops.tan, ops.where, ops.maximum, ops.abs)
        eigvals, eigvec = make_sym2(ops.hypot, ops.atan2, ops.cos, ops.sin, ops.where)
        _, contact = make_contact(ops.maximum, ops.where)
        _KERNELS[key] = Kernels(terms, eigvals, eigvec, contact)
    return _KERNELS[key]


_hermite_midpoint = getattr(hermite_midpoint, "py_func", hermite_midpoint)  # the scalar formula, on arrays
_predicted_change_limit = getattr(predicted_change_limit, "py_func", predicted_change_limit)  # (Python numbers)


def _hessian_solve(hkk, hks, hss, a, b, W):
    """:func:`pneunet_env.physics.solver.hessian_solve` on arrays: ``(pd, x0, x1)``, ``x = H^-1 (a, b)`` where ``H`` is
    positive definite (``pd``), 0 elsewhere."""
    det = hkk * hss - hks * hks
    pd = (hkk > 0.0) & (det > 0.0)
    det = W(pd, det, 1.0)  # no 0 / 0 where it is not used
    return pd, W(pd, (hss * a - hks * b) / det, 0.0), W(pd, (hkk * b - hks * a) / det, 0.0)


def _set_iterate(m, sel, kk, ss, ev, eigvals, ops: Ops) -> None:
    """Make ``(kk, ss)`` with evaluation ``ev`` the iterate of the envs ``sel``."""
    W = ops.where
    ok, U, g0, g1, hkk, hks, hss, dv, vk, vs = ev
    for name, v in (("k", kk), ("s", ss), ("ok", ok), ("U", U), ("g0", g0), ("g1", g1), ("hkk", hkk),
                    ("hks", hks), ("hss", hss), ("dv", dv), ("vk", vk), ("vs", vs)):
        m[name] = W(sel, v, m[name])
    lmin, lmax = eigvals(hkk, hks, hss)
    m["gn"] = W(sel, ops.hypot(g0, g1), m["gn"])
    m["lmin"] = W(sel, lmin, m["lmin"])
    m["lmax"] = W(sel, lmax, m["lmax"])


def _trial_point(m, sel, W) -> None:
    kn = m["k"] + m["t"] * m["d0"]
    sn = m["s"] + m["t"] * m["d1"]
    kn = W(kn < 0.0, 0.0, kn)  # projected onto the domain's edge kappa~ = 0 (see solver.descend)
    m["kn"], m["sn"] = W(sel, kn, m["kn"]), W(sel, sn, m["sn"])
    m["xk"], m["xs"] = W(sel, kn, m["xk"]), W(sel, sn, m["xs"])


def _accept(m, sel, W) -> None:
    """The iterate of the envs ``sel`` becomes their branch state."""
    for b, a in (("bk", "k"), ("bs", "s"), ("bU", "U"), ("bgn", "gn"), ("blmin", "lmin"), ("bstatus", "dstatus"),
                 ("bok", "ok"), ("bhkk", "hkk"), ("bhks", "hks"), ("bhss", "hss"), ("bvk", "vk"), ("bvs", "vs"),
                 ("bdv", "dv")):
        m[b] = W(sel, m[a], m[b])


def _after_evaluation(m, ev, ops: Ops, eigvals, max_jump) -> None:
    W, A = ops.where, ops.abs
    pos = m["pos"]
    ok = ev.ok
    # A predictor outside the domain: the corrector starts from the branch point instead (another evaluation),
    # and keeps within max_jump of it.
    pred_out = (pos == _E_PRED) & ~ok
    m["xk"], m["xs"] = W(pred_out, m["bk"], m["xk"]), W(pred_out, m["bs"], m["xs"])
    m["k0"], m["s0"] = W(pred_out, m["bk"], m["k0"]), W(pred_out, m["bs"], m["s0"])
    m["pred"] = W(pos == _E_PRED, ok, m["pred"])  # the corrector started from its predictor
    # The Hermite midpoint of a long sub-step ("branch"): its ends lie on one branch when the Newton correction there
    # is small (solver._one_branch).
    mid = pos == _E_MID
    pdm, ck, cs = _hessian_solve(ev.h_kk, ev.h_ks, ev.h_ss, ev.g_kappa, ev.g_strain, W)
    m["mid_ok"] = W(mid, ok & pdm & (ops.maximum(A(ck), A(cs)) <= BRANCH_MIDPOINT_FRACTION * max_jump), m["mid_ok"])
    # The start of a descent (a predictor inside the domain is one).
    start = ((pos == _E_START) | (pos == _E_PRED)) & ~pred_out
    # A line-search trial: decided on the iterate before it changes.
    trial = pos == _E_TRIAL
    Un = ev.energy
    nnorm = ops.hypot(ev.g_kappa, ev.g_strain)
    U, gn = m["U"], m["gn"]
    armijo = (Un <= U + ARMIJO * m["t"] * m["slope"]) | (
        (A(Un - U) <= ENERGY_ROUNDOFF * ops.maximum(A(U), 1.0)) & (nnorm < gn))
    acc = trial & ok & armijo
    rej = trial & ~acc
    moved = A(m["kn"] - m["k"]) + A(m["sn"] - m["s"])

    _set_iterate(m, start | acc, W(acc, m["kn"], m["xk"]), W(acc, m["sn"], m["xs"]), ev, eigvals, ops)

    bad = start & ~ok  # start outside the domain: descend returns (k, s, inf, inf, -inf, 0, 5)
    m["it"] = W(start, 0, m["it"])
    m["U"] = W(bad, math.inf, m["U"])
    m["gn"] = W(bad, math.inf, m["gn"])
    m["lmin"] = W(bad, -math.inf, m["lmin"])
    status = W(bad, STATUS_OUTSIDE, W(start, STATUS_MAX_ITER, m["dstatus"]))

    # Rejected trials: halve the step, or give up (status 3).
    m["backs"] = W(rej, m["backs"] + 1, m["backs"])
    m["t"] = W(rej, 0.5 * m["t"], m["t"])
    more = rej & (m["t"] > MIN_STEP_LENGTH)
    _trial_point(m, more, W)
    give_up = rej & ~more
    status = W(give_up, STATUS_LINE_SEARCH, status)
    # Accepted trials: the trial is the iterate now.
    stalled = acc & (moved == 0.0)
    status = W(stalled, STATUS_STALLED, status)
    far = ops.maximum(A(m["k"] - m["k0"]), A(m["s"] - m["s0"])) > m["radius"]
    guarded = (m["radius"] < math.inf) & ((m["lmin"] <= 0.0) | far)
    m["dstatus"] = status
    pos = W(pred_out, _E_START, W(mid, _M_END, pos))
    pos = W(start & ~bad, _D_CHECK, W(bad, _D_END, pos))
    pos = W(give_up, _D_END, pos)
    pos = W(acc, W(stalled | guarded, _D_END, _D_CHECK), pos)
    m["pos"] = pos


def _descend_check(m, gtol, eig_floor, ops: Ops, eigvec) -> None:
    W, A, mx = ops.where, ops.abs, ops.maximum
    sel = m["pos"] == _D_CHECK
    gn, lmin, lmax = m["gn"], m["lmin"], m["lmax"]
    conv = sel & (gn <= gtol) & (lmin > 0.0)
    limit = sel & ~conv & (m["it"] >= m["maxit"])
    go = sel & ~(conv | limit)
    m["dstatus"] = W(conv, STATUS_CONVERGED, m["dstatus"])
    m["it"] = W(go, m["it"] + 1, m["it"])
    g0, g1, hkk, hks, hss, k = m["g0"], m["g1"], m["hkk"], m["hks"], m["hss"], m["k"]
    scale = mx(mx(A(lmin), A(lmax)), 1.0)
    # Newton where the Hessian is safely positive definite, else on the eigenbasis (see solver.descend).
    det = hkk * hss - hks * hks
    newton = lmin >= eig_floor * scale
    ct, st = eigvec(hkk, hks, hss)
    l1 = mx(A(lmin), eig_floor * scale)
    l2 = mx(A(lmax), eig_floor * scale)
    a2 = g0 * ct + g1 * st
    a1 = -g0 * st + g1 * ct
    d0 = W(newton, (hks * g1 - hss * g0) / det, -(a2 / l2) * ct + (a1 / l1) * st)
    d1 = W(newton, (hks * g0 - hkk * g1) / det, -(a2 / l2) * st - (a1 / l1) * ct)
    slope = g0 * d0 + g1 * d1
    # (Near-)stationary but not a minimum: leave along the negative-curvature direction.
    neg = ~newton & (lmin <= 0.0) & (gn <= ESCAPE_GRADIENT * gtol)
    v0, v1 = -st, ct
    step = ESCAPE_STEP * mx(A(k), 1.0)
    step = W(g0 * v0 + g1 * v1 > 0.0, -step, step)
    nd0, nd1 = step * v0, step * v1
    d0, d1 = W(neg, nd0, d0), W(neg, nd1, d1)
    slope = W(neg, ops.minimum(g0 * nd0 + g1 * nd1, 0.0), slope)
    m["d0"], m["d1"], m["slope"] = W(go, d0, m["d0"]), W(go, d1, m["d1"]), W(go, slope, m["slope"])
    m["t"] = W(go, 1.0, m["t"])
    _trial_point(m, go, W)
    m["pos"] = W(go, _E_TRIAL, W(conv | limit, _D_END, m["pos"]))


def _descend_end(m, max_iter, min_step, max_step, max_jump, control, ops: Ops) -> None:
    W, A, mx = ops.where, ops.abs, ops.maximum
    ended = m["pos"] == _D_END
    tested = m["pos"] == _M_END  # a corrector whose long sub-step's midpoint was tested
    sel = ended | tested
    # descend's epilogue.
    floor = ended & (m["dstatus"] != STATUS_CONVERGED) & (m["gn"] <= ACCEPT_GTOL) & (m["lmin"] > 0.0)
    m["dstatus"] = W(floor, STATUS_ROUNDOFF, m["dstatus"])
    m["iters"] = W(ended, m["iters"] + m["it"], m["iters"])
    mode = m["mode"]
    k, s, bk, bs = m["k"], m["s"], m["bk"], m["bs"]
    jump = mx(A(k - bk), A(s - bs))  # from the branch state before it changes

    # The polish at p0: its result is the branch state.
    pol = sel & (mode == _POLISH)
    # A corrector: accept the sub-step on the same branch, else shrink it, else a fold.
    cor = sel & (mode == _CORRECTOR)
    converged = m["dstatus"] <= STATUS_ROUNDOFF
    acc = cor & ((ended & converged & (jump <= max_jump)) | (tested & m["mid_ok"]))
    if control == 1:
        # "branch": a corrector that converged within max_jump of its predictor (k0, s0) but moved farther from the
        # branch state: accepted if the midpoint of the two ends' Hermite interpolant lies on their branch (an
        # evaluation, where the end's Hessian is positive definite; else a rejection).
        pd1, t1k, t1s = _hessian_solve(m["hkk"], m["hks"], m["hss"], m["vk"], m["vs"], W)
        long = cor & ended & ~acc & m["pred"] & converged & (mx(A(k - m["k0"]), A(s - m["s0"])) <= max_jump)
        test = long & pd1
        km, sm = _hermite_midpoint(bk, bs, m["tk"], m["ts"], k, s, t1k, t1s, m["pt"] - m["p"])
        m["xk"], m["xs"] = W(test, km, m["xk"]), W(test, sm, m["xs"])
        m["xp"] = W(test, 0.5 * (m["p"] + m["pt"]), m["xp"])
        rej = cor & ~acc & ~test
    else:
        test = None
        rej = cor & ~acc
    shrink = rej & (m["h"] > min_step)
    fold_start = rej & ~shrink  # the branch ends: descend fully from the branch point at pt
    # After a fold.
    fold = sel & (mode == _FOLD)

    m["p"] = W(acc | fold, m["pt"], m["p"])
    m["substeps"] = W(acc | fold, m["substeps"] + 1, m["substeps"])
    m["snapped"] = m["snapped"] | (fold & (jump > max_jump))
    _accept(m, pol | acc | fold, W)
    h = m["h"]
    h = W(acc & (m["it"] <= EASY_CORRECTOR_ITERATIONS), ops.minimum(GROW * h, max_step), h)
    h = W(shrink, mx(SHRINK * h, min_step), h)
    h = W(fold, STEP_AFTER_FOLD * max_step, h)
    m["h"] = h
    m["xk"], m["xs"], m["xp"] = W(fold_start, m["bk"], m["xk"]), W(fold_start, m["bs"], m["xs"]), \
        W(fold_start, m["pt"], m["xp"])
    m["k0"], m["s0"] = W(fold_start, m["bk"], m["k0"]), W(fold_start, m["bs"], m["s0"])
    m["radius"] = W(fold_start, math.inf, m["radius"])
    m["maxit"] = W(fold_start, max_iter, m["maxit"])
    m["mode"] = W(fold_start, _FOLD, mode)
    pos = W(fold_start, _E_START, W(pol | acc | shrink | fold, _F_LOOP, m["pos"]))
    m["pos"] = pos if test is None else W(test, _E_MID, pos)


def _follow_loop(m, corr_iter, min_step, max_jump, max_substeps, control, ops: Ops) -> None:
    W, A, mx = ops.where, ops.abs, ops.maximum
    sel = m["pos"] == _F_LOOP
    done = sel & ((m["p"] == m["p1"]) | (m["bstatus"] > STATUS_ROUNDOFF))
    live = sel & ~done
    spent = live & (m["attempts"] >= max_substeps)  # the sub-step budget (see solver.follow_ev)
    go = live & ~spent
    m["bstatus"] = W(spent, STATUS_BUDGET, m["bstatus"])
    m["attempts"] = W(go, m["attempts"] + 1, m["attempts"])
    # The tangent dx/dp at the branch state, where its Hessian is positive definite.
    tangent, tk, ts = _hessian_solve(m["bhkk"], m["bhks"], m["bhss"], m["bvk"], m["bvs"], W)
    rate = mx(A(tk), A(ts))
    h = m["h"]
    predicted_limit = _predicted_change_limit(max_jump, control)  # ("branch": longer, accepted on one branch)
    limit = tangent & (h * rate > predicted_limit)
    h = W(limit, mx(predicted_limit / W(limit, rate, 1.0), min_step), h)
    p, p1, bk, bs = m["p"], m["p1"], m["bk"], m["bs"]
    pt = W(h >= A(p1 - p) * (1.0 - LAST_STEP_SLACK), p1, p + m["sign"] * h)
    m["h"] = W(go, h, m["h"])
    m["pt"] = W(go, pt, m["pt"])
    kc, sc = W(tangent, bk + (pt - p) * tk, bk), W(tangent, bs + (pt - p) * ts, bs)
    m["xk"], m["xs"], m["xp"] = W(go, kc, m["xk"]), W(go, sc, m["xs"]), W(go, pt, m["xp"])
    m["tk"], m["ts"] = W(go, tk, m["tk"]), W(go, ts, m["ts"])
    m["pred"] = W(go, False, m["pred"])
    # The corrector keeps within max_jump of the branch state ("jump") or of its predictor ("branch").
    k0, s0 = (bk, bs) if control == 0 else (kc, sc)
    m["k0"], m["s0"] = W(go, k0, m["k0"]), W(go, s0, m["s0"])
    m["radius"] = W(go, max_jump, m["radius"])
    m["maxit"] = W(go, corr_iter, m["maxit"])
    m["mode"] = W(go, _CORRECTOR, m["mode"])
    m["pos"] = W(go, W(tangent, _E_PRED, _E_START), W(done | spent, _DONE, m["pos"]))


def _round(m, prm, opts, ops: Ops, kern) -> None:
    """One round: evaluate every env's pending point, then advance every env's control flow (in place in ``m``)."""
    terms, eigvals, eigvec = kern.terms, kern.eigvals, kern.eigvec
    gtol, max_iter, corr_iter, max_step, min_step, max_jump, eig_floor, max_substeps, control = opts
    ev = terms(m["xk"], m["xs"], m["xp"], *prm, m["kobj"], m["ko"])
    m["evals"] = ops.where(m["pos"] <= _E_MID, m["evals"] + 1, m["evals"])  # the envs waiting for it (not _DONE)
    _after_evaluation(m, ev, ops, eigvals, max_jump)
    # Every env that waited for this evaluation is now at a branch position, and one pass resolves them all:
    # D_CHECK -> E_TRIAL or D_END; D_END, M_END -> F_LOOP, E_START or E_MID; F_LOOP -> E_PRED, E_START or DONE.
    _descend_check(m, gtol, eig_floor, ops, eigvec)
    _descend_end(m, max_iter, min_step, max_step, max_jump, control, ops)
    _follow_loop(m, corr_iter, min_step, max_jump, max_substeps, control, ops)


def _outputs(m, ops: Ops) -> dict[str, Any]:
    bok = m["bok"]
    return {
        "kappa": m["bk"], "side_strain": m["bs"], "energy": m["bU"], "gradient_norm": m["bgn"],
        "min_eigenvalue": m["blmin"], "iterations": m["iters"], "substeps": m["substeps"], "snapped": m["snapped"],
        "status": m["bstatus"], "volume_change": ops.where(bok, m["bdv"], math.nan), "evaluations": m["evals"],
        "backtracks": m["backs"],
    }


def solve_masked(k, s, p0, p1, kobj, ko, prm, opts, active, ops: Ops, *, compact: bool = True,
                 check_every: int = 1, max_rounds: int | None = None, round_fn=None) -> dict[str, Any]:
    """Follow N equilibria from ``p0`` to ``p1`` on the namespace ``ops`` (no validation; see
    :func:`pneunet_env.physics.batched.solve_batch`, which checks the inputs and builds the result).

    Args:
        k, s, p0, p1, kobj, ko: float64 ``(N,)`` arrays of the namespace (start state, pressures, object).
        prm: :func:`pneunet_env.physics.solver.params_tuple`; opts: :meth:`SolverOptions.as_tuple`.
        active: bool ``(N,)``; inactive envs keep their state (NaN diagnostics, ``STATUS_INACTIVE``).
        ops: the namespace (:data:`pneunet_env.physics.xp.NUMPY` or :func:`~pneunet_env.physics.xp.torch_ops`).
        compact: drop finished envs from the rounds once at most half are live (a gather).
        check_every: rounds between the checks for live envs (each a host sync on a GPU).
        max_rounds: bound on the rounds; envs still running then end with ``STATUS_BUDGET``. ``None``: until
            every env has finished (the algorithm's own budgets, ``max_iter`` and ``max_substeps``, bound it).
        round_fn: a replacement for the round (e.g. ``torch.compile`` of it), same signature as :func:`_round`.

    Returns:
        The outputs :data:`OUTPUTS` as a dict of ``(N,)`` arrays of the namespace.
    """
    W = ops.where
    n = k.shape[0]
    kern = kernels(ops)
    step = _round if round_fn is None else round_fn
    _, max_iter, _, max_step, *_ = opts
    m: dict[str, Any] = {name: ops.full(n, 0.0, "float") for name in _FLOAT}
    m.update({name: ops.full(n, 0, "int") for name in _INT})
    m.update({name: ops.full(n, False, "bool") for name in _BOOL})
    m["p1"], m["kobj"], m["ko"] = p1, kobj, ko
    for name in ("bU", "bgn", "blmin"):  # NaN until a polish has given the branch state (inactive envs stay NaN)
        m[name] = ops.full(n, math.nan, "float")
    # follow_ev: polish the start (a full descent at p0), then continue.
    m["xk"], m["xs"], m["xp"] = k, s, p0
    m["k0"], m["s0"] = k, s
    m["radius"] = W(active, math.inf, 0.0)
    m["mode"] = W(active, _POLISH, m["mode"])
    m["maxit"] = W(active, max_iter, m["maxit"])
    m["p"] = p0
    m["h"] = ops.minimum(ops.abs(p1 - p0), max_step)
    m["sign"] = W(p1 >= p0, 1.0, -1.0)
    m["pos"] = W(active, _E_START, _DONE)

    out = _outputs(m, ops)  # the batch's outputs, written by _store as envs leave the rounds
    orig = None  # indices of the machine's envs in the batch, once compacted
    size = n
    rounds = 0
    while True:
        if rounds % check_every == 0:
            live = m["pos"] != _DONE
            n_live = int(live.sum())
            if n_live == 0:
                break
            if compact and n_live * 2 <= size:
                _store(out, _outputs(m, ops), ~live, orig, ops)
                keep = ops.nonzero(live)
                orig = keep if orig is None else orig[keep]
                m = {name: v[keep] for name, v in m.items()}
                size = n_live
        if max_rounds is not None and rounds >= max_rounds:
            # Out of rounds: the envs still running keep their last branch state (the start, if still in the
            # polish) and are flagged unconverged.
            live = m["pos"] != _DONE
            m["bstatus"] = W(live, STATUS_BUDGET, m["bstatus"])
            polish = live & (m["mode"] == _POLISH)
            m["bk"], m["bs"] = W(polish, m["k0"], m["bk"]), W(polish, m["s0"], m["bs"])
            m["bok"] = W(polish, False, m["bok"])
            break
        step(m, prm, opts, ops, kern)
        rounds += 1
    _store(out, _outputs(m, ops), None, orig, ops)
    # Inactive envs keep their input state.
    out["kappa"] = W(active, out["kappa"], k)
    out["side_strain"] = W(active, out["side_strain"], s)
    out["status"] = W(active, out["status"], STATUS_INACTIVE)
    return out


def _store(out, res, sel, orig, ops: Ops) -> None:
    """Write the outputs ``res`` of the machine's envs (those of ``sel``; all if ``None``) into ``out``."""
    for name in OUTPUTS:
        v = res[name]
        if orig is None:
            out[name] = v if sel is None else ops.where(sel, v, out[name])
        else:
            idx = orig if sel is None else orig[sel]
            dst = copy(out[name])
            dst[idx] = v if sel is None else v[sel]
            out[name] = dst
