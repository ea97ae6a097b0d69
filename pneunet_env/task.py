"""The grasping task as pure functions (gymnax style): the params, the state, the rules, the step and the reset.

Everything here is a plain function of records and of :class:`EnvParams`; nothing holds state. **One step**,
:func:`step`, takes an :class:`EnvState` and an action to the next :class:`EnvState`, observation, reward and episode
flags: the pressure (or jaw) update, the contact, the rules and the observation. Every environment is a thin shell
around it: :class:`pneunet_env.envs.grasp.PneuNetGraspEnv` calls it on scalars,
:class:`pneunet_env.envs.grasp_vector.PneuNetGraspVectorEnv` on ``(N,)`` arrays or tensors (with :func:`autoreset`
for the episodes that end), and :class:`pneunet_env.envs.rigid.RigidGraspEnv` with a rigid jaw. Only the contact
differs, and it is pluggable: a function ``contact(kappa~, e_s, p0, p1, obj, params) -> Equilibrium``
(:func:`newton_contact` and :func:`newton_contact_batch` solve the pneu-net's quasi-static equilibrium; the jaw's is
kinematic).

**One array path.** The array namespace (:class:`pneunet_env.physics.xp.Ops`: Python scalars, numpy or torch) is
chosen once, when the env builds its :class:`EnvParams`, and carried in :attr:`TaskParams.ops`; no function of the
step tests the type of its input.

The task's other concerns have modules of their own: the objects and their thresholds
(:mod:`pneunet_env.task_objects`), the action (:mod:`pneunet_env.actions`) and the info (:mod:`pneunet_env.info`).
Their public names are importable from here too.

**Episode.** An episode is one grasp of one object, ``squeeze_steps + hold_steps`` steps long.

* *Squeeze phase* (steps ``1 .. squeeze_steps``): the object rests on its support; the actuator
  closes on it as the policy raises the pressure. Damage is checked; slip is not.
* *Hold phase* (steps ``squeeze_steps + 1 .. squeeze_steps + hold_steps``): the object is lifted and
  held; the grip must carry its weight by friction at every step. Damage is still checked.

**Damage** (irreversible): the contact traction exceeds the object's failure traction (*overstressed*), or the
indentation exceeds its crush indentation (*crushed*), both set by the config's ``damage_rule``
(:func:`~pneunet_env.task_objects.object_thresholds`). **Slip** (hold phase only): friction cannot carry the
object's weight, ``grip_faces mu_f F L_c b < m g`` (``hold_rule: weight``; ``PneuNetGrasp-v0``'s ``slab`` rule:
``F < rho g H / (grip_faces mu_f)``); the object is dropped. See ``docs/env.md`` for the physics of each threshold.

**Reward** (per step; see :func:`make_rules`):

=========================================  =====================
event                                      reward
=========================================  =====================
a hold-phase step, held (no slip, intact)  ``+reward_hold``
the episode's end reached, held, intact    ``+reward_success``
damage (the step it happens)               ``-penalty_damage``
slip / drop (the step it happens)          ``-penalty_slip``
=========================================  =====================

Damage and a drop end the episode (``terminated``) unless ``terminate_on_damage`` /
``terminate_on_slip`` is false. The end of the hold phase is a time limit: ``truncated``, never
``terminated``. A solve that fails to converge keeps the previous state and ends the episode with
``truncated`` and ``info["solver_failed"]``.

Units: everything here is dimensionless (pressure and traction ``/mu``, lengths ``/w``) except the
object's sampled properties and the ``*_kpa``/``*_mm``/``*_per_m`` entries of :func:`build_info`.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.actions import batch_actions, check_action, single_action, update_pressure
from pneunet_env.config import EnvConfig, TaskConfig
from pneunet_env.info import FULL_KEYS, INFO_LEVELS, LEAN_KEYS, OBJECT_KEYS, build_info, info_keys, object_info
from pneunet_env.objects import GraspObject
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.batched import solve_batch
from pneunet_env.physics.free_table import free_table
from pneunet_env.physics.solver import (
    ActuatorNumbers,
    Equilibrium,
    equilibrium,
    params_tuple,
    solve_equilibrium,
    step_state,
)
from pneunet_env.physics.xp import SCALAR, Ops
from pneunet_env.records import fresh_arrays, leaves, merge, take  # noqa: F401  (re-exported)
from pneunet_env.task_objects import (
    CATALOGUE_DRAWS,
    PIN_KEYS,
    Thresholds,
    class_name,
    class_names,
    contact_length_mm,
    draw_count,
    object_from_uniforms,
    object_thresholds,
    sample_object,
    warn_if_beyond_convergence,
)

__all__ = [
    "TaskParams",
    "task_params_type",
    "EnvParams",
    "EnvState",
    "Step",
    "TaskState",
    "Touch",
    "Outcome",
    "Contact",
    "make_rules",
    "rules_for",
    "initial_state",
    "transition",
    "observation",
    "newton_contact",
    "newton_contact_batch",
    "torch_contact_batch",
    "free_volume_change",
    "reset_state",
    "step",
    "merge",
    "leaves",
    "take",
    "fresh_arrays",
    "autoreset",
    # re-exported from pneunet_env.task_objects, pneunet_env.actions and pneunet_env.info
    "PIN_KEYS", "CATALOGUE_DRAWS", "Thresholds", "sample_object", "object_from_uniforms", "object_thresholds",
    "contact_length_mm", "class_names", "class_name", "draw_count", "warn_if_beyond_convergence", "check_action",
    "single_action", "batch_actions", "update_pressure", "INFO_LEVELS", "LEAN_KEYS", "OBJECT_KEYS", "FULL_KEYS",
    "info_keys", "build_info", "object_info",
]


# ---------------------------------------------------------------------------------------------
# The params: every field of the config's task section, the dimensionless numbers and the namespace
# ---------------------------------------------------------------------------------------------

DERIVED_FIELDS = ("pressure_max", "pressure_step", "width_mm", "shear_modulus_kpa", "depth_mm", "finger_width_mm",
                  "finger_length_mm", "ops")
"""The fields of :class:`TaskParams` after the task section's: ``pressure_max`` (``p~_max = p_max / mu``; a rigid
jaw's travel, mm), ``pressure_step`` (``p~`` change per step at ``|action| = 1``), the scales ``width_mm`` (``w``),
``shear_modulus_kpa`` (``mu``) and ``depth_mm`` (``t``), the finger's width and length in mm (the hold rule's
contact), and ``ops`` (the array namespace, default :data:`~pneunet_env.physics.xp.SCALAR`)."""


class _TaskParamsMethods:
    __slots__ = ()

    @classmethod
    def from_config(cls, config: EnvConfig, ops: Ops = SCALAR):
        """From the config's ``task`` section by field name, with the pressures made dimensionless, the scales and
        the array namespace ``ops`` (a config whose task section has more fields gets a params type that has
        them too, :func:`task_params_type`)."""
        a, tc = config.actuator, config.task
        typ = task_params_type(type(tc))
        return typ(**{f.name: getattr(tc, f.name) for f in dataclasses.fields(tc)},
                   pressure_max=config.pressure_max, pressure_step=config.pressure_step, width_mm=a.width_mm,
                   shear_modulus_kpa=a.shear_modulus_kpa, depth_mm=a.depth_mm, finger_width_mm=a.finger_width_mm,
                   finger_length_mm=a.length_mm, ops=ops)

    @property
    def episode_steps(self) -> int:
        return self.squeeze_steps + self.hold_steps


@functools.cache
def task_params_type(section: type = TaskConfig) -> type:
    """The params record of a task section (a dataclass such as :class:`~pneunet_env.config.TaskConfig`): a
    ``NamedTuple`` with one field per field of the section, in order, then :data:`DERIVED_FIELDS`. So a new config
    field reaches the rules (:func:`make_rules`, numba's compiled ones too) with no other edit."""
    names = [f.name for f in dataclasses.fields(section)] + list(DERIVED_FIELDS)
    base = collections.namedtuple("TaskParams", names, defaults=(SCALAR,))
    typ = type("TaskParams", (base, _TaskParamsMethods), {"__slots__": (), "__module__": __name__, "__doc__": (
        f"The task's numbers, built once from an :class:`~pneunet_env.config.EnvConfig` (:meth:`from_config`): "
        f"every field of :class:`~{section.__module__}.{section.__qualname__}` by name, then the derived "
        f":data:`DERIVED_FIELDS`.")})
    if section is not TaskConfig:
        typ.__qualname__ = f"TaskParams[{section.__qualname__}]"
    return typ


TaskParams = task_params_type(TaskConfig)


# ---------------------------------------------------------------------------------------------
# Damage, slip, reward, episode end
# ---------------------------------------------------------------------------------------------


class TaskState(NamedTuple):
    """What the task remembers between steps (beyond the pressure and the equilibrium)."""

    step: Any  # steps taken
    damaged: Any  # sticky
    dropped: Any  # sticky: slipped in the hold phase
    peak_force: Any  # largest F~ so far


def initial_state(ops: Ops = SCALAR, like=None) -> TaskState:
    """The task state at ``reset`` on the namespace ``ops``: Python scalars (one record, immutable, shared by every
    single env's reset), or arrays of ``like``'s shape (and device)."""
    if ops is SCALAR:
        return _SCALAR_START
    return TaskState(ops.full_like(like, 0, "int"), ops.full_like(like, False, "bool"),
                     ops.full_like(like, False, "bool"), ops.full_like(like, 0.0, "float"))


_SCALAR_START = TaskState(0, False, False, 0.0)
"""The task state at reset of one env (``SCALAR.full_like``'s values: an int, two bools, a float)."""


class Touch(NamedTuple):
    """What the rules read of an equilibrium (an :class:`Equilibrium` has these fields too)."""

    contact_force: Any  # F~
    indentation: Any  # delta~
    in_contact: Any


class Outcome(NamedTuple):
    """The result of one step's rules (all elementwise)."""

    state: TaskState  # the new task state
    in_hold: Any  # this step is in the hold phase
    overstressed: Any  # F > failure traction now
    crushed: Any  # delta > crush indentation now (in contact)
    damage_event: Any  # damage happened on this step
    slipping: Any  # hold phase and F below the grip traction now
    drop_event: Any  # the first slip of the episode happened on this step
    held: Any  # a hold-phase step with the object held and intact
    terminated: Any
    truncated: Any
    success: Any  # the episode ended at its time limit with the object held and intact
    reward: Any


def make_rules(number, maximum, jit=None):
    """Build the task's rules from two operations: written once, instantiated on Python scalars (one env), numpy
    and torch arrays (:func:`rules_for`), and compiled by numba for the fused vector step (:mod:`pneunet_env.fused`),
    the way :func:`pneunet_env.physics.mechanics.make_terms` builds the energy.

    ``number(flag)`` makes a flag a float for the reward; ``maximum(a, b)`` is the elementwise maximum; ``jit``
    decorates the built function (``numba.njit``). Returns ``rules(task, eq, thresholds, failed, params) ->
    Outcome``: the :class:`TaskState` before the step, the equilibrium reached (an :class:`Equilibrium`, or any
    record with :class:`Touch`'s fields; the previous one where the solve failed), the object's :class:`Thresholds`,
    whether the solve failed (the state was kept: the episode truncates) and the :class:`TaskParams` (any record with
    its fields; the fused step passes it with ``ops=None``). A new reward term is a field of the config's task section
    (it reaches ``params`` by name) and a line here.
    """

    def rules(task, eq, thresholds, failed, params):
        # Written with the operators & | ^ (not np.logical_*): they act elementwise on bool arrays and tensors and
        # on Python/numpy/numba bools alike, and cost far less than a ufunc call on scalars. ``x ^ True`` is "not x".
        F = eq.contact_force
        step = task.step + 1
        in_hold = step > params.squeeze_steps
        end = step >= params.squeeze_steps + params.hold_steps
        overstressed = F > thresholds.failure_traction
        crushed = eq.in_contact & (eq.indentation > thresholds.crush_indentation)
        damage_now = overstressed | crushed
        damage_event = damage_now & (task.damaged ^ True)
        damaged = task.damaged | damage_now
        slipping = in_hold & (F < thresholds.grip_traction)
        drop_event = slipping & (task.dropped ^ True)
        dropped = task.dropped | slipping
        intact = (damaged | dropped | failed) ^ True
        held = in_hold & intact
        terminated = (damage_event & params.terminate_on_damage) | (drop_event & params.terminate_on_slip)
        truncated = (terminated ^ True) & (end | failed)
        success = end & intact
        reward = (params.reward_hold * number(held) + params.reward_success * number(success)
                  - params.penalty_damage * number(damage_event) - params.penalty_slip * number(drop_event))
        return Outcome(TaskState(step, damaged, dropped, maximum(task.peak_force, F)), in_hold, overstressed, crushed,
                       damage_event, slipping, drop_event, held, terminated, truncated, success, reward)

    return rules if jit is None else jit(rules)


def _same(x):
    return x


def _scalar_peak(a, b):
    # one environment: the same number as np.maximum gives (an np.float64), without a ufunc call
    return np.float64(b if b > a else a)


def _double(flag):
    return flag.double()


_NUMBER = {"scalar": _same, "numpy": _same, "torch": _double}
"""``number`` of :func:`make_rules` by namespace: a flag as the reward's float."""
_PEAK = {"scalar": _scalar_peak}
"""``maximum`` of :func:`make_rules` where it is not the namespace's."""
_RULES: dict[str, Callable] = {}


def rules_for(ops: Ops) -> Callable:
    """The rules (:func:`make_rules`) on the namespace ``ops``, built on first use."""
    if ops.name not in _RULES:
        _RULES[ops.name] = make_rules(_NUMBER[ops.name], _PEAK.get(ops.name, ops.maximum))
    return _RULES[ops.name]


def transition(state: TaskState, eq, thresholds: Thresholds, solver_failed, params: TaskParams) -> Outcome:
    """Apply the rules (:func:`make_rules`, on ``params.ops``) to the equilibrium ``eq`` reached by one step."""
    return rules_for(params.ops)(state, eq, thresholds, solver_failed, params)


# ---------------------------------------------------------------------------------------------
# Observation
# ---------------------------------------------------------------------------------------------


def observation(pressure, volume_change, params: TaskParams, volume_scale: float | None = None):
    """The observation, float32, shape ``pressure.shape + (1,)`` (or ``+ (2,)`` with a volume), on ``params.ops``.

    ``[p / p_max]``, and with ``volume_scale`` given ``[p / p_max, dV / volume_scale]`` (the chamber's
    volume change, which a flow sensor could measure; ``volume_scale`` is the free actuator's at ``p_max``).
    """
    xp = params.ops
    p = pressure / params.pressure_max
    return xp.to_float32(xp.stack([p] if volume_scale is None else [p, volume_change / volume_scale]))


# ---------------------------------------------------------------------------------------------
# The contact (pluggable), the params and the state
# ---------------------------------------------------------------------------------------------

Contact = Callable[..., Equilibrium]
"""``contact(kappa~, e_s, p0, p1, obj, params) -> Equilibrium``: the state reached from the equilibrium
``(kappa~, e_s)`` at command ``p0`` when the command becomes ``p1`` (a pressure for the pneu-net, a jaw closure for
a rigid gripper), against the object ``obj``; scalars for one env, ``(N,)`` arrays for a batch."""


def newton_contact(kappa, side_strain, p0, p1, obj: GraspObject, params: EnvParams) -> Equilibrium:
    """The pneu-net's quasi-static step for one env: the compiled continuation
    (:func:`pneunet_env.physics.solver.step_state`) from ``(kappa~, e_s)`` at ``p0`` to ``p1``, without the argument
    checks of :func:`~pneunet_env.physics.solver.solve_equilibrium` (the pressure comes from :func:`update_pressure`,
    the object was checked at reset): this is the hot path."""
    raw = step_state(kappa, side_strain, p0, p1, params.actuator, obj.stiffness, obj.curvature, params.solver)
    return equilibrium(p1, raw, params.actuator.chamber_height, obj.stiffness, obj.curvature)


def newton_contact_batch(kappa, side_strain, p0, p1, obj: GraspObject, params: EnvParams, backend: str = "auto",
                         parallel: bool | None = None, threads: int | None = None) -> Equilibrium:
    """The pneu-net's quasi-static step for ``(N,)`` envs (:func:`pneunet_env.physics.batched.solve_batch`)."""
    return solve_batch(kappa, side_strain, p0, p1, obj.stiffness, obj.curvature, params.actuator_params,
                       params.solver_options, backend=backend, validate=False, parallel=parallel, threads=threads)


def torch_contact_batch(kappa, side_strain, p0, p1, obj: GraspObject, params: EnvParams, compile: bool = False,
                        max_rounds: int | None = None) -> Equilibrium:
    """The pneu-net's quasi-static step for ``(N,)`` float64 tensors of one device: the masked solver on torch
    (:func:`pneunet_env.physics.batched.solve_batch_torch`), an :class:`Equilibrium` of tensors there."""
    from pneunet_env.physics.batched import solve_batch_torch

    active = params.ops.full_like(kappa, True, "bool")
    return solve_batch_torch(kappa, side_strain, p0, p1, obj.stiffness, obj.curvature, params.actuator,
                             params.solver, active, compile=compile, max_rounds=max_rounds)


def free_volume_change(config: EnvConfig) -> float:
    """The free actuator's chamber volume change ``(V1 - V0)/(w^2 t)`` at ``p_max`` (loaded from rest): the
    scale of the volume observation."""
    eq = solve_equilibrium(config.pressure_max, 0.0, 0.02, config.actuator_params, options=config.solver)
    if not eq.converged:  # pragma: no cover - the free actuator always converges at the defaults
        raise RuntimeError(f"the free actuator did not converge at p~={config.pressure_max}: {eq.message}")
    return eq.volume_change


class EnvParams(NamedTuple):
    """Everything a step needs that does not change within an episode: built once from the validated config.

    Attributes:
        task: the rules' numbers and the array namespace (:class:`TaskParams`); a rigid jaw's has the jaw's travel
            and step in place of the pressure's.
        actuator: the dimensionless actuator as the compiled solver takes it
            (:class:`~pneunet_env.physics.solver.ActuatorNumbers`).
        solver: :meth:`SolverOptions.as_tuple <pneunet_env.physics.solver.SolverOptions.as_tuple>`.
        actuator_params, solver_options: the same, as their validated objects.
        volume_scale: the free actuator's volume change at ``p_max`` with ``observe_volume``, else ``None``.
        free_table: the free actuator's path to ``p_max`` (:class:`~pneunet_env.physics.free_table.FreeTable`) where
            the solver's ``free_table`` is set and numba is installed, else ``None``: read by the compiled steps
            only (:mod:`pneunet_env.fused`).
    """

    task: TaskParams
    actuator: ActuatorNumbers
    solver: tuple
    actuator_params: Any
    solver_options: Any
    volume_scale: float | None
    free_table: Any = None

    @classmethod
    def from_config(cls, config: EnvConfig, ops: Ops = SCALAR) -> EnvParams:
        """The params of ``config``, on the array namespace ``ops`` (:data:`~pneunet_env.physics.xp.SCALAR`: one env;
        :data:`~pneunet_env.physics.xp.NUMPY` or :func:`~pneunet_env.physics.xp.torch_ops`: a batch)."""
        scale = free_volume_change(config) if config.task.observe_volume else None
        prm, opts = params_tuple(config.actuator_params), config.solver.as_tuple()
        table = free_table(prm, opts, config.pressure_max) if config.solver.free_table and HAVE_NUMBA else None
        return cls(TaskParams.from_config(config, ops), prm, opts, config.actuator_params, config.solver, scale, table)

    @property
    def ops(self) -> Ops:
        """The array namespace (``task.ops``)."""
        return self.task.ops


class EnvState(NamedTuple):
    """The whole state of one env (scalars) or of a batch (``(N,)`` arrays), as one record with named fields.

    Attributes:
        command: the controlled quantity, ``p~`` (or a jaw's closure in mm): what the action moves.
        eq: the quasi-static state reached (:class:`~pneunet_env.physics.solver.Equilibrium`).
        obj: the episode's object (:class:`~pneunet_env.objects.GraspObject`).
        thresholds: its damage and slip thresholds (:class:`Thresholds`).
        task: the rules' memory (:class:`TaskState`).
    """

    command: Any
    eq: Equilibrium
    obj: GraspObject
    thresholds: Thresholds
    task: TaskState


class Step(NamedTuple):
    """What :func:`step` returns: the new state, what the env hands out, and what its info is built from."""

    state: EnvState
    obs: Any
    reward: Any
    terminated: Any
    truncated: Any
    solve: Equilibrium  # the step's solve (its diagnostics), even where it failed and the state was kept
    outcome: Outcome
    action_clipped: Any
    solver_failed: Any


# ---------------------------------------------------------------------------------------------
# Reset and step
# ---------------------------------------------------------------------------------------------


def reset_state(obj: GraspObject, params: EnvParams, contact: Contact) -> EnvState:
    """The state at ``reset``: command 0, the actuator at rest (the equilibrium at ``p~ = 0``), the object's
    thresholds, a fresh task state. Scalars for one object, ``(N,)`` arrays for a batch (``params.ops``)."""
    ops = params.ops
    zero = ops.full_like(obj.stiffness, 0.0, "float")
    eq = contact(zero, zero, zero, zero, obj, params)
    return EnvState(zero * 1.0, eq, obj, object_thresholds(obj, params.task), initial_state(ops, obj.stiffness))


def _keep_where(failed, old: Equilibrium, new: Equilibrium, ops: Ops) -> Equilibrium:
    """``new``, with ``old``'s entries where the solve ``failed`` (the previous state is kept)."""
    return Equilibrium(*(ops.where(failed, a, b) for a, b in zip(old, new, strict=True)))


def step(state: EnvState, action, params: EnvParams, contact: Contact) -> Step:
    """One step of the task, pure: the same function for one env (scalars) and for a batch (``(N,)`` arrays).

    1. the command: ``clip(p + clip(a, -1, 1) dp_max, 0, p_max)`` (:func:`update_pressure`; NaN/inf raise);
    2. the contact: the quasi-static state at the new command (``contact``); where it did not converge, the
       previous state and command are kept and the step is flagged ``solver_failed`` (the episode truncates);
    3. the rules: damage, slip, reward, the episode's end (:func:`transition`);
    4. the observation (:func:`observation`).

    Args:
        state: the state before the step.
        action: one number per env (a float, or an ``(N,)`` array), nominally in ``[-1, 1]``.
        params: the env's :class:`EnvParams` (its ``ops`` is the namespace of ``state``).
        contact: the :data:`Contact` (the pneu-net's Newton solve, or a jaw's kinematics).
    """
    ops, tp = params.ops, params.task
    command, clipped = update_pressure(state.command, action, tp)
    prev = state.eq
    solve = contact(prev.curvature, prev.side_strain, prev.pressure, command, state.obj, params)
    failed = solve.converged ^ True
    eq = _keep_where(failed, prev, solve, ops)
    command = ops.where(failed, state.command, command)
    out = transition(state.task, eq, state.thresholds, failed, tp)
    obs = observation(command, eq.volume_change, tp, params.volume_scale)
    new = EnvState(command, eq, state.obj, state.thresholds, out.state)
    return Step(new, obs, out.reward, out.terminated, out.truncated, solve, out, clipped, failed)


def autoreset(state: EnvState, idx, obj: GraspObject, params: EnvParams, contact: Contact,
              own: frozenset[int] | None = None) -> EnvState:
    """``state`` with the envs ``idx`` reset on the objects ``obj`` (``(len(idx),)`` arrays).

    The randomness is passed in, as the objects drawn for those envs (the vector env draws them from each env's
    own stream: :func:`object_from_uniforms` on its uniforms), so this stays pure. ``own``: the arrays of ``state``
    that may be written in place (:func:`fresh_arrays`; see :func:`merge`); ``None``: a fresh state.
    """
    return merge(state, idx, reset_state(obj, params, contact), params.ops, own)
