"""The task's objects: drawing them (from the config's ranges or its catalogue), reset pins, and the damage and slip
thresholds the rules compare the contact with.

The object itself is :class:`pneunet_env.objects.GraspObject`; here are the task's uses of it: :func:`sample_object`
(one object, or a batch, from an env's generator), :func:`object_from_uniforms` (the pure half, from the uniform
draws: the vector env draws them from each sub-env's own stream), :data:`PIN_KEYS` (``reset(options=...)``),
:func:`object_thresholds` (by the config's ``damage_rule``) and the warning for objects stiffer than any at which the
solver was measured to converge.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.catalogue import class_table
from pneunet_env.config import LOG_UNIFORM_FIELDS, RANGE_FIELDS, EnvConfig
from pneunet_env.objects import GraspObject, object_mass_kg
from pneunet_env.physics.contact import CONVERGED_CONTACT_RATIO, contact_ratio, winkler_stiffness
from pneunet_env.physics.params import MIN_OBJECT_CURVATURE

__all__ = [
    "PIN_KEYS",
    "CATALOGUE_DRAWS",
    "Thresholds",
    "sample_object",
    "object_from_uniforms",
    "object_thresholds",
    "class_names",
    "class_name",
    "draw_count",
    "warn_if_beyond_convergence",
    "contact_length_mm",
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
ranges (shear modulus, density and failure stress log-uniform; radius, thickness and failure strain uniform). A
catalogue with a cylinder class draws one more, its length (uniform), last."""


def class_names(config: EnvConfig) -> tuple[str, ...]:
    """The names of the catalogue classes an env draws from, by class code (empty when objects come from ranges)."""
    return class_table(config.objects.class_items).names if config.objects.from_catalogue else ()


def class_name(names: tuple[str, ...], class_id: int) -> str:
    """The name of class code ``class_id`` (``"ranges"`` for -1: an object drawn from ranges or built by hand)."""
    return names[class_id] if 0 <= class_id < len(names) else "ranges"


def draw_count(config: EnvConfig) -> int:
    """Uniform draws per object: 7 from the catalogue (:data:`CATALOGUE_DRAWS`; 8 where a drawn class is a cylinder,
    whose length takes one more), else 5 (``RANGE_FIELDS``)."""
    if not config.objects.from_catalogue:
        return len(RANGE_FIELDS)
    return len(CATALOGUE_DRAWS) + class_table(config.objects.class_items).has_length


def _log_uniform(lo, hi, x):
    """``lo (hi/lo)^x``: a log-uniform draw from its uniform ``x``, for one object or a batch alike.

    Always numpy's ``power`` ufunc, never Python's or numpy's scalar ``**``: the ufunc's kernel (chosen by the CPU's
    SIMD level, AVX-512's differs from libm's ``pow`` in the last bit of about 4 % of draws) gives the same bits for
    an element whether it comes alone, in a 0-d array or in a batch, so the single and the vector env draw the same
    object on one install.
    """
    return lo * np.power(hi / lo, x)


def _catalogue_values(u: np.ndarray, config: EnvConfig, batch: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    """The properties of catalogue objects from their uniforms ``u`` (``(7,) + shape``), and their extra fields."""
    tab = class_table(config.objects.class_items)
    cid = np.minimum(np.searchsorted(tab.cumulative, u[0], side="right"), len(tab.names) - 1)

    def uniform(col, x):
        lo, hi = col[0][cid], col[1][cid]
        return lo + (hi - lo) * x

    def log_uniform(col, x):
        lo, hi = col[0][cid], col[1][cid]
        return _log_uniform(lo, hi, x)

    values = {
        "object_shear_modulus_kpa": log_uniform(tab.shear_modulus_kpa, u[1]),
        "object_curvature_per_m": 1e3 / uniform(tab.radius_mm, u[2]),
        "object_thickness_mm": uniform(tab.thickness_mm, u[3]),
        "object_density_kg_m3": log_uniform(tab.density_kg_m3, u[4]),
        "object_failure_strain": uniform(tab.failure_strain, u[5]),
    }
    length = uniform(tab.length_mm, u[7]) if tab.has_length else 0.0
    mass = object_mass_kg(tab.shape[cid], 1e3 / values["object_curvature_per_m"], values["object_density_kg_m3"],
                          length_mm=length)
    extra = {"failure_stress_kpa": log_uniform(tab.failure_stress_kpa, u[6]), "class_id": cid.astype(np.int64),
             "mass_kg": mass}
    if not batch:
        values = {k: float(v) for k, v in values.items()}
        extra = {"failure_stress_kpa": float(extra["failure_stress_kpa"]), "class_id": int(extra["class_id"]),
                 "mass_kg": float(mass)}
    return values, extra


def object_from_uniforms(
    u: np.ndarray, config: EnvConfig, pinned: Mapping[str, Any] | None = None, batch: bool | None = None
) -> GraspObject:
    """The object of the uniform draws ``u`` (shape ``(5,)``: one object; ``(5,) + shape``: a batch).

    The pure half of :func:`sample_object` (which is ``object_from_uniforms(rng.random((5,) + shape), ...)``):
    a batched environment draws ``u`` from each sub-environment's own stream and maps them here.
    ``batch=None`` infers it from ``u.ndim``; ``batch=True`` with ``u.shape == (5,)`` gives 0-d array fields.
    A batch is computed with array operations (no loop over objects); its values equal the single-object ones bit
    for bit on one install (both go through :func:`_log_uniform`'s ufunc). Across machines they may differ in the
    last bit: numpy picks ``power``'s kernel by the CPU's SIMD level (AVX-512 or not).
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
            v = _log_uniform(lo, hi, u[i]) if name in LOG_UNIFORM_FIELDS else lo + (hi - lo) * u[i]
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
    if extra is None:
        return _with_shape(obj, config)
    if pins:  # a pinned size or density: the class's shape, the pinned numbers
        extra["mass_kg"] = _as_batch(object_mass_kg(
            class_table(config.objects.class_items).shape[extra["class_id"]], 1e3 / np.asarray(obj.curvature_per_m),
            obj.density_kg_m3, length_mm=_drawn_length(u, config, extra["class_id"])), batch)
    return dataclasses.replace(obj, **extra)


def _as_batch(x, batch: bool):
    return np.asarray(x, dtype=float) if batch else float(x)


def _drawn_length(u: np.ndarray, config: EnvConfig, cid) -> Any:
    tab = class_table(config.objects.class_items)
    if not tab.has_length:
        return 0.0
    lo, hi = tab.length_mm[0][cid], tab.length_mm[1][cid]
    return lo + (hi - lo) * u[7]


def _with_shape(obj: GraspObject, config: EnvConfig) -> GraspObject:
    """``obj`` (drawn from the config's ranges, a solid sphere's mass) with the mass of the config's ``shape``."""
    oc = config.objects
    if oc.shape == "sphere":
        return obj
    length = oc.object_length_mm if oc.object_length_mm is not None else config.actuator.finger_width_mm
    mass = object_mass_kg(oc.shape, 1e3 / np.asarray(obj.curvature_per_m), obj.density_kg_m3, obj.thickness_mm,
                          length)
    return dataclasses.replace(obj, mass_kg=mass)


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
        mass_kg=object_mass_kg("sphere", 1e3 / kap, rho),
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


def object_thresholds(obj: GraspObject, params: Any) -> Thresholds:
    """The thresholds of ``obj`` in model units (traction ``/mu``, indentation ``/w``), by ``params.damage_rule``
    (``params``: the :class:`pneunet_env.task.TaskParams`, typed ``Any`` here since :mod:`pneunet_env.task` imports
    this module).

    * ``"hoop_strain"``: eq. 3.2's object is an annulus whose indentation shrinks the whole ring, so the strain
      that breaks it is the hoop strain ``delta kappa_obj``: crushed when it exceeds the failure strain
      (``delta~_c = eps_f / (w kappa_obj)``), overstressed when the traction exceeds the failure stress
      ``sigma_f`` (a catalogue class's own; ``3 eps_f mu_obj`` for an object drawn from ranges);
    * ``"crush_fraction"`` (the paper task's rule): overstressed above ``3 eps_f mu_obj``, crushed through when
      ``delta > crush_fraction H``.

    Slip, by ``params.hold_rule``: the grip traction below which friction cannot carry the object,

    * ``"weight"``: ``m g / (grip_faces mu_f L_c b) / mu``: each of ``grip_faces`` fingers presses with the normal
      force ``N = F L_c b`` (the traction over the contact length ``L_c``, :func:`contact_length_mm`, and the
      finger's width ``b``), and friction ``mu_f N`` on each carries the object's weight ``m g`` (its mass from its
      3D shape, :attr:`GraspObject.mass_kg`);
    * ``"slab"`` (``PneuNetGrasp-v0``): ``rho g H / (grip_faces mu_f) / mu``, two faces of a slab of thickness ``H``
      pinched, friction carrying the weight per unit contact area ``rho g H``.

    See ``docs/env.md``, "The hold rule".
    """
    mu = params.shear_modulus_kpa
    if params.damage_rule == "hoop_strain":
        failure = obj.failure_stress_kpa / mu
        crush = obj.failure_strain / obj.curvature
    else:
        failure = 3.0 * obj.failure_strain * obj.shear_modulus_kpa / mu
        crush = params.crush_fraction * obj.thickness
    if params.hold_rule == "slab":
        weight_kpa = obj.density_kg_m3 * params.gravity_m_s2 * obj.thickness_mm * 1e-3 * 1e-3  # rho g H, Pa -> kPa
    else:  # the weight m g over the contact area L_c b of every finger: N/m^2 = Pa -> kPa
        area_m2 = contact_length_mm(obj, params) * 1e-3 * params.finger_width_mm * 1e-3
        weight_kpa = obj.mass_kg * params.gravity_m_s2 / area_m2 * 1e-3
    grip = weight_kpa / (params.grip_faces * params.friction_coefficient) / mu
    return Thresholds(failure, crush, grip)


def contact_length_mm(obj: GraspObject, params: Any):
    """The length (mm) of each finger's contact with ``obj``: the whole finger (``params.finger_length_mm``), whose
    cells all lie on the object at one curvature in the model, but at most the object's circumference shared by the
    ``grip_faces`` fingers, ``2 pi R / grip_faces`` (half of it each for two fingers: they cannot wrap more)."""
    wrap = 2e3 * np.pi / (obj.curvature_per_m * params.grip_faces)
    # a batch: numpy arrays or torch tensors alike (both have clip(max=...))
    return wrap.clip(max=params.finger_length_mm) if np.ndim(wrap) else min(params.finger_length_mm, float(wrap))


def warn_if_beyond_convergence(obj: GraspObject, warned: bool = False) -> bool:
    """Warn (once: pass and keep the returned flag) if an object's contact is stiffer than any at which the solver
    was measured to converge (:data:`pneunet_env.physics.contact.CONVERGED_CONTACT_RATIO`). Returns the flag."""
    if warned:
        return True
    ratio = np.max(contact_ratio(np.asarray(obj.stiffness), np.asarray(obj.curvature)))
    if ratio > CONVERGED_CONTACT_RATIO:
        warnings.warn(
            f"object with k~/(w kappa_obj)^4 = {ratio:.3g} beyond {CONVERGED_CONTACT_RATIO:g}, the largest at which "
            "the solver was measured to converge: steps may be flagged unconverged (info['solver_failed'])",
            UserWarning, stacklevel=3,
        )
        return True
    return False

