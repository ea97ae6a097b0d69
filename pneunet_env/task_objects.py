"""The task's objects: drawing them (from the config's ranges or its catalogue), reset pins, and the damage and slip
thresholds the rules compare the contact with.

The object itself is :class:`pneunet_env.objects.GraspObject`; here are the task's uses of it: :func:`sample_object`
(one object, or a batch, from an env's generator), :func:`object_from_uniforms` (the pure half, from the uniform
draws: the vector env draws them from each sub-env's own stream), :data:`PIN_KEYS` (``reset(options=...)``),
:func:`object_thresholds` (by the config's ``damage_rule``) and the warning for objects stiffer than any at which the
solver was measured to converge.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import warnings
from collections.abc import Mapping
from typing import Any, NamedTuple, NoReturn

import numpy as np

from pneunet_env.catalogue import class_table
from pneunet_env.config import LOG_UNIFORM_FIELDS, RANGE_FIELDS, EnvConfig
from pneunet_env.objects import SHAPES, GraspObject, _mass_one, _material_fields, object_mass_kg
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
    if size is None:  # one object (a reset's): its floats straight to the scalar path
        return _one_object(rng.random(draw_count(config)).tolist(), config, _checked_pins(pinned))
    shape: tuple[int, ...] = tuple(np.atleast_1d(size).astype(int))
    return object_from_uniforms(rng.random((draw_count(config),) + shape), config, pinned, batch=True)


CATALOGUE_DRAWS = ("class", "object_shear_modulus_kpa", "radius_mm", "object_thickness_mm", "object_density_kg_m3",
                   "object_failure_strain", "failure_stress_kpa")
"""The uniform draws of a catalogue object, in order: the class (by weight), then its properties from the class's
ranges (shear modulus, density and failure stress log-uniform; radius, thickness and failure strain uniform). A
catalogue with a cylinder class draws one more, its length (uniform), last."""


def class_names(config: EnvConfig) -> tuple[str, ...]:
    """The names of the catalogue classes an env draws from, by class code (empty when objects come from ranges)."""
    return config.objects.table.names if config.objects.from_catalogue else ()


def class_name(names: tuple[str, ...], class_id: int) -> str:
    """The name of class code ``class_id`` (``"ranges"`` for -1: an object drawn from ranges or built by hand)."""
    return names[class_id] if 0 <= class_id < len(names) else "ranges"


def draw_count(config: EnvConfig) -> int:
    """Uniform draws per object: 7 from the catalogue (:data:`CATALOGUE_DRAWS`; 8 where a drawn class is a cylinder,
    whose length takes one more), else 5 (``RANGE_FIELDS``)."""
    if not config.objects.from_catalogue:
        return len(RANGE_FIELDS)
    return len(CATALOGUE_DRAWS) + _scalar_table(config.objects.class_items, config.objects.catalogue).has_length


class _ScalarTable(NamedTuple):
    """A :class:`~pneunet_env.catalogue.ClassTable` as Python floats, for drawing one object without numpy: per
    class, ``(lo, hi)`` of each property, in :data:`CATALOGUE_DRAWS`'s order after the class."""

    cumulative: list[float]
    last: int  # the last class code
    shear_modulus_kpa: list[tuple[float, float]]
    radius_mm: list[tuple[float, float]]
    thickness_mm: list[tuple[float, float]]
    density_kg_m3: list[tuple[float, float]]
    failure_strain: list[tuple[float, float]]
    failure_stress_kpa: list[tuple[float, float]]
    shape: list[int]
    length_mm: list[tuple[float, float]]
    has_length: bool


@functools.lru_cache(maxsize=32)
def _scalar_table(class_items: tuple[tuple[str, float], ...], catalogue: str | None = None) -> _ScalarTable:
    tab = class_table(class_items, catalogue)

    def col(c):
        return list(zip(c[0].tolist(), c[1].tolist(), strict=True))

    return _ScalarTable(tab.cumulative.tolist(), len(tab.names) - 1, col(tab.shear_modulus_kpa), col(tab.radius_mm),
                        col(tab.thickness_mm), col(tab.density_kg_m3), col(tab.failure_strain),
                        col(tab.failure_stress_kpa), tab.shape.tolist(), col(tab.length_mm), tab.has_length)


def _log_uniform(lo, hi, x):
    """``lo (hi/lo)^x``: a log-uniform draw from its uniform ``x``, for one object or a batch alike.

    Always numpy's ``power`` ufunc, never Python's or numpy's scalar ``**``: the ufunc's kernel (chosen by the CPU's
    SIMD level, AVX-512's differs from libm's ``pow`` in the last bit of about 4 % of draws) gives the same bits for
    an element whether it comes alone, in a 0-d array or in a batch, so the single and the vector env draw the same
    object on one install.
    """
    return lo * np.power(hi / lo, x)


def _one_catalogue_values(u: list[float], config: EnvConfig) -> tuple[dict[str, float], int, float, int, float]:
    """One catalogue object's properties from its uniforms (floats), with its class code, failure stress (kPa), shape
    code and length (mm): :func:`_catalogue_values` of one object, the same bits (the class by the same comparisons,
    ``+ - * /`` on floats, the log-uniforms through :func:`_log_uniform`'s ufunc, all three in one call)."""
    tab = _scalar_table(config.objects.class_items, config.objects.catalogue)
    cid = min(bisect.bisect_right(tab.cumulative, u[0]), tab.last)  # np.searchsorted(..., side="right")
    (m_lo, m_hi), (d_lo, d_hi), (f_lo, f_hi) = tab.shear_modulus_kpa[cid], tab.density_kg_m3[cid], \
        tab.failure_stress_kpa[cid]
    p_mu, p_rho, p_fs = np.power([m_hi / m_lo, d_hi / d_lo, f_hi / f_lo], [u[1], u[4], u[6]]).tolist()
    mu, rho, fs = m_lo * p_mu, d_lo * p_rho, f_lo * p_fs
    (r_lo, r_hi), (h_lo, h_hi), (e_lo, e_hi) = tab.radius_mm[cid], tab.thickness_mm[cid], tab.failure_strain[cid]
    values = {
        "object_shear_modulus_kpa": mu,
        "object_curvature_per_m": 1e3 / (r_lo + (r_hi - r_lo) * u[2]),
        "object_thickness_mm": h_lo + (h_hi - h_lo) * u[3],
        "object_density_kg_m3": rho,
        "object_failure_strain": e_lo + (e_hi - e_lo) * u[5],
    }
    if tab.has_length:
        l_lo, l_hi = tab.length_mm[cid]
        length = l_lo + (l_hi - l_lo) * u[7]
    else:
        length = 0.0
    return values, cid, fs, tab.shape[cid], length


def _catalogue_values(u: np.ndarray, config: EnvConfig) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """The properties of catalogue objects from their uniforms ``u`` (``(7,) + shape``), their extra fields and their
    lengths (mm; 0 where no class is a cylinder), as arrays (one object's: :func:`_one_catalogue_values`). The mass
    is the caller's: it follows the object's size and density after any pin."""
    tab = config.objects.table
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
    extra = {"failure_stress_kpa": log_uniform(tab.failure_stress_kpa, u[6]), "class_id": cid.astype(np.int64)}
    return values, extra, length


def object_from_uniforms(
    u: np.ndarray, config: EnvConfig, pinned: Mapping[str, Any] | None = None, batch: bool | None = None
) -> GraspObject:
    """The object of the uniform draws ``u`` (shape ``(5,)``: one object; ``(5,) + shape``: a batch).

    The pure half of :func:`sample_object` (which is ``object_from_uniforms(rng.random((5,) + shape), ...)``):
    a batched environment draws ``u`` from each sub-environment's own stream and maps them here.
    ``batch=None`` infers it from ``u.ndim``; ``batch=True`` with ``u.shape == (5,)`` gives 0-d array fields.
    A batch is computed with array operations (no loop over objects); one object (``batch=False``) in float
    arithmetic (:func:`_one_object`: a reset's draw in a few microseconds). The two give the same bits on one install
    (both go through :func:`_log_uniform`'s ufunc; ``+ - * /`` round alike on floats and in numpy). Across machines
    they may differ in the last bit: numpy picks ``power``'s kernel by the CPU's SIMD level (AVX-512 or not).
    """
    u = np.asarray(u, dtype=float)
    n_draws = draw_count(config)
    if u.ndim == 0 or u.shape[0] != n_draws:
        raise ValueError(f"u must have shape ({n_draws},) + batch shape, got {u.shape}")
    shape = u.shape[1:]
    if batch is None:
        batch = bool(shape)
    pins = _checked_pins(pinned)
    if not batch:
        if shape:
            raise ValueError(f"batch=False draws one object: u must have shape ({n_draws},), got {u.shape}")
        return _one_object(u.tolist(), config, pins)
    extra: dict[str, Any] | None = None
    if config.objects.from_catalogue:
        values, extra, length = _catalogue_values(u, config)
    else:
        values = {name: _log_uniform(lo, hi, u[i]) if name in LOG_UNIFORM_FIELDS else lo + (hi - lo) * u[i]
                  for i, (name, (lo, hi)) in enumerate(_ranges(config))}
    _apply_pins(values, pins, config, shape)
    common = _material_args(values, config)
    try:
        if "object_stiffness" in pins:
            obj = _batch_object(None, _pin("object_stiffness", pins["object_stiffness"], shape, True), **common)
        else:
            obj = _batch_object(values["object_shear_modulus_kpa"], None, **common)
    except ValueError as exc:
        _raise_naming_pins(exc, pins)
    if extra is None:
        return _with_shape(obj, config)
    # the class's shape, the object's size and density (pinned or drawn)
    extra["mass_kg"] = np.asarray(object_mass_kg(config.objects.table.shape[extra["class_id"]],
                                                 1e3 / np.asarray(obj.curvature_per_m), obj.density_kg_m3,
                                                 length_mm=length), dtype=float)
    return dataclasses.replace(obj, **extra)


def _one_object(u: list[float], config: EnvConfig, pins: dict[str, Any]) -> GraspObject:
    """:func:`object_from_uniforms` of one object, from its uniforms as floats: the same numbers, checks and messages
    as the batch path, in float arithmetic (no numpy but :func:`_log_uniform`'s ufunc, one call for the object)."""
    catalogue = config.objects.from_catalogue
    if catalogue:
        values, cid, failure_stress, code, length = _one_catalogue_values(u, config)
    else:
        ranges = _ranges(config)
        values = {name: lo + (hi - lo) * x for (name, (lo, hi)), x in zip(ranges, u, strict=True)}
        logs = [i for i, (name, _) in enumerate(ranges) if name in LOG_UNIFORM_FIELDS]
        powers = np.power([ranges[i][1][1] / ranges[i][1][0] for i in logs], [u[i] for i in logs]).tolist()
        for i, p in zip(logs, powers, strict=True):
            name, (lo, _) = ranges[i]
            values[name] = lo * p  # _log_uniform: lo (hi/lo)^x
    if pins:
        _apply_pins(values, pins, config, None)
    try:
        if "object_stiffness" in pins:
            obj = GraspObject.from_stiffness(_pin("object_stiffness", pins["object_stiffness"], ()),
                                             **_material_args(values, config))
            fields = dataclasses.asdict(obj)
        else:
            fields = _material_fields(values["object_shear_modulus_kpa"], values["object_thickness_mm"],
                                      values["object_curvature_per_m"], values["object_density_kg_m3"],
                                      values["object_failure_strain"], config.scales)
    except ValueError as exc:
        _raise_naming_pins(exc, pins)
    if catalogue:  # the class's own failure stress, and the mass of its shape
        fields["failure_stress_kpa"], fields["class_id"] = failure_stress, cid
        fields["mass_kg"] = _mass_one(code, 1e3 / fields["curvature_per_m"], fields["density_kg_m3"], 0.0, length)
    elif config.objects.shape != "sphere":
        fields["mass_kg"] = _mass_one(SHAPES.index(config.objects.shape), 1e3 / fields["curvature_per_m"],
                                      fields["density_kg_m3"], fields["thickness_mm"], float(_length_mm(config)))
    return GraspObject._of(fields)


def _ranges(config: EnvConfig) -> tuple[tuple[str, tuple[float, float]], ...]:
    """``(name, (lo, hi))`` of each of :data:`~pneunet_env.config.RANGE_FIELDS`, in its order."""
    return tuple((name, getattr(config.objects, name)) for name in RANGE_FIELDS)


def _checked_pins(pinned: Mapping[str, Any] | None) -> dict[str, Any]:
    """The pins given (``None`` values dropped); ``ValueError`` for an unknown key or two that conflict."""
    pins = {k: v for k, v in (pinned or {}).items() if v is not None}
    if not pins:
        return pins
    unknown = sorted(set(pins) - set(PIN_KEYS))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; valid: {list(PIN_KEYS)}")
    if "object_stiffness" in pins and "object_shear_modulus_kpa" in pins:
        raise ValueError("reset options 'object_stiffness' and 'object_shear_modulus_kpa' conflict: pin one")
    if "object_curvature" in pins and "object_curvature_per_m" in pins:
        raise ValueError("reset options 'object_curvature' and 'object_curvature_per_m' conflict: pin one")
    return pins


def _apply_pins(values: dict[str, Any], pins: dict[str, Any], config: EnvConfig, shape: tuple[int, ...] | None):
    """Replace the drawn ``values`` by the pinned ones (``shape``: the batch's, ``None`` for one object: floats)."""
    batch = shape is not None
    for key in ("object_shear_modulus_kpa", "object_thickness_mm", "object_curvature_per_m",
                "object_density_kg_m3", "object_failure_strain"):
        if key in pins:
            values[key] = _pin(key, pins[key], shape or (), batch)
    if "object_curvature" in pins:
        values["object_curvature_per_m"] = _pin("object_curvature", pins["object_curvature"], shape or (), batch) / (
            config.actuator.width_mm * 1e-3
        )


def _material_args(values: dict[str, Any], config: EnvConfig) -> dict[str, Any]:
    """The keyword arguments, but the modulus or stiffness, of ``GraspObject.from_material`` (or its batch twin)."""
    return dict(
        thickness_mm=values["object_thickness_mm"],
        curvature_per_m=values["object_curvature_per_m"],
        density_kg_m3=values["object_density_kg_m3"],
        failure_strain=values["object_failure_strain"],
        scales=config.scales,
    )


def _raise_naming_pins(exc: ValueError, pins: dict[str, Any]) -> NoReturn:
    """Raise ``exc``, naming the pins when there are some (a pin that does not fit the drawn object)."""
    if pins and not str(exc).startswith("reset option"):
        raise ValueError(f"reset option(s) {sorted(pins)}: {exc}") from None
    raise exc


def _with_shape(obj: GraspObject, config: EnvConfig) -> GraspObject:
    """``obj`` (drawn from the config's ranges, a solid sphere's mass) with the mass of the config's ``shape``."""
    oc = config.objects
    if oc.shape == "sphere":
        return obj
    mass = object_mass_kg(oc.shape, 1e3 / np.asarray(obj.curvature_per_m), obj.density_kg_m3, obj.thickness_mm,
                          _length_mm(config))
    return dataclasses.replace(obj, mass_kg=mass)


def _length_mm(config: EnvConfig):
    """The length (mm) of an object drawn from ranges: ``objects.object_length_mm``, else the finger's width."""
    oc = config.objects
    return oc.object_length_mm if oc.object_length_mm is not None else config.actuator.finger_width_mm


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
    if isinstance(wrap, float) or not np.ndim(wrap):  # one object (a float first: no numpy call on a reset's path)
        return min(params.finger_length_mm, float(wrap))
    return wrap.clip(max=params.finger_length_mm)


def warn_if_beyond_convergence(obj: GraspObject, warned: bool = False) -> bool:
    """Warn (once: pass and keep the returned flag) if an object's contact is stiffer than any at which the solver
    was measured to converge (:data:`pneunet_env.physics.contact.CONVERGED_CONTACT_RATIO`). Returns the flag."""
    if warned:
        return True
    if type(obj.stiffness) is float:  # one object: the same 0-d power as a batch's element, without the reduction
        ratio = contact_ratio(obj.stiffness, np.asarray(obj.curvature))
    else:
        ratio = np.max(contact_ratio(np.asarray(obj.stiffness), np.asarray(obj.curvature)))
    if ratio > CONVERGED_CONTACT_RATIO:
        warnings.warn(
            f"object with k~/(w kappa_obj)^4 = {ratio:.3g} beyond {CONVERGED_CONTACT_RATIO:g}, the largest at which "
            "the solver was measured to converge: steps may be flagged unconverged (info['solver_failed'])",
            UserWarning, stacklevel=3,
        )
        return True
    return False

