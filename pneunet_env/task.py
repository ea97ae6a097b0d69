"""The grasping task as pure, numpy-vectorised functions (gymnax style): one place for the rules.

Everything here is a plain function of arrays (or scalars) and of :class:`TaskParams`; nothing holds
state. :class:`pneunet_env.envs.grasp.PneuNetGraspEnv` calls these functions on scalars, one environment at
a time; a batched environment calls the same functions on arrays of shape ``(N,)`` and gets the same
numbers, element by element. Only the equilibrium solve (:func:`pneunet_env.solve_equilibrium`) lies
between :func:`update_pressure` and :func:`transition`.

**Episode.** An episode is one grasp of one object, ``squeeze_steps + hold_steps`` steps long.

* *Squeeze phase* (steps ``1 .. squeeze_steps``): the object rests on its support; the actuator
  closes on it as the policy raises the pressure. Damage is checked; slip is not.
* *Hold phase* (steps ``squeeze_steps + 1 .. squeeze_steps + hold_steps``): the object is lifted and
  held; the grip must carry its weight by friction at every step. Damage is still checked.

**Damage** (irreversible): the contact traction exceeds the object's failure stress
(``F > sigma_f``, *overstressed*), or the indentation exceeds ``crush_fraction`` times the object's
thickness (``delta > crush_fraction H``, *crushed through*). **Slip** (hold phase only): friction
cannot carry the weight, ``F < rho g H / (grip_faces mu_f)``; the object is dropped.
See :func:`object_thresholds` and ``docs/env.md`` for the physics of each threshold.

**Reward** (per step; see :func:`transition`):

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

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.config import LOG_UNIFORM_FIELDS, RANGE_FIELDS, EnvConfig
from pneunet_env.objects import GraspObject
from pneunet_env.physics.solver import STATUS_MESSAGES

__all__ = [
    "TaskParams",
    "Thresholds",
    "TaskState",
    "Outcome",
    "PIN_KEYS",
    "sample_object",
    "object_from_uniforms",
    "SolvedState",
    "solved_state",
    "object_info",
    "object_thresholds",
    "check_action",
    "single_action",
    "update_pressure",
    "initial_state",
    "transition",
    "observation",
    "build_info",
]

PIN_KEYS = (
    "object_stiffness",
    "object_shear_modulus_kpa",
    "object_curvature",
    "object_curvature_per_m",
    "object_thickness_mm",
    "object_density_kg_m3",
    "object_failure_strain",
)
"""Keys of ``reset(options=...)`` that pin an object property (``object_stiffness`` is ``k~``,
``object_curvature`` is ``w kappa_obj``; the others are in the units their names say)."""


class TaskParams(NamedTuple):
    """The task's numbers, dimensionless where the model is (built once from an :class:`EnvConfig`)."""

    pressure_max: float  # p~_max = p_max / mu
    pressure_step: float  # p~ change per step at |action| = 1
    squeeze_steps: int
    hold_steps: int
    reward_hold: float
    reward_success: float
    penalty_damage: float
    penalty_slip: float
    terminate_on_damage: bool
    terminate_on_slip: bool
    crush_fraction: float
    friction_coefficient: float
    grip_faces: int
    gravity_m_s2: float
    width_mm: float  # w
    shear_modulus_kpa: float  # mu
    depth_mm: float  # t

    @classmethod
    def from_config(cls, config: EnvConfig) -> TaskParams:
        return cls(
            pressure_max=config.pressure_max,
            pressure_step=config.pressure_step,
            squeeze_steps=config.squeeze_steps,
            hold_steps=config.hold_steps,
            reward_hold=config.reward_hold,
            reward_success=config.reward_success,
            penalty_damage=config.penalty_damage,
            penalty_slip=config.penalty_slip,
            terminate_on_damage=config.terminate_on_damage,
            terminate_on_slip=config.terminate_on_slip,
            crush_fraction=config.crush_fraction,
            friction_coefficient=config.friction_coefficient,
            grip_faces=config.grip_faces,
            gravity_m_s2=config.gravity_m_s2,
            width_mm=config.width_mm,
            shear_modulus_kpa=config.shear_modulus_kpa,
            depth_mm=config.depth_mm,
        )

    @property
    def episode_steps(self) -> int:
        return self.squeeze_steps + self.hold_steps


# ---------------------------------------------------------------------------------------------
# The object and its thresholds
# ---------------------------------------------------------------------------------------------


def sample_object(
    rng: np.random.Generator,
    config: EnvConfig,
    size: int | tuple[int, ...] | None = None,
    pinned: Mapping[str, Any] | None = None,
) -> GraspObject:
    """Draw an object (``size=None``) or a batch from the config's ranges, then apply ``pinned``.

    The draws are ``rng.random((5,) + shape)``, mapped in the order of :data:`pneunet_env.config.RANGE_FIELDS`:
    shear modulus and density log-uniformly, thickness, curvature and failure strain uniformly. All five
    are drawn even when pinned or fixed, so pinning one property never changes the others.

    Args:
        rng: the environment's generator (``env.np_random``).
        config: the ranges.
        size: ``None`` for one object (float fields), else the batch shape.
        pinned: a subset of :data:`PIN_KEYS` (a value of ``None`` is ignored). ``object_stiffness``
            (``k~``) sets the shear modulus through eq. 3.2 with the object's (possibly pinned) size.

    Raises:
        ValueError: an unknown pin key, conflicting pins, or an invalid value (named).
    """
    shape: tuple[int, ...] = () if size is None else tuple(np.atleast_1d(size).astype(int))
    return object_from_uniforms(rng.random((len(RANGE_FIELDS),) + shape), config, pinned, batch=size is not None)


def object_from_uniforms(
    u: np.ndarray, config: EnvConfig, pinned: Mapping[str, Any] | None = None, batch: bool | None = None
) -> GraspObject:
    """The object of the uniform draws ``u`` (shape ``(5,)``: one object; ``(5,) + shape``: a batch).

    The pure half of :func:`sample_object` (which is ``object_from_uniforms(rng.random((5,) + shape), ...)``):
    a batched environment draws ``u`` from each sub-environment's own stream and maps them here.
    ``batch=None`` infers it from ``u.ndim``; ``batch=True`` with ``u.shape == (5,)`` gives 0-d array fields.
    A batch is computed with array operations (no loop over objects); its values equal the single-object
    ones to round-off (numpy's vectorised ``**`` may differ from the scalar one in the last bit).
    """
    u = np.asarray(u, dtype=float)
    if u.ndim == 0 or u.shape[0] != len(RANGE_FIELDS):
        raise ValueError(f"u must have shape ({len(RANGE_FIELDS)},) + batch shape, got {u.shape}")
    shape = u.shape[1:]
    if batch is None:
        batch = bool(shape)
    values: dict[str, Any] = {}
    for i, name in enumerate(RANGE_FIELDS):
        lo, hi = getattr(config, name)
        v = lo * (hi / lo) ** u[i] if name in LOG_UNIFORM_FIELDS else lo + (hi - lo) * u[i]
        values[name] = v if batch else float(v)
    pins = {k: v for k, v in (pinned or {}).items() if v is not None}
    unknown = sorted(set(pins) - set(PIN_KEYS))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; valid: {list(PIN_KEYS)}")
    if "object_stiffness" in pins and "object_shear_modulus_kpa" in pins:
        raise ValueError("reset options 'object_stiffness' and 'object_shear_modulus_kpa' conflict: pin one")
    if "object_curvature" in pins and "object_curvature_per_m" in pins:
        raise ValueError("reset options 'object_curvature' and 'object_curvature_per_m' conflict: pin one")
    for key in ("object_shear_modulus_kpa", "object_thickness_mm", "object_curvature_per_m",
                "object_density_kg_m3", "object_failure_strain"):
        if key in pins:
            values[key] = _pin(key, pins[key], shape, batch)
    if "object_curvature" in pins:
        values["object_curvature_per_m"] = _pin("object_curvature", pins["object_curvature"], shape, batch) / (
            config.width_mm * 1e-3
        )
    common = dict(
        thickness_mm=values["object_thickness_mm"],
        curvature_per_m=values["object_curvature_per_m"],
        density_kg_m3=values["object_density_kg_m3"],
        failure_strain=values["object_failure_strain"],
        scales=config.scales,
    )
    if not batch:
        if "object_stiffness" in pins:
            return GraspObject.from_stiffness(_pin("object_stiffness", pins["object_stiffness"], shape), **common)
        return GraspObject.from_material(values["object_shear_modulus_kpa"], **common)
    if "object_stiffness" in pins:
        return _batch_object(None, _pin("object_stiffness", pins["object_stiffness"], shape, batch), **common)
    return _batch_object(values["object_shear_modulus_kpa"], None, **common)


def _first_bad(name: str, value: np.ndarray, bad: np.ndarray, rule: str) -> None:
    if np.any(bad):
        v = value[np.nonzero(bad)] if value.ndim else value
        raise ValueError(f"object {name} {rule}, got {float(np.ravel(v)[0])!r}")


def _batch_object(shear_modulus_kpa, stiffness, thickness_mm, curvature_per_m, density_kg_m3, failure_strain,
                  scales) -> GraspObject:
    """:meth:`GraspObject.from_material` (``stiffness=None``) or :meth:`~GraspObject.from_stiffness` for a batch.

    The same checks and the same formulas (eq. 3.2 in :func:`pneunet_env.physics.units.object_stiffness_from_material`),
    as array operations instead of a loop over objects; ``ValueError`` names the first bad value.
    """
    given = shear_modulus_kpa if stiffness is None else stiffness
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (
        given, thickness_mm, curvature_per_m, density_kg_m3, failure_strain)))
    given, H_mm, kap, rho, eps = (np.array(a) for a in arrays)  # own, writable copies
    with np.errstate(all="ignore"):
        for name, v in (("density_kg_m3", rho), ("failure_strain", eps)):
            _first_bad(name, v, ~np.isfinite(v) | (v <= 0.0), "must be finite and > 0")
        for name, v in (("thickness_mm", H_mm), ("curvature_per_m", kap)):
            _first_bad(name, v, ~np.isfinite(v) | (v <= 0.0), "must be finite and > 0")
        label = "shear_modulus_kpa" if stiffness is None else "stiffness (k~)"
        _first_bad(label, given, ~np.isfinite(given) | (given < 0.0), "must be finite and >= 0")
        H = H_mm * 1e-3
        _first_bad("thickness_mm", H_mm, H * kap >= 1.0, "is not below the object's outer radius 1/kappa_obj")
        # eq. 3.2, in the operation order of units.object_stiffness_from_material (kPa/m, then k~)
        factor = 1.0 / (1.0 - H * kap) ** 2 - 1.0
        if stiffness is None:
            mu = given
            k = (2.0 * mu * kap * factor) * 1e-3 * scales.width_mm / scales.shear_modulus_kpa
        else:
            unit = (2.0 * 1.0 * kap * factor) * 1e-3 * scales.width_mm / scales.shear_modulus_kpa
            mu = given / unit
            k = given
        c = kap * scales.width_mm * 1e-3
        _first_bad("curvature_per_m", kap, c >= np.pi, "gives w kappa_obj >= pi")
    return GraspObject(
        shear_modulus_kpa=mu,
        thickness_mm=H_mm,
        curvature_per_m=kap,
        density_kg_m3=rho,
        failure_strain=eps,
        stiffness=k,
        curvature=c,
        thickness=H_mm / scales.width_mm,
    )


def _pin(key: str, value: Any, shape: tuple[int, ...], batch: bool = False):
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"reset option {key!r} must be a number, got {value!r}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"reset option {key!r} must be finite, got {value!r}")
    if np.any(a < 0.0):
        raise ValueError(f"reset option {key!r} must be >= 0, got {value!r}")
    if not batch:
        if a.ndim != 0:
            raise ValueError(f"reset option {key!r} must be a single number, got {value!r}")
        return float(a)
    try:
        return np.broadcast_to(a, shape).astype(float)
    except ValueError:
        raise ValueError(f"reset option {key!r} has shape {a.shape}, which does not fit the batch {shape}") from None


class Thresholds(NamedTuple):
    """An object's damage and slip thresholds, dimensionless (see :func:`object_thresholds`)."""

    failure_traction: float | np.ndarray  # F~_f: overstressed above it
    crush_indentation: float | np.ndarray  # delta~_c: crushed through above it
    grip_traction: float | np.ndarray  # F~_g: slips below it (hold phase)


def object_thresholds(obj: GraspObject, params: TaskParams) -> Thresholds:
    """The thresholds of ``obj`` in model units (traction ``/mu``, indentation ``/w``).

    * failure traction ``sigma_f / mu`` with ``sigma_f = eps_f E_obj = 3 eps_f mu_obj`` (incompressible);
    * crush indentation ``crush_fraction H / w``;
    * grip traction ``rho g H / (grip_faces mu_f) / mu``: two faces of a slab of thickness ``H`` pinched,
      friction carrying the weight per unit contact area ``rho g H``.
    """
    mu = params.shear_modulus_kpa
    failure = 3.0 * obj.failure_strain * obj.shear_modulus_kpa / mu
    crush = params.crush_fraction * obj.thickness
    weight_kpa = obj.density_kg_m3 * params.gravity_m_s2 * obj.thickness_mm * 1e-3 * 1e-3  # rho g H, Pa -> kPa
    grip = weight_kpa / (params.grip_faces * params.friction_coefficient) / mu
    return Thresholds(failure, crush, grip)


# ---------------------------------------------------------------------------------------------
# Action -> pressure
# ---------------------------------------------------------------------------------------------


def check_action(action):
    """``action`` as a float array (a Python float if 0-d); ``ValueError`` naming it unless all finite."""
    if isinstance(action, float):
        if not math.isfinite(action):
            raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
        return action
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be real numbers, got {action!r}") from None
    if a.ndim == 0:
        x = float(a)  # a Python float: much cheaper arithmetic than a 0-d array
        if not math.isfinite(x):
            raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
        return x
    if not np.isfinite(a).all():
        raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
    return a


def single_action(action) -> float:
    """A single env's action (shape ``(1,)``, or any one-number array-like) as a Python float.

    ``ValueError`` naming it if it is not one real number. (NaN and inf are caught by
    :func:`update_pressure`.) The common case, a float array of shape ``(1,)``, is read directly.
    """
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        return float(action[0])
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be a real number (shape (1,)), got {action!r}") from None
    if arr.size != 1:
        raise ValueError(f"action must hold one number (shape (1,)), got shape {arr.shape}: {action!r}")
    return arr.item()


def update_pressure(pressure, action, params: TaskParams):
    """The pressure after one action: ``clip(p + clip(a, -1, 1) dp_max, 0, p_max)``.

    Args:
        pressure: current ``p~`` (scalar or ``(N,)``).
        action: one number per environment (same shape as ``pressure``), nominally in ``[-1, 1]``.

    Returns:
        ``(new_pressure, action_clipped)``: ``action_clipped`` is true where ``|a| > 1`` was clipped.

    Raises:
        ValueError: a NaN or infinite action.
    """
    a = check_action(action)
    if isinstance(a, float) and not isinstance(pressure, np.ndarray):  # one env: plain floats, the same numbers
        clipped = a < -1.0 or a > 1.0
        a = min(max(a, -1.0), 1.0)
        return min(max(pressure + a * params.pressure_step, 0.0), params.pressure_max), clipped
    clipped = (a < -1.0) | (a > 1.0)
    a = np.minimum(np.maximum(a, -1.0), 1.0)
    p = np.minimum(np.maximum(pressure + a * params.pressure_step, 0.0), params.pressure_max)
    return p, clipped


# ---------------------------------------------------------------------------------------------
# The solve's result, as the rules read it
# ---------------------------------------------------------------------------------------------

_STATUS_BY_CODE = np.array(["not solved (inactive)"] + [STATUS_MESSAGES[c] for c in range(max(STATUS_MESSAGES) + 1)],
                           dtype=object)
"""Status messages by ``code + 1``: :data:`pneunet_env.physics.solver.STATUS_MESSAGES`, and -1 for an env not solved."""


class SolvedState(NamedTuple):
    """An equilibrium with the attributes of :class:`pneunet_env.physics.solver.Equilibrium` that the task reads.

    Scalars for one environment, ``(N,)`` arrays for a batch (``status`` then an object array of strings).
    Dimensionless: pressure and traction ``/mu``, lengths ``/w``; see :func:`solved_state`.
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


def solved_state(
    pressure, kappa, side_strain, volume_change, energy, gradient_norm, min_eigenvalue, iterations, substeps, snapped,
    status_code, object_stiffness, object_curvature, chamber_height: float,
) -> SolvedState:
    """A solve's raw result (:func:`pneunet_env.physics.solver.step_state`'s tuple, or a
    :class:`pneunet_env.physics.batched.BatchEquilibrium`'s columns) as a :class:`SolvedState`.

    The contact quantities follow :class:`pneunet_env.physics.solver.Equilibrium` exactly: top-wall strain
    ``e_m = d (1 + e_s) kappa~``; indentation ``delta~ = (kappa~ - kappa~_obj)/(kappa~ kappa~_obj)`` where
    ``kappa~ > kappa~_obj`` and there is an object (``k~ > 0``), else 0; traction ``F~ = k~ delta~``; in contact
    where also ``k~ > 0``.
    ``status_code`` indexes :data:`pneunet_env.physics.solver.STATUS_MESSAGES` (``<= 1``: converged; -1 in a batch: not
    solved).
    """
    if not isinstance(kappa, np.ndarray):  # one environment: plain Python arithmetic, the solver's own
        kc = object_curvature
        delta = (kappa - kc) / (kappa * kc) if (kappa > kc and object_stiffness > 0.0) else 0.0
        return SolvedState(
            pressure, kappa, side_strain, chamber_height * (1.0 + side_strain) * kappa, object_stiffness * delta,
            delta, object_stiffness > 0.0 and kappa > kc, volume_change, energy, gradient_norm, min_eigenvalue,
            status_code <= 1, iterations, substeps, snapped, STATUS_MESSAGES[status_code],
        )
    kc = object_curvature
    above = (kappa > kc) & (np.asarray(object_stiffness) > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(above, (kappa - kc) / (kappa * kc), 0.0)
    code = np.asarray(status_code)
    return SolvedState(
        pressure, kappa, side_strain, chamber_height * (1.0 + side_strain) * kappa, object_stiffness * delta, delta,
        above, volume_change, energy, gradient_norm, min_eigenvalue,
        (code <= 1) & (code >= 0), iterations, substeps, snapped, _STATUS_BY_CODE[code + 1],
    )


# ---------------------------------------------------------------------------------------------
# Damage, slip, reward, episode end
# ---------------------------------------------------------------------------------------------


_float64 = np.float64


class TaskState(NamedTuple):
    """What the task remembers between steps (beyond the pressure and the equilibrium)."""

    step: int | np.ndarray  # steps taken
    damaged: bool | np.ndarray  # sticky
    dropped: bool | np.ndarray  # sticky: slipped in the hold phase
    peak_force: float | np.ndarray  # largest F~ so far


def initial_state(shape: tuple[int, ...] | None = None) -> TaskState:
    """The task state at ``reset``: scalars (``shape=None``) or arrays of ``shape``."""
    if shape is None:
        return TaskState(0, False, False, 0.0)
    return TaskState(np.zeros(shape, int), np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape))


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


def transition(
    state: TaskState,
    contact_force,
    indentation,
    in_contact,
    thresholds: Thresholds,
    solver_failed,
    params: TaskParams,
) -> Outcome:
    """Apply the rules to the equilibrium reached by one step (the step count advances by one).

    Args:
        state: the task state before the step.
        contact_force: ``F~`` at the new equilibrium (the previous one if the solve failed).
        indentation: ``delta~`` there.
        in_contact: whether the actuator presses on the object.
        thresholds: the object's (:func:`object_thresholds`).
        solver_failed: the solve did not converge (the state was kept): ends the episode, ``truncated``.
        params: the task's numbers.
    """
    # Written with the operators & | ^ (not np.logical_*): they act elementwise on bool arrays and on
    # Python/numpy bools alike, and cost far less than a ufunc call on scalars. ``x ^ True`` is "not x".
    step = state.step + 1
    in_hold = step > params.squeeze_steps
    end = step >= params.squeeze_steps + params.hold_steps
    overstressed = contact_force > thresholds.failure_traction
    crushed = in_contact & (indentation > thresholds.crush_indentation)
    damage_now = overstressed | crushed
    damage_event = damage_now & (state.damaged ^ True)
    damaged = state.damaged | damage_now
    slipping = in_hold & (contact_force < thresholds.grip_traction)
    drop_event = slipping & (state.dropped ^ True)
    dropped = state.dropped | slipping
    intact = (damaged | dropped | solver_failed) ^ True
    held = in_hold & intact
    terminated = (damage_event & params.terminate_on_damage) | (drop_event & params.terminate_on_slip)
    truncated = (terminated ^ True) & (end | solver_failed)
    success = end & intact
    reward = (
        params.reward_hold * held
        + params.reward_success * success
        - params.penalty_damage * damage_event
        - params.penalty_slip * drop_event
    )
    if isinstance(contact_force, np.ndarray) or isinstance(state.peak_force, np.ndarray):
        peak = np.maximum(state.peak_force, contact_force)
    else:  # one environment: the same number (an np.float64, as np.maximum gives) without a ufunc call
        peak = _float64(contact_force if contact_force > state.peak_force else state.peak_force)
    return Outcome(
        TaskState(step, damaged, dropped, peak),
        in_hold, overstressed, crushed, damage_event, slipping, drop_event, held, terminated, truncated, success,
        reward,
    )


# ---------------------------------------------------------------------------------------------
# Observation and info
# ---------------------------------------------------------------------------------------------


def observation(pressure, volume_change, params: TaskParams, volume_scale: float | None = None) -> np.ndarray:
    """The observation, float32, shape ``pressure.shape + (1,)`` (or ``+ (2,)`` with a volume).

    ``[p / p_max]``, and with ``volume_scale`` given ``[p / p_max, dV / volume_scale]`` (the chamber's
    volume change, which a flow sensor could measure; ``volume_scale`` is the free actuator's at ``p_max``).
    """
    if not isinstance(pressure, np.ndarray):  # one environment
        if volume_scale is None:
            return np.array([pressure / params.pressure_max], dtype=np.float32)
        return np.array([pressure / params.pressure_max, volume_change / volume_scale], dtype=np.float32)
    p = np.asarray(pressure, dtype=np.float64) / params.pressure_max
    if volume_scale is None:
        return p[..., None].astype(np.float32)
    v = np.asarray(volume_change, dtype=np.float64) / volume_scale
    return np.stack(np.broadcast_arrays(p, v), axis=-1).astype(np.float32)


def _ratio(a, b):
    """``a / b``, and 0 where ``b`` is 0 (an object of zero modulus carries no traction)."""
    if not isinstance(a, np.ndarray) and not isinstance(b, np.ndarray):
        return a / b if b > 0.0 else 0.0
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    return np.divide(a, b, out=np.zeros(a.shape), where=b > 0.0)


def object_info(obj: GraspObject, thresholds: Thresholds, params: TaskParams) -> dict[str, Any]:
    """The entries of :func:`build_info` that depend only on the object (constant over an episode).

    An environment may compute them once per episode and pass them to :func:`build_info` as ``static``
    (the values are the same; only the work is saved).
    """
    mu, w = params.shear_modulus_kpa, params.width_mm
    return {
        "object_stiffness": obj.stiffness,
        "object_stiffness_kpa_per_mm": obj.stiffness * mu / w,
        "object_shear_modulus_kpa": obj.shear_modulus_kpa,
        "object_curvature": obj.curvature,
        "object_curvature_per_m": obj.curvature_per_m,
        "object_thickness_mm": obj.thickness_mm,
        "object_density_kg_m3": obj.density_kg_m3,
        "object_failure_strain": obj.failure_strain,
        "failure_traction_kpa": thresholds.failure_traction * mu,
        "crush_indentation_mm": thresholds.crush_indentation * w,
        "grip_traction_kpa": thresholds.grip_traction * mu,
    }


def build_info(
    eq,
    solve,
    obj: GraspObject,
    thresholds: Thresholds,
    state: TaskState,
    params: TaskParams,
    outcome: Outcome | None = None,
    action_clipped=False,
    solver_failed=False,
    static: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``info`` dict, from arrays (or scalars): dimensionless values and physical ones.

    Args:
        eq: the state's equilibrium: anything with the attributes of :class:`pneunet_env.physics.solver.Equilibrium`
            (``pressure, curvature, side_strain, top_strain, contact_force, indentation, in_contact,
            volume_change``), e.g. a :class:`SolvedState`.
        solve: the step's solve (its diagnostics: ``converged, iterations, substeps, snapped, gradient_norm,
            min_eigenvalue, status``); the same as ``eq`` unless the solve failed and the state was kept.
        obj, thresholds: the object and its thresholds.
        state: the task state after the step.
        outcome: the step's :class:`Outcome` (``None`` at reset).
        action_clipped, solver_failed: flags of the step.
        static: ``object_info(obj, thresholds, params)``, if the caller keeps it (computed here otherwise).
            Its values are shared between the calls that pass it: scalars (immutable) in the single env.

    Every array value is freshly computed (no buffer is reused between calls), unless ``static`` holds arrays.
    """
    mu, w = params.shear_modulus_kpa, params.width_mm
    F = eq.contact_force
    in_contact = eq.in_contact
    if isinstance(in_contact, np.ndarray):
        delta = np.where(in_contact, eq.indentation, 0.0)
        damage_ratio = np.maximum(
            _ratio(F, thresholds.failure_traction), _ratio(delta, thresholds.crush_indentation)
        )
    else:
        delta = eq.indentation if in_contact else 0.0
        damage_ratio = max(_ratio(F, thresholds.failure_traction), _ratio(delta, thresholds.crush_indentation))
    if static is None:
        static = object_info(obj, thresholds, params)
    info: dict[str, Any] = {
        "pressure": eq.pressure,
        "pressure_kpa": eq.pressure * mu,
        "curvature": eq.curvature,
        "curvature_per_m": eq.curvature / (w * 1e-3),
        "side_strain": eq.side_strain,
        "top_strain": eq.top_strain,
        "contact_force": F,
        "contact_force_kpa": F * mu,
        "indentation": delta,
        "indentation_mm": delta * w,
        "volume_change": eq.volume_change,
        "volume_change_mm3": eq.volume_change * w * w * params.depth_mm,
        "in_contact": in_contact,
        **static,
        "grip_ratio": _ratio(F, thresholds.grip_traction),
        "damage_ratio": damage_ratio,
        "peak_contact_force_kpa": state.peak_force * mu,
        "step": state.step,
        "damaged": state.damaged,
        "dropped": state.dropped,
        "snapped": solve.snapped,
        "solver_converged": solve.converged,
        "solver_failed": solver_failed,
        "solver_iterations": solve.iterations,
        "solver_substeps": solve.substeps,
        "solver_status": solve.status,
        "gradient_norm": solve.gradient_norm,
        "min_eigenvalue": solve.min_eigenvalue,
        "action_clipped": action_clipped,
        "in_hold": False if outcome is None else outcome.in_hold,
        "overstressed": False if outcome is None else outcome.overstressed,
        "crushed": False if outcome is None else outcome.crushed,
        "slipping": False if outcome is None else outcome.slipping,
        "held": False if outcome is None else outcome.held,
    }
    return info
