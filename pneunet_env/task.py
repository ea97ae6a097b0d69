"""The grasping task as pure, numpy-vectorised functions (gymnax style): one place for the rules.

Everything here is a plain function of arrays (or scalars) and of :class:`EnvParams`; nothing holds
state. **One step**, :func:`step`, takes an :class:`EnvState` and an action to the next :class:`EnvState`,
observation, reward and episode flags: the pressure (or jaw) update, the contact, the rules and the
observation. Every environment is a thin shell around it: :class:`pneunet_env.envs.grasp.PneuNetGraspEnv` calls
it on scalars, :class:`pneunet_env.envs.grasp_vector.PneuNetGraspVectorEnv` on ``(N,)`` arrays (with
:func:`autoreset` for the episodes that end), and :class:`pneunet_env.envs.rigid.RigidGraspEnv` with a rigid
jaw. Only the contact differs, and it is pluggable: a function ``contact(kappa~, e_s, p0, p1, obj, params) ->
Equilibrium`` (:func:`newton_contact` and :func:`newton_contact_batch` solve the pneu-net's quasi-static
equilibrium; the jaw's is kinematic).

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

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.catalogue import class_table
from pneunet_env.config import LOG_UNIFORM_FIELDS, RANGE_FIELDS, EnvConfig
from pneunet_env.objects import GraspObject
from pneunet_env.physics.batched import solve_batch
from pneunet_env.physics.contact import CONVERGED_CONTACT_RATIO, contact_ratio, winkler_stiffness
from pneunet_env.physics.params import MIN_OBJECT_CURVATURE
from pneunet_env.physics.solver import (
    Equilibrium,
    equilibrium,
    params_tuple,
    solve_equilibrium,
    status_message,
    step_state,
)
from pneunet_env.physics.xp import is_torch, ops_for, to_host

__all__ = [
    "TaskParams",
    "EnvParams",
    "EnvState",
    "Step",
    "Thresholds",
    "TaskState",
    "Outcome",
    "Contact",
    "INFO_LEVELS",
    "PIN_KEYS",
    "sample_object",
    "object_from_uniforms",
    "object_info",
    "object_thresholds",
    "check_action",
    "single_action",
    "batch_actions",
    "update_pressure",
    "initial_state",
    "transition",
    "observation",
    "newton_contact",
    "newton_contact_batch",
    "torch_contact_batch",
    "free_volume_change",
    "reset_state",
    "class_names",
    "class_name",
    "draw_count",
    "warn_if_beyond_convergence",
    "step",
    "merge",
    "autoreset",
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
    damage_rule: str = "crush_fraction"  # or "hoop_strain" (config.TaskConfig.damage_rule)

    @classmethod
    def from_config(cls, config: EnvConfig) -> TaskParams:
        """From the config's ``task`` section by field name, with the pressures made dimensionless and the scales."""
        a, tc = config.actuator, config.task
        derived = {"pressure_max": config.pressure_max, "pressure_step": config.pressure_step,
                   "width_mm": a.width_mm, "shear_modulus_kpa": a.shear_modulus_kpa, "depth_mm": a.depth_mm}
        return cls(**derived, **{f: getattr(tc, f) for f in cls._fields if f not in derived})

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
    return object_from_uniforms(rng.random((draw_count(config),) + shape), config, pinned, batch=size is not None)


CATALOGUE_DRAWS = ("class", "object_shear_modulus_kpa", "radius_mm", "object_thickness_mm", "object_density_kg_m3",
                   "object_failure_strain", "failure_stress_kpa")
"""The uniform draws of a catalogue object, in order: the class (by weight), then its properties from the class's
ranges (shear modulus, density and failure stress log-uniform; radius, thickness and failure strain uniform)."""


def class_names(config: EnvConfig) -> tuple[str, ...]:
    """The names of the catalogue classes an env draws from, by class code (empty when objects come from ranges)."""
    return class_table(config.objects.class_items).names if config.objects.from_catalogue else ()


def class_name(names: tuple[str, ...], class_id: int) -> str:
    """The name of class code ``class_id`` (``"ranges"`` for -1: an object drawn from ranges or built by hand)."""
    return names[class_id] if 0 <= class_id < len(names) else "ranges"


def draw_count(config: EnvConfig) -> int:
    """Uniform draws per object: 7 from the catalogue (:data:`CATALOGUE_DRAWS`), else 5 (``RANGE_FIELDS``)."""
    return len(CATALOGUE_DRAWS) if config.objects.from_catalogue else len(RANGE_FIELDS)


def _catalogue_values(u: np.ndarray, config: EnvConfig, batch: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    """The properties of catalogue objects from their uniforms ``u`` (``(7,) + shape``), and their extra fields."""
    tab = class_table(config.objects.class_items)
    cid = np.minimum(np.searchsorted(tab.cumulative, u[0], side="right"), len(tab.names) - 1)

    def uniform(col, x):
        lo, hi = col[0][cid], col[1][cid]
        return lo + (hi - lo) * x

    def log_uniform(col, x):
        lo, hi = col[0][cid], col[1][cid]
        return lo * (hi / lo) ** x

    values = {
        "object_shear_modulus_kpa": log_uniform(tab.shear_modulus_kpa, u[1]),
        "object_curvature_per_m": 1e3 / uniform(tab.radius_mm, u[2]),
        "object_thickness_mm": uniform(tab.thickness_mm, u[3]),
        "object_density_kg_m3": log_uniform(tab.density_kg_m3, u[4]),
        "object_failure_strain": uniform(tab.failure_strain, u[5]),
    }
    extra = {"failure_stress_kpa": log_uniform(tab.failure_stress_kpa, u[6]), "class_id": cid.astype(np.int64)}
    if not batch:
        values = {k: float(v) for k, v in values.items()}
        extra = {"failure_stress_kpa": float(extra["failure_stress_kpa"]), "class_id": int(extra["class_id"])}
    return values, extra


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
    n_draws = draw_count(config)
    if u.ndim == 0 or u.shape[0] != n_draws:
        raise ValueError(f"u must have shape ({n_draws},) + batch shape, got {u.shape}")
    shape = u.shape[1:]
    if batch is None:
        batch = bool(shape)
    values: dict[str, Any] = {}
    extra: dict[str, Any] | None = None
    if config.objects.from_catalogue:
        values, extra = _catalogue_values(u, config, batch)
    else:
        for i, name in enumerate(RANGE_FIELDS):
            lo, hi = getattr(config.objects, name)
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
            config.actuator.width_mm * 1e-3
        )
    common = dict(
        thickness_mm=values["object_thickness_mm"],
        curvature_per_m=values["object_curvature_per_m"],
        density_kg_m3=values["object_density_kg_m3"],
        failure_strain=values["object_failure_strain"],
        scales=config.scales,
    )
    try:
        if not batch:
            if "object_stiffness" in pins:
                obj = GraspObject.from_stiffness(_pin("object_stiffness", pins["object_stiffness"], shape), **common)
            else:
                obj = GraspObject.from_material(values["object_shear_modulus_kpa"], **common)
        elif "object_stiffness" in pins:
            obj = _batch_object(None, _pin("object_stiffness", pins["object_stiffness"], shape, batch), **common)
        else:
            obj = _batch_object(values["object_shear_modulus_kpa"], None, **common)
    except ValueError as exc:
        if pins and not str(exc).startswith("reset option"):  # a pin that does not fit the drawn object: name it
            raise ValueError(f"reset option(s) {sorted(pins)}: {exc}") from None
        raise
    return obj if extra is None else dataclasses.replace(obj, **extra)


def _first_bad(name: str, value: np.ndarray, bad: np.ndarray, rule: str) -> None:
    if np.any(bad):
        v = value[np.nonzero(bad)] if value.ndim else value
        raise ValueError(f"object {name} {rule}, got {float(np.ravel(v)[0])!r}")


def _batch_object(shear_modulus_kpa, stiffness, thickness_mm, curvature_per_m, density_kg_m3, failure_strain,
                  scales) -> GraspObject:
    """:meth:`GraspObject.from_material` (``stiffness=None``) or :meth:`~GraspObject.from_stiffness` for a batch.

    The same checks and the same formula (eq. 3.2, :func:`pneunet_env.physics.contact.winkler_stiffness`), as array
    operations instead of a loop over objects; ``ValueError`` names the first bad value.
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
        if stiffness is None:  # eq. 3.2 (physics.contact), as array operations
            mu = given
            k = winkler_stiffness(mu, H_mm, kap, scales.width_mm, scales.shear_modulus_kpa)
        else:
            mu = given / winkler_stiffness(1.0, H_mm, kap, scales.width_mm, scales.shear_modulus_kpa)
            k = given
        failure_stress = 3.0 * eps * mu
        _first_bad(label, given, ~np.isfinite(k) | ~np.isfinite(mu) | ~np.isfinite(failure_stress),
                   "with its failure_strain gives a stiffness or failure stress (3 eps_f mu_obj) that is not a finite "
                   "number")
        c = kap * scales.width_mm * 1e-3
        _first_bad("curvature_per_m", kap, c >= np.pi, "gives w kappa_obj >= pi")
        _first_bad("curvature_per_m", kap, c < MIN_OBJECT_CURVATURE, f"gives w kappa_obj < {MIN_OBJECT_CURVATURE:g}")
    return GraspObject(
        shear_modulus_kpa=mu,
        thickness_mm=H_mm,
        curvature_per_m=kap,
        density_kg_m3=rho,
        failure_strain=eps,
        stiffness=k,
        curvature=c,
        thickness=H_mm / scales.width_mm,
        failure_stress_kpa=failure_stress,
        class_id=np.full(np.shape(k), -1, dtype=np.int64),
    )


def _pin(key: str, value: Any, shape: tuple[int, ...], batch: bool = False):
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise ValueError(f"reset option {key!r} must be a number, got {value!r}")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"reset option {key!r} must be a number, got {value!r}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"reset option {key!r} must be finite, got {value!r}")
    if np.any(a < 0.0):
        raise ValueError(f"reset option {key!r} must be >= 0, got {value!r}")
    if key not in ("object_stiffness", "object_shear_modulus_kpa") and np.any(a == 0.0):
        raise ValueError(f"reset option {key!r} must be > 0 (a size, density or strain), got {value!r}")
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
    """The thresholds of ``obj`` in model units (traction ``/mu``, indentation ``/w``), by ``params.damage_rule``.

    * ``"hoop_strain"``: eq. 3.2's object is an annulus whose indentation shrinks the whole ring, so the strain
      that breaks it is the hoop strain ``delta kappa_obj``: crushed when it exceeds the failure strain
      (``delta~_c = eps_f / (w kappa_obj)``), overstressed when the traction exceeds the failure stress
      ``sigma_f`` (a catalogue class's own; ``3 eps_f mu_obj`` for an object drawn from ranges);
    * ``"crush_fraction"`` (the paper task's rule): overstressed above ``3 eps_f mu_obj``, crushed through when
      ``delta > crush_fraction H``.

    Slip (both): the grip traction ``rho g H / (grip_faces mu_f) / mu``: two faces of a slab of thickness ``H``
    pinched, friction carrying the weight per unit contact area ``rho g H``. See ``docs/env.md``.
    """
    mu = params.shear_modulus_kpa
    if params.damage_rule == "hoop_strain":
        failure = obj.failure_stress_kpa / mu
        crush = obj.failure_strain / obj.curvature
    else:
        failure = 3.0 * obj.failure_strain * obj.shear_modulus_kpa / mu
        crush = params.crush_fraction * obj.thickness
    weight_kpa = obj.density_kg_m3 * params.gravity_m_s2 * obj.thickness_mm * 1e-3 * 1e-3  # rho g H, Pa -> kPa
    grip = weight_kpa / (params.grip_faces * params.friction_coefficient) / mu
    return Thresholds(failure, crush, grip)


# ---------------------------------------------------------------------------------------------
# Action -> pressure
# ---------------------------------------------------------------------------------------------


def check_action(action):
    """``action`` as a float array (a Python float if 0-d; a tensor stays a tensor); ``ValueError`` naming it unless
    all finite."""
    if is_torch(action):
        bad = ~action.isfinite()
        if bool(bad.any()):
            i = int(bad.reshape(-1).nonzero()[0, 0])
            raise ValueError(f"actions[{i}] must be finite (no NaN or inf), got {float(action.reshape(-1)[i])!r}")
        return action
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


_REAL_KINDS = "iuf"  # numpy dtype kinds of real numbers (not bool, complex, strings or objects)


def _real_array(action, name: str, shape_hint: str) -> np.ndarray:
    """``action`` as a float64 array if it is real numbers; ``TypeError`` naming what it got otherwise."""
    if isinstance(action, (str, bytes, bool, np.bool_)) or action is None:
        raise TypeError(f"{name} must be real numbers {shape_hint}, got {type(action).__name__} {action!r}")
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"{name} must be real numbers {shape_hint}, got {action!r}") from None
    if raw.dtype.kind not in _REAL_KINDS:
        if raw.dtype.kind == "O" and all(type(v) is int for v in raw.ravel()):  # ints too large for int64
            try:
                return np.array([float(v) for v in raw.ravel()], dtype=np.float64).reshape(raw.shape)
            except OverflowError:
                raise ValueError(f"{name} {action!r} is too large for a float") from None
        raise TypeError(f"{name} must be real numbers {shape_hint}, got dtype {raw.dtype}: {action!r}")
    return raw.astype(np.float64, copy=False)


def single_action(action) -> float:
    """A single env's action as a Python float: a real number, or an array of shape ``(1,)`` (or ``()``).

    ``TypeError`` naming it for anything that is not real numbers (``None``, strings, booleans, complex numbers,
    objects); ``ValueError`` for the wrong shape or a number too large for a float. (NaN and inf are caught by
    :func:`update_pressure`.) The common case, a float array of shape ``(1,)``, is read directly.
    """
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        return float(action[0])
    if type(action) in (float, int):
        try:
            return float(action)
        except OverflowError:
            raise ValueError(f"action {action!r} is too large for a float") from None
    arr = _real_array(action, "action", "(a number, or shape (1,))")
    if arr.shape not in ((1,), ()):
        raise ValueError(f"action must have shape (1,), got shape {arr.shape}: {action!r}")
    return float(arr.reshape(-1)[0])


def batch_actions(actions, n: int, device=None):
    """A batch's actions, shape ``(n, 1)`` or ``(n,)``, as a float64 ``(n,)`` array; errors name what they got
    (``TypeError`` for what is not real numbers, ``ValueError`` for the shape or a NaN/inf, with its index).

    With ``device`` (a torch device: the torch backend) the result is a float64 tensor there, from a tensor (moved
    if it is elsewhere) or from anything numpy takes; a NaN or inf is then caught once, by the step
    (:func:`update_pressure`), with its index. Without ``device`` a CPU tensor is taken as numpy takes it.
    """
    if device is not None:
        return _tensor_actions(actions, n, device)
    a = _real_array(actions, "actions", f"of shape ({n}, 1)")
    if a.shape == (n, 1):
        a = a[:, 0]
    elif a.shape != (n,):
        raise ValueError(f"actions must have shape ({n}, 1) (or ({n},)), got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"actions[{i}] must be finite (no NaN or inf), got {a[i]!r}")
    return a


def _tensor_actions(actions, n: int, device):
    import torch

    if is_torch(actions):
        if not (actions.dtype.is_floating_point
                or actions.dtype in (torch.int8, torch.int16, torch.int32, torch.int64, torch.uint8)):
            raise TypeError(f"actions must be real numbers of shape ({n}, 1), got a tensor of dtype {actions.dtype}")
        a = actions.to(dtype=torch.float64, device=device)
    else:
        a = torch.from_numpy(np.array(_real_array(actions, "actions", f"of shape ({n}, 1)"))).to(device)
    if tuple(a.shape) == (n, 1):
        a = a[:, 0]
    elif tuple(a.shape) != (n,):
        raise ValueError(f"actions must have shape ({n}, 1) (or ({n},)), got shape {tuple(a.shape)}")
    return a


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
    xp = ops_for(a)
    clipped = (a < -1.0) | (a > 1.0)
    a = xp.minimum(xp.maximum(a, -1.0), 1.0)
    p = xp.minimum(xp.maximum(pressure + a * params.pressure_step, 0.0), params.pressure_max)
    return p, clipped


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


def initial_state(shape: tuple[int, ...] | None = None, like=None) -> TaskState:
    """The task state at ``reset``: scalars (``shape=None``) or arrays of ``shape`` (tensors on ``like``'s device
    when ``like`` is a tensor)."""
    if shape is None:
        return TaskState(0, False, False, 0.0)
    if is_torch(like):
        xp, n = ops_for(like), like.shape[0]
        return TaskState(xp.full(n, 0, "int"), xp.full(n, False, "bool"), xp.full(n, False, "bool"),
                         xp.full(n, 0.0, "float"))
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


def make_rules(number, maximum, jit=None):
    """Build the task's rules from two operations: written once, instantiated on Python scalars (one env), numpy
    and torch arrays (:func:`transition`), and compiled by numba for the fused vector step
    (:mod:`pneunet_env.fused`), the way :func:`pneunet_env.physics.mechanics.make_terms` builds the energy.

    ``number(flag)`` makes a flag a float for the reward; ``maximum(a, b)`` is the elementwise maximum; ``jit``
    decorates the built function (``numba.njit``). Returns ``rules(step, damaged, dropped, peak, F, delta,
    in_contact, failure, crush, grip, failed, squeeze_steps, episode_steps, reward_hold, reward_success,
    penalty_damage, penalty_slip, terminate_on_damage, terminate_on_slip)`` -> ``(step, damaged, dropped, peak,
    in_hold, overstressed, crushed, damage_event, slipping, drop_event, held, terminated, truncated, success,
    reward)``; see :func:`transition` for what each is.
    """

    def rules(step0, damaged0, dropped0, peak0, F, delta, in_contact, failure, crush, grip, failed, squeeze_steps,
              episode_steps, reward_hold, reward_success, penalty_damage, penalty_slip, terminate_on_damage,
              terminate_on_slip):
        # Written with the operators & | ^ (not np.logical_*): they act elementwise on bool arrays and tensors and
        # on Python/numpy/numba bools alike, and cost far less than a ufunc call on scalars. ``x ^ True`` is "not x".
        step = step0 + 1
        in_hold = step > squeeze_steps
        end = step >= episode_steps
        overstressed = F > failure
        crushed = in_contact & (delta > crush)
        damage_now = overstressed | crushed
        damage_event = damage_now & (damaged0 ^ True)
        damaged = damaged0 | damage_now
        slipping = in_hold & (F < grip)
        drop_event = slipping & (dropped0 ^ True)
        dropped = dropped0 | slipping
        intact = (damaged | dropped | failed) ^ True
        held = in_hold & intact
        terminated = (damage_event & terminate_on_damage) | (drop_event & terminate_on_slip)
        truncated = (terminated ^ True) & (end | failed)
        success = end & intact
        reward = (reward_hold * number(held) + reward_success * number(success) - penalty_damage * number(damage_event)
                  - penalty_slip * number(drop_event))
        return (step, damaged, dropped, maximum(peak0, F), in_hold, overstressed, crushed, damage_event, slipping,
                drop_event, held, terminated, truncated, success, reward)

    return rules if jit is None else jit(rules)


def _same(x):
    return x


def _scalar_peak(a, b):
    # one environment: the same number as np.maximum gives (an np.float64), without a ufunc call
    return _float64(b if b > a else a)


_scalar_rules = make_rules(_same, _scalar_peak)
_numpy_rules = make_rules(_same, np.maximum)
_TORCH_RULES: list = []


def _rules_for(contact_force, peak_force):
    if is_torch(contact_force):
        if not _TORCH_RULES:
            _TORCH_RULES.append(make_rules(lambda f: f.double(), ops_for(contact_force).maximum))
        return _TORCH_RULES[0]
    if isinstance(contact_force, np.ndarray) or isinstance(peak_force, np.ndarray):
        return _numpy_rules
    return _scalar_rules


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

    The rules themselves are :func:`make_rules`'s, on scalars, numpy arrays or torch tensors.
    """
    rules = _rules_for(contact_force, state.peak_force)
    (step, damaged, dropped, peak, in_hold, overstressed, crushed, damage_event, slipping, drop_event, held,
     terminated, truncated, success, reward) = rules(
        state.step, state.damaged, state.dropped, state.peak_force, contact_force, indentation, in_contact,
        thresholds.failure_traction, thresholds.crush_indentation, thresholds.grip_traction, solver_failed,
        params.squeeze_steps, params.squeeze_steps + params.hold_steps, params.reward_hold, params.reward_success,
        params.penalty_damage, params.penalty_slip, params.terminate_on_damage, params.terminate_on_slip)
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
    if is_torch(pressure):
        xp = ops_for(pressure)
        p = pressure / params.pressure_max
        return xp.to_float32(p[..., None] if volume_scale is None else xp.stack([p, volume_change / volume_scale]))
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
    if is_torch(a) or is_torch(b):
        xp = ops_for(a if is_torch(a) else b)
        return xp.where(b > 0.0, a / xp.where(b > 0.0, b, 1.0), 0.0)
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
        "object_class": obj.class_id,
        "failure_traction_kpa": thresholds.failure_traction * mu,
        "crush_indentation_mm": thresholds.crush_indentation * w,
        "grip_traction_kpa": thresholds.grip_traction * mu,
    }


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
    return equilibrium(p1, raw, params.actuator[0], obj.stiffness, obj.curvature)


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

    active = ops_for(kappa).full(kappa.shape[0], True, "bool")
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
        task: the rules' numbers (:class:`TaskParams`); a rigid jaw's has the jaw's travel and step in place of
            the pressure's.
        actuator: the dimensionless actuator as the compiled solver takes it
            (:func:`pneunet_env.physics.solver.params_tuple`).
        solver: :meth:`SolverOptions.as_tuple <pneunet_env.physics.solver.SolverOptions.as_tuple>`.
        actuator_params, solver_options: the same, as their validated objects.
        volume_scale: the free actuator's volume change at ``p_max`` with ``observe_volume``, else ``None``.
    """

    task: TaskParams
    actuator: tuple
    solver: tuple
    actuator_params: Any
    solver_options: Any
    volume_scale: float | None

    @classmethod
    def from_config(cls, config: EnvConfig) -> EnvParams:
        scale = free_volume_change(config) if config.task.observe_volume else None
        return cls(TaskParams.from_config(config), params_tuple(config.actuator_params), config.solver.as_tuple(),
                   config.actuator_params, config.solver, scale)


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
    obs: np.ndarray
    reward: Any
    terminated: Any
    truncated: Any
    solve: Equilibrium  # the step's solve (its diagnostics), even where it failed and the state was kept
    outcome: Outcome
    action_clipped: Any
    solver_failed: Any


def warn_if_beyond_convergence(obj: GraspObject, warned: bool = False) -> bool:
    """Warn (once: pass and keep the returned flag) if an object's contact is stiffer than any at which the solver
    was measured to converge (:data:`pneunet_env.physics.contact.CONVERGED_CONTACT_RATIO`). Returns the flag."""
    if warned:
        return True
    ratio = np.max(contact_ratio(np.asarray(obj.stiffness), np.asarray(obj.curvature)))
    if ratio > CONVERGED_CONTACT_RATIO:
        import warnings

        warnings.warn(
            f"object with k~/(w kappa_obj)^4 = {ratio:.3g} beyond {CONVERGED_CONTACT_RATIO:g}, the largest at which "
            "the solver was measured to converge: steps may be flagged unconverged (info['solver_failed'])",
            UserWarning, stacklevel=3,
        )
        return True
    return False


def reset_state(obj: GraspObject, params: EnvParams, contact: Contact) -> EnvState:
    """The state at ``reset``: command 0, the actuator at rest (the equilibrium at ``p~ = 0``), the object's
    thresholds, a fresh task state. Scalars for one object, ``(N,)`` arrays for a batch."""
    k = obj.stiffness
    shape = tuple(k.shape) if is_torch(k) else np.shape(k)
    zero: Any = 0.0 if shape == () else (k * 0.0 if is_torch(k) else np.zeros(shape))
    eq = contact(zero, zero, zero, zero, obj, params)
    return EnvState(0.0 if shape == () else zero * 1.0, eq, obj, object_thresholds(obj, params.task),
                    initial_state(None if shape == () else shape, k))


def _keep_where(failed, old: Equilibrium, new: Equilibrium) -> Equilibrium:
    """``new``, with ``old``'s entries where the solve ``failed`` (the previous state is kept)."""
    if is_torch(failed):  # no test of failed.any(): that would be a host sync on a GPU
        where = ops_for(failed).where
        return Equilibrium(*(where(failed, a, b) for a, b in zip(old, new, strict=True)))
    if not isinstance(failed, np.ndarray):
        return old if failed else new
    if not failed.any():
        return new
    return Equilibrium(*(np.where(failed, a, b) for a, b in zip(old, new, strict=True)))


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
        params: the env's :class:`EnvParams`.
        contact: the :data:`Contact` (the pneu-net's Newton solve, or a jaw's kinematics).
    """
    command, clipped = update_pressure(state.command, action, params.task)
    prev = state.eq
    solve = contact(prev.curvature, prev.side_strain, prev.pressure, command, state.obj, params)
    conv = solve.converged
    failed = (not conv) if isinstance(conv, (bool, np.bool_)) else ~conv
    eq = _keep_where(failed, prev, solve)
    if is_torch(failed):
        command = ops_for(failed).where(failed, state.command, command)
    elif isinstance(failed, np.ndarray):
        command = np.where(failed, state.command, command) if failed.any() else command
    elif failed:
        command = state.command
    out = transition(state.task, eq.contact_force, eq.indentation, eq.in_contact, state.thresholds, failed, params.task)
    obs = observation(command, eq.volume_change, params.task, params.volume_scale)
    new = EnvState(command, eq, state.obj, state.thresholds, out.state)
    return Step(new, obs, out.reward, out.terminated, out.truncated, solve, out, clipped, failed)


def _fields(record) -> tuple:
    if isinstance(record, tuple):
        return tuple(record)
    return tuple(getattr(record, f.name) for f in dataclasses.fields(record))


def merge(old, idx, new):
    """A fresh record (NamedTuple or dataclass, nested): ``old`` with entries ``idx`` replaced by ``new``'s.

    Arrays are copied, never changed in place, so a state handed out earlier stays as it was.
    """
    out = []
    for a, b in zip(_fields(old), _fields(new), strict=True):
        if isinstance(a, tuple) or dataclasses.is_dataclass(a):
            out.append(merge(a, idx, b))
        else:
            c = a.clone() if is_torch(a) else np.array(a, copy=True)
            c[idx] = b
            out.append(c)
    return type(old)(*out)


def autoreset(state: EnvState, idx: np.ndarray, obj: GraspObject, params: EnvParams, contact: Contact) -> EnvState:
    """``state`` with the envs ``idx`` reset on the objects ``obj`` (``(len(idx),)`` arrays).

    The randomness is passed in, as the objects drawn for those envs (the vector env draws them from each env's
    own stream: :func:`object_from_uniforms` on its uniforms), so this stays pure.
    """
    return merge(state, idx, reset_state(obj, params, contact))


# ---------------------------------------------------------------------------------------------
# Info
# ---------------------------------------------------------------------------------------------

INFO_LEVELS = ("lean", "full")
"""``info_level`` of the envs: ``"lean"`` (default) gives :data:`LEAN_KEYS` every step and the object's constants
at reset; ``"full"`` gives every key of :func:`build_info` every step."""

LEAN_KEYS = (
    "pressure_kpa", "curvature_per_m", "contact_force_kpa", "indentation_mm", "in_contact",
    "step", "in_hold", "held", "damaged", "overstressed", "crushed", "dropped", "slipping", "action_clipped",
    "snapped", "solver_converged", "solver_failed",
)
"""The keys of a lean step info: pressure, curvature, contact, the task's flags and the solver's status."""

OBJECT_KEYS = (
    "object_stiffness", "object_stiffness_kpa_per_mm", "object_shear_modulus_kpa", "object_curvature",
    "object_curvature_per_m", "object_thickness_mm", "object_density_kg_m3", "object_failure_strain",
    "object_class", "failure_traction_kpa", "crush_indentation_mm", "grip_traction_kpa",
)
"""The object's constants (:func:`object_info`): in every reset info, and in every step's with ``"full"``."""


FULL_KEYS = (
    "pressure", "pressure_kpa", "curvature", "curvature_per_m", "side_strain", "top_strain", "contact_force",
    "contact_force_kpa", "indentation", "indentation_mm", "volume_change", "volume_change_mm3", "in_contact",
    *OBJECT_KEYS, "grip_ratio", "damage_ratio", "peak_contact_force_kpa", "step", "damaged", "dropped", "snapped",
    "solver_converged", "solver_failed", "solver_iterations", "solver_substeps", "solver_status", "gradient_norm",
    "min_eigenvalue", "action_clipped", "in_hold", "overstressed", "crushed", "slipping", "held",
)
"""The keys of a full info (:func:`build_info` with ``level="full"``)."""


def info_keys(level: str) -> tuple[str, ...]:
    """Every key an info of ``level`` can hold (the lean level's reset info adds the object's constants)."""
    if level not in INFO_LEVELS:
        raise ValueError(f"info_level must be one of {INFO_LEVELS}, got {level!r}")
    return LEAN_KEYS + OBJECT_KEYS if level == "lean" else FULL_KEYS


def build_info(
    state: EnvState,
    params: TaskParams,
    result: Step | None = None,
    level: str = "lean",
    static: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``info`` dict, from scalars or arrays: physical values (``*_kpa``, ``*_mm``, ``*_per_m``) and flags.

    Args:
        state: the state after the step (or at reset).
        params: the task's numbers.
        result: the step's :class:`Step` (``None`` at reset).
        level: ``"lean"`` (:data:`LEAN_KEYS`; at reset the object's constants too, :data:`OBJECT_KEYS`) or ``"full"``
            (every key below, every step).
        static: ``object_info(obj, thresholds, params)``, if the caller keeps it (computed here otherwise).

    The full info: ``pressure`` / ``pressure_kpa``, ``curvature`` (``w kappa``) / ``curvature_per_m``,
    ``side_strain``, ``top_strain``, ``contact_force`` (``F~``) / ``contact_force_kpa``, ``indentation``
    (``delta~``) / ``indentation_mm``, ``volume_change`` / ``volume_change_mm3``, ``in_contact``; the object's
    constants (:data:`OBJECT_KEYS`); ``grip_ratio`` (``F`` over the grip traction, >= 1 holds), ``damage_ratio``
    (>= 1 damages), ``peak_contact_force_kpa``; the task's ``step``, ``in_hold``, ``damaged``, ``overstressed``,
    ``crushed``, ``slipping``, ``dropped``, ``held``, ``action_clipped``; the solver's ``snapped``,
    ``solver_converged``, ``solver_failed``, ``solver_iterations``, ``solver_substeps``, ``solver_status`` (its
    message), ``gradient_norm``, ``min_eigenvalue``.

    Every array value is freshly computed (no buffer is reused between calls), unless ``static`` holds arrays.
    """
    if level not in INFO_LEVELS:
        raise ValueError(f"info_level must be one of {INFO_LEVELS}, got {level!r}")
    eq, obj, thresholds, task_state = state.eq, state.obj, state.thresholds, state.task
    solve = eq if result is None else result.solve
    outcome = None if result is None else result.outcome
    action_clipped = False if result is None else result.action_clipped
    solver_failed = False if result is None else result.solver_failed
    if level == "lean":
        return _lean_info(eq, solve, obj, thresholds, task_state, params, outcome, action_clipped, solver_failed,
                          static)
    mu, w = params.shear_modulus_kpa, params.width_mm
    F = eq.contact_force
    in_contact = eq.in_contact
    if not isinstance(in_contact, (bool, np.bool_)):
        xp = ops_for(in_contact)
        delta = xp.where(in_contact, eq.indentation, 0.0)
        damage_ratio = xp.maximum(
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
        "peak_contact_force_kpa": task_state.peak_force * mu,
        "step": task_state.step,
        "damaged": task_state.damaged,
        "dropped": task_state.dropped,
        "snapped": solve.snapped,
        "solver_converged": solve.converged,
        "solver_failed": solver_failed,
        "solver_iterations": solve.iterations,
        "solver_substeps": solve.substeps,
        "solver_status": status_message(to_host(solve.status)),
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


def _lean_info(eq, solve, obj, thresholds, task_state, params, outcome, action_clipped, solver_failed, static):
    mu, w = params.shear_modulus_kpa, params.width_mm
    in_contact = eq.in_contact
    if isinstance(in_contact, (bool, np.bool_)):
        delta = eq.indentation if in_contact else 0.0
    else:
        delta = ops_for(in_contact).where(in_contact, eq.indentation, 0.0)
    info: dict[str, Any] = {
        "pressure_kpa": eq.pressure * mu,
        "curvature_per_m": eq.curvature / (w * 1e-3),
        "contact_force_kpa": eq.contact_force * mu,
        "indentation_mm": delta * w,
        "in_contact": in_contact,
        "step": task_state.step,
        "in_hold": False if outcome is None else outcome.in_hold,
        "held": False if outcome is None else outcome.held,
        "damaged": task_state.damaged,
        "overstressed": False if outcome is None else outcome.overstressed,
        "crushed": False if outcome is None else outcome.crushed,
        "dropped": task_state.dropped,
        "slipping": False if outcome is None else outcome.slipping,
        "action_clipped": action_clipped,
        "snapped": solve.snapped,
        "solver_converged": solve.converged,
        "solver_failed": solver_failed,
    }
    if outcome is None:  # at reset: the object's constants
        info.update(object_info(obj, thresholds, params) if static is None else static)
    return info
