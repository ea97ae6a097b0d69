"""The vector env's step fused into one compiled loop (numba): :func:`fused_step` is :func:`pneunet_env.task.step`.

One pass over the envs, split over numba's threads, does for each env what :func:`pneunet_env.task.step` does with
array operations: the pressure update (:func:`pneunet_env.task.update_pressure`'s clip), the quasi-static solve
(:func:`pneunet_env.physics.solver.step_state`, the compiled continuation), eq. 3.1's contact
(:func:`pneunet_env.physics.contact.make_contact`), keeping the previous state where the solve did not converge, the
task's rules (:func:`pneunet_env.task.make_rules`, compiled) and the observation. Nothing is written twice: the
solve, the contact and the rules are the package's own formulas, compiled here. Only the per-env bookkeeping that
the array form does with ``where`` is a branch.

The result is a :class:`pneunet_env.task.Step`, bit for bit the one :func:`pneunet_env.task.step` gives with
:func:`pneunet_env.task.newton_contact_batch` (the same compiled scalar solve, the same operations in the same
order; tested), so the env's info, autoreset and seeding are unchanged.
"""

from __future__ import annotations

import sys

import numpy as np

from pneunet_env import task
from pneunet_env.physics import _jit, batched, contact, mechanics
from pneunet_env.physics import solver as _solver
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.solver import Equilibrium, _evaluate, step_state_from

__all__ = ["HAVE_FUSED", "fused_step"]

HAVE_FUSED = HAVE_NUMBA
"""Whether the fused step is available (it needs numba)."""


def _flag_value(flag):
    """A flag as the reward's number (1.0 or 0.0, what numpy's ``float * bool`` uses)."""
    return 1.0 if flag else 0.0


def _make_loop(stamp: int, variant: int):
    # stamp and variant key numba's on-disk cache (see physics.batched._make_loop).
    def _loop(action, command, k, s, p_eq, kobj, ko, eq_force, eq_delta, eq_touch, eq_dv, failure, crush, grip,
              step0, damaged0, dropped0, peak0, prm, opts, tp, ev_cache, ev_valid,
              o_p, o_k, o_s, o_top, o_force, o_delta, o_touch, o_dv, o_U, o_gn, o_lmin, o_conv, o_it, o_sub, o_snap,
              o_status, o_command, o_failed, o_clipped, o_step, o_damaged, o_dropped, o_peak, o_in_hold, o_over,
              o_crushed, o_dmg_event, o_slipping, o_drop_event, o_held, o_terminated, o_truncated, o_success,
              o_reward, o_obs):
        if stamp < 0 or variant < 0:
            return
        (dp, p_max, squeeze, episode, r_hold, r_success, pen_damage, pen_slip, term_damage, term_slip,
         volume_scale) = tp
        for i in numba.prange(k.shape[0]):
            a = action[i]
            o_clipped[i] = a < -1.0 or a > 1.0
            a = min(max(a, -1.0), 1.0)
            p = min(max(command[i] + a * dp, 0.0), p_max)
            c = ev_cache[i]
            if ev_valid[i]:  # the evaluation at (k, s, p_eq) that the last step ended on
                ev0 = (c[0] != 0.0, c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9])
            else:
                ev0 = _evaluate(k[i], s[i], p_eq[i], prm, kobj[i], ko[i])
            r = step_state_from(k[i], s[i], p_eq[i], p, prm, kobj[i], ko[i], opts, ev0)
            delta, force, touch = _contact(r[0], kobj[i], ko[i])
            status = r[8]
            conv = status >= 0 and status <= 1
            o_p[i] = p
            o_k[i] = r[0]
            o_s[i] = r[1]
            o_top[i] = prm[0] * (1.0 + r[1]) * r[0]
            o_force[i] = force
            o_delta[i] = delta
            o_touch[i] = touch
            o_dv[i] = r[9]
            o_U[i] = r[2]
            o_gn[i] = r[3]
            o_lmin[i] = r[4]
            o_conv[i] = conv
            o_it[i] = r[5]
            o_sub[i] = r[6]
            o_snap[i] = r[7]
            o_status[i] = status
            failed = not conv
            o_failed[i] = failed
            if not failed:  # the new state's evaluation, for the next step (a failed step keeps the state and its own)
                ev = r[10]
                c[0] = 1.0 if ev[0] else 0.0
                c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9] = ev[1], ev[2], ev[3], ev[4], ev[5], ev[6], \
                    ev[7], ev[8], ev[9]
                ev_valid[i] = True
            if failed:  # the previous state (and command) is kept
                p, force, delta, touch, dv = command[i], eq_force[i], eq_delta[i], eq_touch[i], eq_dv[i]
            else:
                dv = r[9]
            o_command[i] = p
            (o_step[i], o_damaged[i], o_dropped[i], o_peak[i], o_in_hold[i], o_over[i], o_crushed[i], o_dmg_event[i],
             o_slipping[i], o_drop_event[i], o_held[i], o_terminated[i], o_truncated[i], o_success[i],
             o_reward[i]) = _rules(step0[i], damaged0[i], dropped0[i], peak0[i], force, delta, touch, failure[i],
                                   crush[i], grip[i], failed, squeeze, episode, r_hold, r_success, pen_damage,
                                   pen_slip, term_damage, term_slip)
            o_obs[i, 0] = p / p_max
            if volume_scale > 0.0:
                o_obs[i, 1] = dv / volume_scale

    return _loop


if HAVE_NUMBA:
    import numba

    _contact = contact.make_contact(_jit.njit(mechanics._smax), _jit.njit(mechanics._swhere), jit=_jit.njit)[1]
    _rules = task.make_rules(_jit.njit(_flag_value), _jit.njit(mechanics._smax), jit=_jit.njit)
    _loop_serial, _loop_parallel = batched.compile_loops(
        _make_loop, (mechanics, contact, _solver, _jit, task, sys.modules[__name__]))


EV_FIELDS = 10
"""Floats per env of the evaluation cache (:func:`new_cache`): the energy kernel's 10-tuple, the flag as 0/1."""


def new_cache(n: int) -> tuple[np.ndarray, np.ndarray]:
    """An empty evaluation cache for ``n`` envs: ``(values (n, 10), valid (n,))``; see :func:`fused_step`."""
    return np.zeros((n, EV_FIELDS)), np.zeros(n, bool)


def fused_step(state: task.EnvState, action: np.ndarray, params: task.EnvParams, parallel: bool | None = None,
               threads: int | None = None, cache: tuple[np.ndarray, np.ndarray] | None = None) -> task.Step:
    """:func:`pneunet_env.task.step` for a batch on the numba back-end, as one compiled loop (see the module).

    Args:
        state: the batch's state (``(N,)`` float64/int64/bool arrays).
        action: float64 ``(N,)``, finite (:func:`pneunet_env.task.batch_actions`).
        params: the env's :class:`~pneunet_env.task.EnvParams`.
        parallel, threads: as for :func:`pneunet_env.physics.batched.solve_batch` (threads chosen by N).
        cache: ``(values, valid)`` from :func:`new_cache`, kept by the caller between steps: the energy evaluation
            each env's last step ended on, which is exactly the next step's first one (its state, its pressure, its
            object), so the step starts from it instead of evaluating again (one evaluation in about five). Updated
            in place; the caller marks envs it resets invalid (``valid[idx] = False``). ``None``: no cache. The
            results are the same, bit for bit.
    """
    if not HAVE_FUSED:
        raise RuntimeError("the fused step needs numba (pip install pneunet-env[fast])")
    n = action.shape[0]
    eq, obj, th, ts, tp = state.eq, state.obj, state.thresholds, state.task, params.task
    f8 = [np.empty(n) for _ in range(10)]  # p, k, s, top, force, delta, dv, U, gn, lmin
    p1, k1, s1, top, force, delta, dv, U, gn, lmin = f8
    touch, conv, snap, failed, clipped = (np.empty(n, bool) for _ in range(5))
    it, sub, status = (np.empty(n, np.int64) for _ in range(3))
    command = np.empty(n)
    t_step = np.empty(n, np.int64)
    t_damaged, t_dropped = np.empty(n, bool), np.empty(n, bool)
    t_peak = np.empty(n)
    flags = [np.empty(n, bool) for _ in range(10)]  # in_hold .. success
    reward = np.empty(n)
    vscale = params.volume_scale
    obs = np.empty((n, 1 if vscale is None else 2), np.float32)
    consts = (float(tp.pressure_step), float(tp.pressure_max), int(tp.squeeze_steps),
              int(tp.squeeze_steps + tp.hold_steps), float(tp.reward_hold), float(tp.reward_success),
              float(tp.penalty_damage), float(tp.penalty_slip), bool(tp.terminate_on_damage),
              bool(tp.terminate_on_slip), 0.0 if vscale is None else float(vscale))
    ev_cache, ev_valid = new_cache(n) if cache is None else cache
    args = (action, state.command, eq.curvature, eq.side_strain, eq.pressure, obj.stiffness, obj.curvature,
            eq.contact_force, eq.indentation, eq.in_contact, eq.volume_change, th.failure_traction,
            th.crush_indentation, th.grip_traction, ts.step, ts.damaged, ts.dropped, ts.peak_force, params.actuator,
            params.solver, consts, ev_cache, ev_valid, p1, k1, s1, top, force, delta, touch, dv, U, gn, lmin, conv, it,
            sub, snap, status, command, failed, clipped, t_step, t_damaged, t_dropped, t_peak, *flags, reward, obs)
    batched.run_loop(_loop_serial, _loop_parallel, args, n, parallel, threads)
    solve = Equilibrium(p1, k1, s1, top, force, delta, touch, dv, U, gn, lmin, conv, it, sub, snap, status,
                        obj.stiffness.copy(), obj.curvature.copy())
    new_eq = task._keep_where(failed, eq, solve)
    in_hold, overstressed, crushed, damage_event, slipping, drop_event, held, terminated, truncated, success = flags
    outcome = task.Outcome(task.TaskState(t_step, t_damaged, t_dropped, t_peak), in_hold, overstressed, crushed,
                           damage_event, slipping, drop_event, held, terminated, truncated, success, reward)
    new = task.EnvState(command, new_eq, state.obj, state.thresholds, outcome.state)
    return task.Step(new, obs, reward, terminated, truncated, solve, outcome, clipped, failed)
