"""The vector env's step fused into one compiled loop (numba): :func:`fused_step` is :func:`pneunet_env.task.step`.

One pass over the envs, split over numba's threads, does for each env what :func:`pneunet_env.task.step` does with
array operations: the pressure update (:func:`pneunet_env.task.update_pressure`'s clip), the quasi-static solve
(:func:`pneunet_env.physics.solver.step_state`, the compiled continuation), eq. 3.1's contact
(:func:`pneunet_env.physics.contact.make_contact`), keeping the previous state where the solve did not converge, the
task's rules (:func:`pneunet_env.task.make_rules`, compiled) and the observation. Nothing is written twice: the
solve, the contact and the rules are the package's own formulas, compiled here. Only the per-env bookkeeping that
the array form does with ``where`` is a branch.

The loop takes records: the state's (:class:`~pneunet_env.physics.solver.Equilibrium`,
:class:`~pneunet_env.task.Thresholds`, :class:`~pneunet_env.task.TaskState` of ``(N,)`` arrays), the task's params
(:class:`~pneunet_env.task.TaskParams`, numbers, as the rules read them) and its outputs (:class:`Outputs`). Inside,
the arrays are bound to names before the parallel loop: numba's parallel loop can neither take a record of arrays
nor keep the writes made through one (numba 0.68; the tests compare the parallel loop with the serial one).

The result is a :class:`pneunet_env.task.Step`, bit for bit the one :func:`pneunet_env.task.step` gives with
:func:`pneunet_env.task.newton_contact_batch` (the same compiled scalar solve, the same operations in the same
order; tested), so the env's info, autoreset and seeding are unchanged, where the params carry no free table
(``solver.free_table: false``). With one (the default), a step that touches nothing follows the free actuator's
tabulated path (:mod:`pneunet_env.physics.free_table`): the same minimum to within the solver's tolerance (not bit
for bit), in one or two energy evaluations. Only the work differs, and the solve's
``evaluations`` says so: with the cache (see :func:`fused_step`) a step starts from the evaluation its last step
ended on, and where the pressure did not change and that start is a converged minimum (the descent's own test) the
solve is skipped, its result being the start itself, as the continuation would return it.

The single env's step (:class:`SingleStep`) is the same loop at N = 1, inlined into one compiled function on the
env's state packed in one float array: one call from Python instead of the scalar :func:`pneunet_env.task.step`'s
dozens, with the same :class:`~pneunet_env.task.Step`, bit for bit (without the free table; with it, as above).
(Calling the loop itself keeps one copy of the per-env code; a shared per-env function, tried first, cost the vector
loop 5-9 % even inlined.) The call takes arrays only (the params' numbers packed in one, :func:`_pack_params`), as
numba types a tuple's numbers one by one on every call, and writes its results in place; a lean ``env.step``
(:meth:`SingleStep.step_lean`) reads them as two lists and builds no record (0.10.0's step built seven, and its info
through the table's 17 rows: 26 us against 6 us unwrapped).
"""

from __future__ import annotations

import math
import sys
import types
from typing import Any, NamedTuple

import numpy as np

from pneunet_env import config, task, task_objects
from pneunet_env.actions import check_action
from pneunet_env.config import EnvConfig
from pneunet_env.info import lean_info
from pneunet_env.physics import _jit, batched, contact, continuation, free_table, mechanics, xp
from pneunet_env.physics import solver as _solver
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.continuation import (
    STATUS_CONVERGED,
    STATUS_INACTIVE,
    Continuation,
    _evaluate,
    _follow_from,
    sym2_eigvals,
)
from pneunet_env.physics.free_table import _follow_table
from pneunet_env.physics.mechanics import Evaluation
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.task import TaskState, Touch
from pneunet_env.task_objects import Thresholds

__all__ = ["HAVE_FUSED", "fused_step", "Outputs", "new_cache", "SingleStep", "STATE_SIZE"]

HAVE_FUSED = HAVE_NUMBA
"""Whether the fused step is available (it needs numba)."""


class Outputs(NamedTuple):
    """The arrays the fused loop writes, env by env (``(N,)``; the observation ``(N, 1)`` or ``(N, 2)``)."""

    command: np.ndarray  # the new command (the previous one where the solve failed)
    solve: Equilibrium  # the step's solve (its object fields are copies of the object's, not written by the loop)
    failed: np.ndarray
    clipped: np.ndarray
    outcome: task.Outcome
    obs: np.ndarray


def _flag_value(flag):
    """A flag as the reward's number (1.0 or 0.0, what numpy's ``float * bool`` uses)."""
    return 1.0 if flag else 0.0


def _make_loop(stamp: int, variant: int):
    # stamp and variant key numba's on-disk cache (see physics.batched._make_loop).
    def _loop(action, command, eq, kobj, ko, thresholds, state, tp, volume_scale, prm, opts, table, spacing, ev_cache,
              ev_valid, out):
        if stamp < 0 or variant < 0:
            return
        # The arrays, by name, one assignment each (see the module: no records of arrays in the parallel loop).
        k_in = eq.curvature
        s_in = eq.side_strain
        p_in = eq.pressure
        force_in = eq.contact_force
        delta_in = eq.indentation
        touch_in = eq.in_contact
        dv_in = eq.volume_change
        gn_in = eq.gradient_norm
        lmin_in = eq.min_eigenvalue
        failure = thresholds.failure_traction
        crush = thresholds.crush_indentation
        grip = thresholds.grip_traction
        step0 = state.step
        damaged0 = state.damaged
        dropped0 = state.dropped
        peak0 = state.peak_force
        solve = out.solve
        o_p = solve.pressure
        o_k = solve.curvature
        o_s = solve.side_strain
        o_top = solve.top_strain
        o_force = solve.contact_force
        o_delta = solve.indentation
        o_touch = solve.in_contact
        o_dv = solve.volume_change
        o_energy = solve.energy
        o_gn = solve.gradient_norm
        o_lmin = solve.min_eigenvalue
        o_conv = solve.converged
        o_it = solve.iterations
        o_sub = solve.substeps
        o_snap = solve.snapped
        o_status = solve.status
        o_evals = solve.evaluations
        o_backs = solve.backtracks
        outcome = out.outcome
        o_step = outcome.state.step
        o_damaged = outcome.state.damaged
        o_dropped = outcome.state.dropped
        o_peak = outcome.state.peak_force
        o_in_hold = outcome.in_hold
        o_over = outcome.overstressed
        o_crushed = outcome.crushed
        o_damage_event = outcome.damage_event
        o_slipping = outcome.slipping
        o_drop_event = outcome.drop_event
        o_held = outcome.held
        o_terminated = outcome.terminated
        o_truncated = outcome.truncated
        o_success = outcome.success
        o_reward = outcome.reward
        o_command = out.command
        o_failed = out.failed
        o_clipped = out.clipped
        o_obs = out.obs
        gtol = opts[0]  # SolverOptions.as_tuple(): the gradient tolerance first
        for i in numba.prange(action.shape[0]):
            a = action[i]
            o_clipped[i] = a < -1.0 or a > 1.0
            a = min(max(a, -1.0), 1.0)
            p = min(max(command[i] + a * tp.pressure_step, 0.0), tp.pressure_max)
            c = ev_cache[i]  # the row of the evaluation cache: the kernel's Evaluation, the flag as 0/1
            n_start = 0  # the start's evaluation: cached, or made here
            if ev_valid[i]:  # the evaluation at (k, s, p_eq) that the last step ended on
                ev0 = Evaluation(c[0] != 0.0, c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9])
            else:
                ev0 = _evaluate(k_in[i], s_in[i], p_in[i], prm, kobj[i], ko[i])
                n_start = 1
            # Where the pressure did not change and the start is a converged minimum (the descent's own test, on
            # its own numbers), the continuation would return the start unchanged with no work: skip the call.
            # With the cached evaluation, those numbers are the state's own: its gradient norm and smallest
            # eigenvalue were computed from that evaluation when the state was accepted (bit for bit; held envs'
            # steps 80 -> 51 ns without the hypot and the eigenvalues).
            skip = False
            if p == p_in[i] and ev0.ok:
                if n_start == 0:
                    gn0 = gn_in[i]
                    lmin0 = lmin_in[i]
                else:
                    gn0 = math.hypot(ev0.g_kappa, ev0.g_strain)
                    lmin0 = sym2_eigvals(ev0.h_kk, ev0.h_ks, ev0.h_ss)[0]
                skip = gn0 <= gtol and lmin0 > 0.0
            spent = 0  # the work of a try along the free table that could not take the step
            spent_back = 0
            if skip:
                r = Continuation(k_in[i], s_in[i], ev0.energy, gn0, lmin0, 0, 0, False, STATUS_CONVERGED,
                                 ev0.volume_change, 0, 0, ev0)
            else:
                # a step that touches nothing, along the free actuator's table (an empty table: never)
                r = _follow_table(k_in[i], s_in[i], p_in[i], p, prm, kobj[i], ko[i], opts, table, spacing)
                if r.status == STATUS_INACTIVE:
                    spent, spent_back = r.evaluations, r.backtracks
                    r = _follow_from(k_in[i], s_in[i], p_in[i], p, prm, kobj[i], ko[i], opts, ev0)
            delta, force, touch = _contact(r.kappa, kobj[i], ko[i])
            conv = r.status >= 0 and r.status <= 1
            o_p[i] = p
            o_k[i] = r.kappa
            o_s[i] = r.side_strain
            o_top[i] = prm.chamber_height * (1.0 + r.side_strain) * r.kappa
            o_force[i] = force
            o_delta[i] = delta
            o_touch[i] = touch
            o_dv[i] = r.volume_change
            o_energy[i] = r.energy
            o_gn[i] = r.gradient_norm
            o_lmin[i] = r.min_eigenvalue
            o_conv[i] = conv
            o_it[i] = r.iterations
            o_sub[i] = r.substeps
            o_snap[i] = r.snapped
            o_status[i] = r.status
            o_evals[i] = n_start + spent + r.evaluations
            o_backs[i] = spent_back + r.backtracks
            failed = not conv
            o_failed[i] = failed
            if not failed:  # the new state's evaluation, for the next step (a failed step keeps the state and its own)
                ev = r.evaluation
                c[0] = 1.0 if ev.ok else 0.0
                c[1], c[2], c[3], c[4], c[5] = ev.energy, ev.g_kappa, ev.g_strain, ev.h_kk, ev.h_ks
                c[6], c[7], c[8], c[9] = ev.h_ss, ev.volume_change, ev.v_kappa, ev.v_strain
                ev_valid[i] = True
            if failed:  # the previous state (and command) is kept
                p, force, delta, touch, dv = command[i], force_in[i], delta_in[i], touch_in[i], dv_in[i]
            else:
                dv = r.volume_change
            o_command[i] = p
            o = _rules(TaskState(step0[i], damaged0[i], dropped0[i], peak0[i]), Touch(force, delta, touch),
                       Thresholds(failure[i], crush[i], grip[i]), failed, tp)
            o_step[i] = o.state.step
            o_damaged[i] = o.state.damaged
            o_dropped[i] = o.state.dropped
            o_peak[i] = o.state.peak_force
            o_in_hold[i] = o.in_hold
            o_over[i] = o.overstressed
            o_crushed[i] = o.crushed
            o_damage_event[i] = o.damage_event
            o_slipping[i] = o.slipping
            o_drop_event[i] = o.drop_event
            o_held[i] = o.held
            o_terminated[i] = o.terminated
            o_truncated[i] = o.truncated
            o_success[i] = o.success
            o_reward[i] = o.reward
            o_obs[i, 0] = p / tp.pressure_max
            if volume_scale > 0.0:
                o_obs[i, 1] = dv / volume_scale

    return _loop


_SOURCES = (mechanics, contact, continuation, _solver, free_table, _jit, xp, config, task, task_objects,
            sys.modules[__name__])
"""The sources the compiled steps are built from (they key numba's disk cache: see ``_jit.njit_cached``). ``config``
too: the task's params are its task section's fields, in their order, and the compiled code reads them by
position."""

if HAVE_NUMBA:
    import numba

    _contact = contact.make_contact(_jit.njit(xp.scalar_max), _jit.njit(xp.scalar_where), jit=_jit.njit)[1]
    _rules = task.make_rules(_jit.njit(_flag_value), _jit.njit(xp.scalar_max), jit=_jit.njit)
    _loop_serial, _loop_parallel = batched.compile_loops(_make_loop, _SOURCES)
    # the single step's copy of the loop, inlined into it (numba IR): its ~50 array views are then made and released
    # in one function, and numba drops their reference counting in pairs (1.6 -> 0.8 us a held step's compiled call)
    _loop_single = numba.njit(_make_loop(0, 2), inline="always", nogil=True)


EV_FIELDS = len(Evaluation._fields)
"""Floats per env of the evaluation cache (:func:`new_cache`): the energy kernel's :class:`Evaluation`, the flag as
0/1."""


def new_cache(n: int) -> tuple[np.ndarray, np.ndarray]:
    """An empty evaluation cache for ``n`` envs: ``(values (n, 10), valid (n,))``; see :func:`fused_step`."""
    return np.zeros((n, EV_FIELDS)), np.zeros(n, bool)


def _empty(record_type, n: int, dtypes: dict[str, Any]):
    """A record of ``n`` uninitialised entries per field (float64 unless ``dtypes`` names another)."""
    return record_type(*(np.empty(n, dtypes.get(f, np.float64)) for f in record_type._fields))


_SOLVE_DTYPES = {"in_contact": bool, "converged": bool, "snapped": bool, "iterations": np.int64, "substeps": np.int64,
                 "status": np.int64, "evaluations": np.int64, "backtracks": np.int64}
_OUTCOME_DTYPES = {f: bool for f in task.Outcome._fields if f != "reward"}
_STATE_DTYPES = {"step": np.int64, "damaged": bool, "dropped": bool}


def _loop_params(tp: task.TaskParams) -> task.TaskParams:
    """The task's params as the compiled loop takes them: numbers only. The namespace and the strings (the damage
    rule, used at reset) become ``None``: a string would be reference-counted in every env's call of the rules."""
    return tp._replace(ops=None, **{f: None for f, v in zip(tp._fields, tp, strict=True) if isinstance(v, str)})


def _table(params: task.EnvParams) -> tuple[np.ndarray, float]:
    """The free table's ``(nodes, spacing)`` as the loop takes them (an empty one where the params have none)."""
    t = free_table.EMPTY if params.free_table is None else params.free_table
    nodes = t.nodes
    if nodes.flags.writeable:  # (an unpickled table): read-only, as numba compiled the loops for
        nodes = nodes.view()
        nodes.setflags(write=False)
    return nodes, float(t.spacing)


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
    obj, vscale = state.obj, params.volume_scale
    solve = _empty(Equilibrium, n, _SOLVE_DTYPES)._replace(object_stiffness=obj.stiffness.copy(),
                                                           object_curvature=obj.curvature.copy())
    outcome = _empty(task.Outcome, n, _OUTCOME_DTYPES)._replace(state=_empty(TaskState, n, _STATE_DTYPES))
    out = Outputs(np.empty(n), solve, np.empty(n, bool), np.empty(n, bool), outcome,
                  np.empty((n, 1 if vscale is None else 2), np.float32))
    ev_cache, ev_valid = new_cache(n) if cache is None else cache
    args = (action, state.command, state.eq, obj.stiffness, obj.curvature, state.thresholds, state.task,
            _loop_params(params.task), 0.0 if vscale is None else float(vscale), params.actuator, params.solver,
            *_table(params), ev_cache, ev_valid, out)
    batched.run_loop(_loop_serial, _loop_parallel, args, n, parallel, threads)
    # the previous state where the solve failed (host arrays: looking whether any did costs no device sync)
    new_eq = task._keep_where(out.failed, state.eq, solve, params.ops) if out.failed.any() else solve
    new = task.EnvState(out.command, new_eq, obj, state.thresholds, outcome.state)
    return task.Step(new, out.obs, outcome.reward, outcome.terminated, outcome.truncated, solve, outcome,
                     out.clipped, out.failed)


# ---------------------------------------------------------------------------------------------
# The single env's step: one compiled call on the env's state as one float array
# ---------------------------------------------------------------------------------------------

_X_EQ, _X_THRESHOLDS, _X_TASK = 1, 21, 24
STATE_SIZE = 28
"""Floats of the single env's packed state: the command, the :class:`Equilibrium`'s 20 fields, the
:class:`Thresholds`' 3, the :class:`TaskState`'s 4 (flags as 0/1)."""


def _kinds(values) -> str:
    """Each number's kind, as the compiled single step reads it from the packed params: ``i`` an integer, ``b`` a
    flag, ``f`` a float (``None``, and the strings the loop does not read, are packed as 0.0)."""
    return "".join("b" if type(v) is bool else "i" if type(v) is int else "f" for v in values)


def _pack_params(params: task.EnvParams) -> np.ndarray:
    """The numbers the single step reads, packed in one float array: the task's (:func:`_loop_params`), the actuator's,
    the solver's (:meth:`SolverOptions.as_tuple`), the free table's spacing and the volume scale (0.0: none). Integers
    and flags are exact in a float; :func:`_make_unpack`'s function reads them back as such."""
    t = [0.0 if v is None else float(v) for v in _loop_params(params.task)]
    table_spacing = _table(params)[1]
    vs = 0.0 if params.volume_scale is None else float(params.volume_scale)
    return np.array(t + [float(v) for v in params.actuator] + [float(v) for v in params.solver] + [table_spacing, vs])


def _make_unpack(params_type: type, task_kinds: str):
    """The compiled function that reads :func:`_pack_params`' array back as the records the loop takes: ``(task
    params, actuator numbers, solver options, table spacing, volume scale)``, each number of its kind (``task_kinds``:
    :func:`_kinds` of the task's params; the actuator's are floats, the solver's :meth:`SolverOptions.as_tuple`'s).

    Why: numba types a tuple argument number by number on every call, about 20 ns each, 0.7 us for these 37 (a
    third of the single step's call); an array is typed at once. The function is generated (one line per field), as
    numba cannot build a record of mixed types in a loop."""
    opt_kinds = _kinds(_solver.SolverOptions().as_tuple())
    n_t, n_a = len(task_kinds), len(_solver.ActuatorNumbers._fields)

    def read(i: int, kind: str) -> str:
        return {"f": f"c[{i}]", "i": f"np.int64(c[{i}])", "b": f"c[{i}] != 0.0"}[kind]

    t = ", ".join(read(i, k) for i, k in enumerate(task_kinds))
    a = ", ".join(read(n_t + i, "f") for i in range(n_a))
    o = ", ".join(read(n_t + n_a + i, k) for i, k in enumerate(opt_kinds))
    end = n_t + n_a + len(opt_kinds)
    source = (f"def unpack(c):\n    return (T({t}), A({a}), ({o},), c[{end}], c[{end + 1}])\n")
    names = {"T": params_type, "A": _solver.ActuatorNumbers, "np": np}
    exec(compile(source, f"<pneunet_env.fused unpack {params_type.__name__}>", "exec"), names)
    return numba.njit(names["unpack"], nogil=True)


def _make_single(stamp: int):
    def single(x, a, c, table, cache, valid, f, n, b, obs):
        # The fused loop at N = 1 (the vector env's own code, compiled for this call), on views of the packed state x
        # (STATE_SIZE floats, updated in place) and of scratch arrays for what it writes (f: floats, n: integers,
        # b: flags, obs: (1, 1 or 2); see the comment above SingleStep). c: the params' numbers (_pack_params), read
        # back as records by the global _unpack (_make_unpack: the default task's, or another section's).
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        tp, prm, opts, spacing, volume_scale = _unpack(c)
        b[17], b[18], b[19] = x[7] != 0.0, x[25] != 0.0, x[26] != 0.0  # the state's flags, as the loop reads them
        flag = b[17:18]  # (in_contact; b[17:20], n[7] and f[13] are input slots: no allocation in the call)
        eq = Equilibrium(x[1:2], x[2:3], x[3:4], x[4:5], x[5:6], x[6:7], flag, x[8:9], x[9:10], x[10:11], x[11:12],
                         flag, n[0:1], n[0:1], flag, n[0:1], x[17:18], x[18:19], n[0:1], n[0:1])
        n[7] = np.int64(x[24])
        f[13] = a
        state = TaskState(n[7:8], b[18:19], b[19:20], x[27:28])
        solve = Equilibrium(f[0:1], f[1:2], f[2:3], f[3:4], f[4:5], f[5:6], b[0:1], f[6:7], f[7:8], f[8:9], f[9:10],
                            b[1:2], n[1:2], n[2:3], b[2:3], n[3:4], x[17:18], x[18:19], n[4:5], n[5:6])  # the object's
        outcome = task.Outcome(TaskState(n[6:7], b[3:4], b[4:5], f[10:11]), b[5:6], b[6:7], b[7:8], b[8:9], b[9:10],
                               b[10:11], b[11:12], b[12:13], b[13:14], b[14:15], f[11:12])
        out = Outputs(f[12:13], solve, b[15:16], b[16:17], outcome, obs)
        _loop_single(f[13:14], x[0:1], eq, x[17:18], x[18:19], Thresholds(x[21:22], x[22:23], x[23:24]), state,
                     tp, volume_scale, prm, opts, table, spacing, cache, valid, out)
        e, ts = solve, outcome.state
        x[0] = out.command[0]
        if not out.failed[0]:  # the new equilibrium (a failed step keeps the previous one)
            x[1], x[2], x[3], x[4], x[5] = e.pressure[0], e.curvature[0], e.side_strain[0], e.top_strain[0], \
                e.contact_force[0]
            x[6], x[7], x[8] = e.indentation[0], 1.0 if e.in_contact[0] else 0.0, e.volume_change[0]
            x[9], x[10], x[11] = e.energy[0], e.gradient_norm[0], e.min_eigenvalue[0]
            x[12], x[13], x[14] = 1.0 if e.converged[0] else 0.0, e.iterations[0], e.substeps[0]
            x[15], x[16], x[17], x[18] = 1.0 if e.snapped[0] else 0.0, e.status[0], e.object_stiffness[0], \
                e.object_curvature[0]
            x[19], x[20] = e.evaluations[0], e.backtracks[0]
        x[24], x[25] = ts.step[0], 1.0 if ts.damaged[0] else 0.0
        x[26], x[27] = 1.0 if ts.dropped[0] else 0.0, ts.peak_force[0]
        # the new state's numbers that a lean info reads, beside the step's (one list from f and one from b, in Python)
        f[14], f[15], f[16], f[17] = x[1], x[2], x[5], x[6]
        b[17] = x[7] != 0.0
        # nothing returned: Python reads f, n, b, obs and x (see SingleStep), a list from each array in one call

    return single


if HAVE_NUMBA:
    _TASK_KINDS = _kinds(_loop_params(task.TaskParams.from_config(EnvConfig())))
    _unpack = _make_unpack(task.TaskParams, _TASK_KINDS)  # the default task's (read by _single as a global)
    _single = _jit.njit_cached(_make_single, _SOURCES)
_SINGLES: dict[tuple[type, str], Any] = {}
"""The compiled single step of a task section with more fields (:func:`pneunet_env.task.task_params_type`), by its
params type and their kinds: compiled when first used, not cached on disk."""


def _single_for(params_type: type, task_kinds: str):
    """The compiled single step for a task's params of this type (and kinds: :func:`_kinds`): the default task's,
    cached on disk, or one compiled for another task section, with its own unpacking of the params."""
    if params_type is task.TaskParams:
        return _single
    key = (params_type, task_kinds)
    if key not in _SINGLES:
        fn = _make_single(0)
        # the same code, reading this section's unpacking as its global _unpack
        names = {**fn.__globals__, "_unpack": _make_unpack(params_type, task_kinds)}
        fn = types.FunctionType(fn.__code__, names, fn.__name__, fn.__defaults__, fn.__closure__)
        _SINGLES[key] = numba.njit(fn, nogil=True)
    return _SINGLES[key]


# The single step's scratch arrays (what its compiled call writes, by index):
# * f (18 floats): the solve's pressure, curvature, side_strain, top_strain, contact_force, indentation (0-5),
#   volume_change, energy, gradient_norm, min_eigenvalue (6-9); the outcome's peak_force (10), reward (11); the new
#   command (12); the action (13, an input); the new state's pressure, curvature, contact_force, indentation (14-17).
# * n (8 integers): unused (0); the solve's iterations, substeps, status, evaluations, backtracks (1-5); the outcome's
#   step (6); the state's step (7, an input).
# * b (20 flags): the solve's in_contact, converged, snapped (0-2); the outcome's damaged, dropped (3, 4), in_hold,
#   overstressed, crushed, damage_event, slipping, drop_event, held, terminated, truncated, success (5-14); failed
#   (15), clipped (16); the state's in_contact, damaged, dropped (17-19: inputs; 17 is then the new state's).
# * x (STATE_SIZE floats, the state, updated in place): the command (0), the equilibrium's 20 fields (1-20), the
#   thresholds' 3 (21-23), the task state's 4 (24-27; flags as 0/1).


class SingleStep:
    """:func:`pneunet_env.task.step` for one env with the pneu-net's contact, as one compiled call (numba): the same
    :class:`~pneunet_env.task.Step`, bit for bit without the free table (see the module), built from the call's
    numbers (see the module for the work counters, which the evaluation cache lowers). Keeps the env's state packed in
    one float array (and the cache) between calls; a state it did not return itself (a reset's, or one set by hand)
    is packed anew, with the cache emptied.

    Two ways to call it: ``single(state, action)`` returns the :class:`~pneunet_env.task.Step`;
    :meth:`step_lean` steps the state it holds and returns only what a lean ``env.step`` returns (no record is built:
    :meth:`state` builds the state's record when it is asked for).
    """

    def __init__(self, params: task.EnvParams) -> None:
        if not HAVE_FUSED:
            raise RuntimeError("the compiled single step needs numba (pip install pneunet-env[fast])")
        # the numbers, packed in one array (the strings and the namespace, read at reset, become 0.0)
        self._params = _pack_params(params)
        self._key = (type(params.task), _kinds(_loop_params(params.task)))
        self._call = _single_for(*self._key)
        self._table = _table(params)[0]
        self._volume = params.volume_scale is not None
        self._mu, self._w = float(params.task.shear_modulus_kpa), float(params.task.width_mm)
        self._x = np.zeros(STATE_SIZE)
        self._c, self._valid = new_cache(1)
        # the loop's outputs at N = 1 (floats, integers, flags, the observation; layout: the comment above)
        self._f, self._n, self._b = np.empty(18), np.empty(8, np.int64), np.empty(20, bool)
        self._obs = np.empty(2 if self._volume else 1, np.float32)  # the observation (the loop writes a (1, k) view)
        self._obs_rows = self._obs.reshape(1, -1)
        self._state: task.EnvState | None = None  # the record of the state self._x holds (None: not built)
        self._obj: Any = None  # the object and thresholds of the state self._x holds
        self._thresholds: Thresholds | None = None
        self._entry = self._first_call  # the compiled call (see _entry_point), found at the first step

    def _first_call(self, *args) -> None:
        """The first step's call: through numba's dispatcher, which compiles the step for these arrays' types (or
        loads it from the disk cache), then the entry point (:meth:`_entry_point`) for every later step. An env made
        and never stepped compiles nothing."""
        self._call(*args)
        self._entry = self._entry_point()

    def _entry_point(self):
        """The compiled call for the types of this instance's own arrays (compiled already, by the first step):
        called directly, without the dispatcher's typing of its ten arguments on every call (0.6-1.0 us of a 7 us
        step). Safe only because its arguments are always these arrays (their types fixed until a copy or an
        unpickling, which ask again) and a float; a test checks that it is the dispatcher's own compiled function
        for them (``Dispatcher.compile`` gives the overload's entry point)."""
        import numba

        if not hasattr(self._call, "compile"):  # numba's own NUMBA_DISABLE_JIT=1: njit gave the Python function
            return self._call
        args = (self._x, 0.0, self._params, self._table, self._c, self._valid, self._f, self._n, self._b,
                self._obs_rows)
        return self._call.compile(tuple(numba.typeof(a) for a in args))

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the compiled function (found again by the params' type on unpickling) and the
        observation's view."""
        state = self.__dict__.copy()
        state["_call"] = state["_obs_rows"] = state["_entry"] = None  # (the view is made again: a copy would not be
        return state                                                   # one; the entry point by the arrays' types)

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._call = _single_for(*self._key)
        self._obs_rows = self._obs.reshape(1, -1)
        self._entry = self._first_call

    def __copy__(self) -> SingleStep:
        """A copy with its own packed state, cache and scratch arrays (the records, immutable, are shared)."""
        new = object.__new__(SingleStep)
        new.__dict__.update(self.__dict__)
        for name in ("_x", "_c", "_valid", "_f", "_n", "_b", "_obs"):
            setattr(new, name, getattr(self, name).copy())
        new._obs_rows = new._obs.reshape(1, -1)
        new._entry = new._first_call  # (not the original's: a bound method would step the original's arrays' owner)
        return new

    def load(self, state: task.EnvState) -> None:
        """Hold ``state`` (packed), with the cache emptied, unless it is the record of the state already held."""
        if state is self._state:
            return
        x = self._x
        x[0] = state.command
        x[_X_EQ:_X_THRESHOLDS] = [float(v) for v in state.eq]
        x[_X_THRESHOLDS:_X_TASK] = [float(v) for v in state.thresholds]
        x[_X_TASK:] = [float(v) for v in state.task]
        self._valid[0] = False
        self._state, self._obj, self._thresholds = state, state.obj, state.thresholds

    def state(self) -> task.EnvState:
        """The record of the state held (built from the packed numbers once, after a :meth:`step_lean`)."""
        if self._state is None:
            x = self._x.tolist()
            eq = Equilibrium(x[1], x[2], x[3], x[4], x[5], x[6], x[7] != 0.0, x[8], x[9], x[10], x[11], x[12] != 0.0,
                             int(x[13]), int(x[14]), x[15] != 0.0, int(x[16]), x[17], x[18], int(x[19]), int(x[20]))
            ts = TaskState(int(x[24]), x[25] != 0.0, x[26] != 0.0, x[27])
            self._state = task.EnvState(x[0], eq, self._obj, self._thresholds, ts)
        return self._state

    def _advance(self, action: float) -> None:
        """The compiled step of the state held, in place (``action``: a float, checked here)."""
        a = action if type(action) is float and math.isfinite(action) else check_action(action)  # (it names a bad one)
        # forgotten first: a Ctrl-C is raised as the call returns, and the record held would then be a step behind
        self._state = None
        self._entry(self._x, a, self._params, self._table, self._c, self._valid, self._f, self._n, self._b,
                    self._obs_rows)

    def __call__(self, state: task.EnvState, action: float) -> task.Step:
        """One step from ``state`` with ``action`` (a float; NaN and inf raise ``ValueError``, as
        :func:`~pneunet_env.task.update_pressure` does)."""
        self.load(state)
        self._advance(action)
        f, n, b = self._f.tolist(), self._n.tolist(), self._b.tolist()
        x = self._x
        solve = Equilibrium(f[0], f[1], f[2], f[3], f[4], f[5], b[0], f[6], f[7], f[8], f[9], b[1], n[1], n[2], b[2],
                            n[3], float(x[17]), float(x[18]), n[4], n[5])
        ts = TaskState(n[6], b[3], b[4], f[10])
        outcome = task.Outcome(ts, *b[5:15], f[11])
        failed = b[15]
        # the new state's record: the solve's (the previous state's equilibrium where it failed)
        self._state = new = task.EnvState(f[12], state.eq if failed else solve, state.obj, state.thresholds, ts)
        return task.Step(new, self._obs.copy(), outcome.reward, outcome.terminated, outcome.truncated, solve,
                         outcome, b[16], failed)

    def step_lean(self, action: float) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One step of the state held (:meth:`load` it first): ``(obs, reward, terminated, truncated, info)`` as a
        single env with ``info_level="lean"`` returns them (:func:`pneunet_env.info.lean_info`; ``is_success`` added
        on an episode's last step), the same values as from :meth:`__call__`'s record, without building one."""
        self._advance(action)
        f, b = self._f.tolist(), self._b.tolist()
        terminated, truncated = b[12], b[13]
        info = lean_info(f[14], f[15], f[16], f[17], b[17], self._n.item(6), b[3], b[4], b[2], b[1], b[15], b[16],
                         b[5], b[6], b[7], b[9], b[11], self._mu, self._w)
        if terminated or truncated:
            info["is_success"] = b[14]
        return self._obs.copy(), f[11], terminated, truncated, info

