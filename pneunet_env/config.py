"""Every parameter of ``PneuNetGrasp-v1``, in physical units, validated, in five sections; YAML loading.

:class:`EnvConfig` holds five typed sections, each the object its consumer takes:

===============  =============================================  ==========================================
section          type                                           consumed by
===============  =============================================  ==========================================
``actuator``     :class:`~pneunet_env.physics.units.PhysicalActuator`  the physics (``.to_dimensionless()``)
``objects``      :class:`ObjectConfig`                          the object draw (:mod:`pneunet_env.task`)
``task``         :class:`TaskConfig`                            the rules (:class:`pneunet_env.task.TaskParams`)
``solver``       :class:`~pneunet_env.physics.solver.SolverOptions`  the solver
``render``       :class:`RenderConfig`                          the renderer
===============  =============================================  ==========================================

Units at this edge: lengths in mm, pressures and moduli in kPa, densities in kg/m^3, curvatures in 1/m; the
solver's options are dimensionless. The environment converts once, at construction, to the dimensionless model
(lengths / ``w``, stresses / ``mu``; see :mod:`pneunet_env.physics.units`). ``configs/env/default.yaml`` lists
every key with its unit and a comment, in the same sections, and equals ``EnvConfig()`` (a test keeps them in
step).

Object properties are ranges ``[low, high]`` sampled per episode (:func:`pneunet_env.task.sample_object`);
``low == high`` fixes the property, and a single number is read as such a range.

Load with :func:`load_config`: ``None`` (defaults), a mapping, a YAML path or an :class:`EnvConfig`, then keyword
overrides. A mapping (or YAML file) may be nested by section (``{"task": {"max_pressure_kpa": 40}}``) or flat
(``{"max_pressure_kpa": 40}``): a flat key is a field name (every field name is unique across the sections) or
``SECTION_FIELD`` (``render_width``, ``solver_gtol``). An unknown key or an invalid value raises ``ValueError``
naming it.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property, wraps
from pathlib import Path
from typing import Any

from pneunet_env.physics.params import ActuatorParams, check_finite
from pneunet_env.physics.solver import SolverOptions
from pneunet_env.physics.units import PhysicalActuator, Scales

__all__ = [
    "EnvConfig",
    "ObjectConfig",
    "TaskConfig",
    "RenderConfig",
    "SECTIONS",
    "load_config",
    "flat_key",
    "DEFAULT_CONFIG_PATH",
    "RANGE_FIELDS",
    "LOG_UNIFORM_FIELDS",
    "ConfigTypeError",
]

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parents[1] / "configs" / "env" / "default.yaml"
"""``configs/env/default.yaml`` in a source checkout (the same values as ``EnvConfig()``)."""

RANGE_FIELDS = (
    "object_shear_modulus_kpa",
    "object_thickness_mm",
    "object_curvature_per_m",
    "object_density_kg_m3",
    "object_failure_strain",
)
"""The object's properties: ``(low, high)`` ranges, sampled once per episode (the fields of :class:`ObjectConfig`)."""

LOG_UNIFORM_FIELDS = ("object_shear_modulus_kpa", "object_density_kg_m3")
"""Ranges sampled log-uniformly (the others uniformly)."""


class ConfigTypeError(TypeError, ValueError):
    """A config value of the wrong type (``"no"`` where ``true``/``false`` belongs): a ``TypeError``, and also the
    ``ValueError`` that :func:`load_config` documents, so that either ``except`` catches it."""


def check_bool(name: str, value: Any) -> bool:
    """``value`` if it is a boolean (Python's or numpy's), as ``bool``; else :class:`ConfigTypeError` naming ``name``
    and ``value`` (a string such as ``"no"``, ``"yes"`` or ``"false"``, and ``1`` or ``0``, are refused, never read as
    a boolean).

    The one rule for a boolean key, wherever it is typed: ``true`` or ``false`` in a YAML file and in ``--set``
    (:mod:`pneunet_env.yamlio` refuses YAML 1.1's ``yes``/``no``/``on``/``off`` there), ``True`` or ``False`` as a
    keyword argument."""
    if type(value).__name__ in ("bool", "bool_"):
        return bool(value)
    kind = {str: "a string", int: "an integer", float: "a number", type(None): "null"}.get(type(value),
                                                                                      type(value).__name__)
    raise ConfigTypeError(f"config key {name!r} must be true or false, got {value!r} ({kind}): write true or false")


def check_class_weights(name: str, value: Any) -> dict[str, float]:
    """``{class: weight}`` checked: class names are strings; each weight a finite number >= 0 (not a boolean); not
    all zero; and their sum finite (``{"apple": 1e308, "kiwifruit": 1e308}`` overflows it). ``ValueError`` (a wrong
    type: :class:`ConfigTypeError`) naming ``name`` and the class."""
    if not isinstance(value, Mapping) or not value:
        raise ConfigTypeError(f"config key {name!r} must be a mapping of class names to weights, or null, got "
                              f"{value!r}")
    out: dict[str, float] = {}
    for k, v in value.items():
        if not isinstance(k, str):
            raise ConfigTypeError(f"config key {name!r}: class names must be strings, got {k!r}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) and not hasattr(v, "__float__"):
            raise ConfigTypeError(f"config key {name!r}: the weight of {k!r} must be a number, got {v!r}")
        try:
            w = float(v)
        except (TypeError, ValueError, OverflowError):
            raise ConfigTypeError(f"config key {name!r}: the weight of {k!r} must be a number, got {v!r}") from None
        if not math.isfinite(w) or w < 0.0:
            raise ValueError(f"config key {name!r}: the weight of {k!r} must be a finite number >= 0, got {v!r}")
        out[k] = w
    total = sum(out.values())
    if not total > 0.0:
        raise ValueError(f"config key {name!r}: the weights must not all be zero, got {dict(value)!r}")
    if not math.isfinite(total):
        raise ValueError(f"config key {name!r}: the weights sum past the largest float ({dict(value)!r}); scale "
                         "them down (only their ratios count)")
    return out


@dataclass(frozen=True)
class ObjectConfig:
    """The objects an episode draws from: catalogue classes, or ``(low, high)`` ranges (physical units).

    With ``use_case`` (a use case of the catalogue, :mod:`pneunet_env.catalogue`) or ``class_weights`` (``{class:
    weight}``) an episode draws a class by weight, then its properties from the class's literature ranges (modulus
    and density log-uniform, the rest uniform); the ranges below are then not used. With both ``None`` the ranges
    are sampled, as in the paper's task.

    Attributes:
        object_shear_modulus_kpa: ``mu_obj`` (kPa), log-uniform.
        object_thickness_mm: ``H`` (mm), uniform.
        object_curvature_per_m: the outer curvature ``kappa_obj`` (1/m), uniform.
        object_density_kg_m3: ``rho`` (kg/m^3), log-uniform.
        object_failure_strain: ``eps_f``, uniform: the object fails at a stress ``eps_f E_obj = 3 eps_f mu_obj``.
        use_case: a use case of the catalogue (``kitchen``, ``lab_bench``, ...), or ``None``.
        class_weights: ``{class: weight}`` (overrides ``use_case``), or ``None``.
        catalogue: a path to the user's own catalogue file, in ``pneunet_env/data/objects.yaml``'s format (its classes
            may lack sources: the outputs then say "unsourced"); ``use_case`` and ``class_weights`` then name its use
            cases and classes. ``None``: the packaged catalogue.
        shape: the 3D shape of an object drawn from the ranges, which sets its mass
            (:func:`pneunet_env.objects.object_mass_kg`): ``"sphere"`` of radius ``1/kappa_obj``, ``"cylinder"`` or
            ``"ring"`` (eq. 3.2's annulus, the paper's) of height ``object_length_mm``. A catalogue class has its own.
        object_length_mm: the cylinder's or ring's height (mm); ``None``: the finger's width, the height the finger
            touches. A sphere has none.
    """

    @property
    def from_catalogue(self) -> bool:
        """Whether objects are drawn from the catalogue's classes (else from the ranges)."""
        return self.use_case is not None or self.class_weights is not None

    @cached_property
    def class_items(self) -> tuple[tuple[str, float], ...]:
        """``((class, weight), ...)`` of the catalogue draw (``class_weights``, else the use case's)."""
        if self.class_weights is not None:
            return tuple(self.class_weights.items())
        from pneunet_env.catalogue import use_case_weights

        return tuple(use_case_weights(self.use_case, self.catalogue).items())

    @property
    def table(self):
        """The :class:`~pneunet_env.catalogue.ClassTable` the objects are drawn from (of :attr:`class_items`, in the
        packaged catalogue or the user's :attr:`catalogue`)."""
        from pneunet_env.catalogue import class_table

        return class_table(self.class_items, self.catalogue)

    object_shear_modulus_kpa: tuple[float, float] = (0.1, 1500.0)
    object_thickness_mm: tuple[float, float] = (10.0, 10.0)
    object_curvature_per_m: tuple[float, float] = (4.0, 4.0)
    object_density_kg_m3: tuple[float, float] = (1000.0, 1000.0)
    object_failure_strain: tuple[float, float] = (0.3, 0.3)
    use_case: str | None = "kitchen"
    class_weights: dict[str, float] | None = None
    shape: str = "sphere"
    object_length_mm: float | None = None
    catalogue: str | None = None

    def __post_init__(self) -> None:
        from pneunet_env.objects import SHAPES

        if self.catalogue is not None:
            if not isinstance(self.catalogue, (str, os.PathLike)) or not str(self.catalogue).strip():
                raise ConfigTypeError(f"config key 'catalogue' must be a path to a catalogue file or null, got "
                                      f"{self.catalogue!r}")
            object.__setattr__(self, "catalogue", str(Path(self.catalogue).expanduser().resolve()))

        if self.shape not in SHAPES:
            raise ValueError(f"config key 'shape' must be one of {SHAPES}, got {self.shape!r}")
        if self.object_length_mm is not None:
            if self.shape == "sphere":
                raise ValueError(f"config key 'object_length_mm' = {self.object_length_mm!r} is a cylinder's or a "
                                 "ring's height; a sphere has none (set it to null, or the shape)")
            if isinstance(self.object_length_mm, bool) or not isinstance(self.object_length_mm, (int, float)) or \
                    not math.isfinite(self.object_length_mm) or self.object_length_mm <= 0.0:
                raise ValueError(f"config key 'object_length_mm' must be a finite number > 0 (mm) or null, got "
                                 f"{self.object_length_mm!r}")
        if self.use_case is not None and not isinstance(self.use_case, str):
            raise ConfigTypeError(f"config key 'use_case' must be a string or null, got {self.use_case!r}")
        if self.class_weights is not None:
            object.__setattr__(self, "class_weights", check_class_weights("class_weights", self.class_weights))
        if self.use_case is not None or self.class_weights is not None:
            from pneunet_env.catalogue import class_table, load_use_cases

            if self.class_weights is None:
                cases = load_use_cases(self.catalogue)
                if self.use_case not in cases:
                    where = "" if self.catalogue is None else f" of the catalogue {self.catalogue!r}"
                    raise ValueError(f"config key 'use_case' must be one of {sorted(cases)}{where} or null (the ranges "
                                     f"below), got {self.use_case!r}")
            try:
                class_table(self.class_items, self.catalogue)
            except ValueError as exc:
                raise ValueError(f"config key 'class_weights': {exc}") from None
        for name in RANGE_FIELDS:
            lo, hi = getattr(self, name)
            if lo <= 0.0:
                raise ValueError(f"config key {name!r} must be > 0, got range {[lo, hi]!r}")
        # The object must fit the model: H kappa_obj < 1 (eq. 3.2).
        h_hi, c_hi = self.object_thickness_mm[1], self.object_curvature_per_m[1]
        if self.from_catalogue:
            return
        if h_hi * 1e-3 * c_hi >= 1.0:
            raise ValueError(
                f"config keys 'object_thickness_mm' (up to {h_hi!r} mm) and 'object_curvature_per_m' (up to "
                f"{c_hi!r} /m) allow an object thicker than its outer radius (need H kappa_obj < 1)"
            )


@dataclass(frozen=True)
class TaskConfig:
    """The task: control, episode, damage and slip, reward, episode end, observation (physical units).

    Attributes:
        max_pressure_kpa: ``p_max``: the pressure is kept in ``[0, p_max]``.
        max_pressure_step_kpa: the pressure change per step at ``|action| = 1``.
        squeeze_steps: steps with the object on its support (damage checked, slip not).
        hold_steps: steps with the object lifted (slip checked); then the episode truncates.
        crush_fraction: crushed through when the indentation exceeds ``crush_fraction H``.
        friction_coefficient: ``mu_f`` between the actuator and the object.
        grip_faces: fingers sharing the weight (a two-sided pinch: 2).
        gravity_m_s2: ``g``.
        hold_rule: ``"weight"``: held while ``grip_faces mu_f N >= m g``, the object's weight (its 3D mass) carried
            by friction on the fingers' contact, ``N = F L_c b`` (the traction over the contact length ``L_c`` and
            the finger's width ``b``); ``"slab"``: held while ``F >= rho g H / (grip_faces mu_f)``, a slab of depth
            ``H`` (``PneuNetGrasp-v1``'s rule). See ``docs/env.md``, "The hold rule".
        reward_hold, reward_success, penalty_damage, penalty_slip: the reward's terms (>= 0; penalties subtracted).
        terminate_on_damage, terminate_on_slip: whether damage / a drop ends the episode.
        observe_volume: add the chamber's volume change (a flow sensor) to the observation.
        damage_rule: ``"hoop_strain"``: crushed when the hoop strain ``delta kappa_obj`` exceeds the object's failure
            strain, overstressed when the traction exceeds its failure stress (eq. 3.2's annulus, whose indentation
            shrinks the whole ring); ``"crush_fraction"``: crushed when ``delta > crush_fraction H``, overstressed
            when ``F > 3 eps_f mu_obj`` (the paper-task rule). See ``docs/env.md``.
    """

    max_pressure_kpa: float = 60.0
    max_pressure_step_kpa: float = 3.0
    squeeze_steps: int = 50
    hold_steps: int = 50
    crush_fraction: float = 1.0
    friction_coefficient: float = 0.5
    grip_faces: int = 2
    gravity_m_s2: float = 9.81
    reward_hold: float = 0.02
    reward_success: float = 1.0
    penalty_damage: float = 2.0
    penalty_slip: float = 1.0
    terminate_on_damage: bool = True
    terminate_on_slip: bool = True
    observe_volume: bool = False
    damage_rule: str = "hoop_strain"
    hold_rule: str = "weight"

    def __post_init__(self) -> None:
        for name in BOOL_FIELDS:
            check_bool(name, getattr(self, name))
        if self.damage_rule not in DAMAGE_RULES:
            raise ValueError(f"config key 'damage_rule' must be one of {DAMAGE_RULES}, got {self.damage_rule!r}")
        if self.hold_rule not in HOLD_RULES:
            raise ValueError(f"config key 'hold_rule' must be one of {HOLD_RULES}, got {self.hold_rule!r}")
        for name in ("max_pressure_kpa", "max_pressure_step_kpa", "crush_fraction", "friction_coefficient",
                     "gravity_m_s2"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"config key {name!r} must be > 0, got {getattr(self, name)!r}")
        for name in ("reward_hold", "reward_success", "penalty_damage", "penalty_slip"):
            if getattr(self, name) < 0.0:
                raise ValueError(
                    f"config key {name!r} must be >= 0 (penalties are magnitudes, subtracted), "
                    f"got {getattr(self, name)!r}"
                )
        if self.max_pressure_step_kpa > self.max_pressure_kpa:
            raise ValueError(
                f"config key 'max_pressure_step_kpa' = {self.max_pressure_step_kpa!r} exceeds "
                f"'max_pressure_kpa' = {self.max_pressure_kpa!r}"
            )

    @property
    def episode_steps(self) -> int:
        """Steps in an episode: ``squeeze_steps + hold_steps`` (then ``truncated``)."""
        return self.squeeze_steps + self.hold_steps


BOOL_FIELDS = ("terminate_on_damage", "terminate_on_slip", "observe_volume")
""":class:`TaskConfig`'s boolean keys: ``true`` or ``false``, never a string (the solver section's one,
``free_table``, is checked by :class:`~pneunet_env.physics.solver.SolverOptions`)."""

DAMAGE_RULES = ("hoop_strain", "crush_fraction")
"""The damage rules (:class:`TaskConfig` ``damage_rule``)."""

HOLD_RULES = ("weight", "slab")
"""The hold rules (:class:`TaskConfig` ``hold_rule``): the object's weight (``PneuNetGrasp-v1``), or a slab of depth
``H`` (``PneuNetGrasp-v1``)."""

MAX_RENDER_PIXELS = 4096
"""Largest ``render.width`` / ``render.height`` (a frame is drawn supersampled in memory)."""


@dataclass(frozen=True)
class RenderConfig:
    """The picture: ``width`` x ``height`` pixels, ``chambers`` chambers drawn (the model is one unit cell)."""

    width: int = 480
    height: int = 360
    chambers: int = 6

    def __post_init__(self) -> None:
        if self.chambers > 12:
            raise ValueError(f"config key 'render.chambers' must be <= 12, got {self.chambers!r}")
        for name in ("width", "height"):
            v = getattr(self, name)
            if not 32 <= v <= MAX_RENDER_PIXELS:
                raise ValueError(f"config key 'render.{name}' must be in [32, {MAX_RENDER_PIXELS}] pixels, got {v!r}")


SECTIONS: dict[str, type] = {
    "actuator": PhysicalActuator,
    "objects": ObjectConfig,
    "task": TaskConfig,
    "solver": SolverOptions,
    "render": RenderConfig,
}
"""The config's sections and their types, in order."""


def _section_fields() -> dict[str, tuple[str, str]]:
    """Flat key -> ``(section, field)``: every field by its own name, and as ``SECTION_FIELD``."""
    out: dict[str, tuple[str, str]] = {}
    for section, cls in SECTIONS.items():
        for f in dataclasses.fields(cls):
            if f.name in out:  # pragma: no cover - a test keeps field names unique across sections
                raise RuntimeError(f"config field {f.name!r} is in two sections")
            out[f.name] = (section, f.name)
    for section, cls in SECTIONS.items():
        for f in dataclasses.fields(cls):
            out.setdefault(f"{section}_{f.name}", (section, f.name))
    return out


FLAT_KEYS = _section_fields()


def flat_key(key: str) -> tuple[str, str]:
    """``(section, field)`` of a flat config key; ``ValueError`` naming an unknown one, with the closest valid keys
    (``did you mean 'max_pressure_kpa'?``), or, where none is close, every valid key."""
    try:
        return FLAT_KEYS[key]
    except (KeyError, TypeError):
        close = closest_keys(key)
        if close:
            where = "; ".join(f"{k!r} (section {FLAT_KEYS[k][0]!r})" for k in close)
            raise ValueError(f"unknown config key {key!r}; did you mean {where}?") from None
        valid = ", ".join(f"{s}.{f.name}" for s, c in SECTIONS.items() for f in dataclasses.fields(c))
        raise ValueError(f"unknown config key {key!r}; valid keys: {valid}") from None


def closest_keys(key: Any, n: int = 3) -> list[str]:
    """The valid flat keys closest to the unknown ``key`` (:func:`difflib.get_close_matches`, best first; at most
    ``n``): a misspelling (``max_presure_kpa``), another case (``Observe_Volume``) or a dotted path
    (``task.max_pressure_kpa``, ``render.width``) finds its key. ``[]`` where none is close."""
    import difflib

    if not isinstance(key, str):
        return []
    fields = [k for k, (_, f) in FLAT_KEYS.items() if k == f]  # the field names; SECTION_FIELD only where it is close
    text = key.strip().lower()
    dotted = text.replace(".", "_")
    exact = [k for k in (text, dotted, text.rpartition(".")[2]) if k in FLAT_KEYS]
    if exact:
        return [FLAT_KEYS[exact[0]][1]]
    close = difflib.get_close_matches(text, fields, n=n, cutoff=0.75)
    return close or difflib.get_close_matches(dotted, list(FLAT_KEYS), n=n, cutoff=0.75)


@dataclass(frozen=True)
class EnvConfig:
    """All parameters of the environment, in five typed sections (physical units at this edge).

    ``configs/env/default.yaml`` lists every key. Each section is the object its consumer takes: ``actuator``
    the physics, ``objects`` the object draw, ``task`` the rules, ``solver`` the solver, ``render`` the renderer.
    """

    actuator: PhysicalActuator = field(default_factory=PhysicalActuator)
    objects: ObjectConfig = field(default_factory=ObjectConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    solver: SolverOptions = field(default_factory=SolverOptions)
    render: RenderConfig = field(default_factory=RenderConfig)

    def __post_init__(self) -> None:
        for section, cls in SECTIONS.items():
            if not isinstance(getattr(self, section), cls):
                raise ValueError(f"config section {section!r} must be a {cls.__name__}, got "
                                 f"{type(getattr(self, section)).__name__}")
        c_hi = self.objects.object_curvature_per_m[1]
        if self.objects.from_catalogue:  # the smallest object the classes allow
            c_hi = 1e3 / float(min(self.objects.table.radius_mm[0]))
        if self.actuator.width_mm * 1e-3 * c_hi >= math.pi:
            source = "the catalogue's classes" if self.objects.from_catalogue else "config key 'object_curvature_per_m'"
            raise ValueError(
                f"{source} (curvature up to {c_hi:g} /m) give w kappa_obj >= pi for config key "
                f"'width_mm' = {self.actuator.width_mm!r}: the actuator's cell is wider than the object's arc allows"
            )
        try:  # the dimensionless actuator validates the geometry (a cavity must remain)
            _ = self.actuator_params
        except ValueError as exc:
            raise ValueError(f"config: invalid actuator ({exc})") from None

    # ---- derived, dimensionless -------------------------------------------------------------
    @property
    def episode_steps(self) -> int:
        """Steps in an episode: ``squeeze_steps + hold_steps`` (then ``truncated``)."""
        return self.task.episode_steps

    @cached_property
    def scales(self) -> Scales:
        """The model's scales: ``w`` (mm) and ``mu`` (kPa)."""
        return self.actuator.scales

    @cached_property
    def actuator_params(self) -> ActuatorParams:
        """The dimensionless actuator (:class:`pneunet_env.physics.params.ActuatorParams`)."""
        return self.actuator.to_dimensionless()

    @property
    def pressure_max(self) -> float:
        """``p~_max = p_max / mu``."""
        return self.task.max_pressure_kpa / self.actuator.shear_modulus_kpa

    @property
    def pressure_step(self) -> float:
        """Largest pressure change per step, ``dp~ = max_pressure_step / mu``."""
        return self.task.max_pressure_step_kpa / self.actuator.shear_modulus_kpa

    # ---- conversion ---------------------------------------------------------------------------
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain nested values (ranges as lists), in section and field order; ``load_config(c.to_dict()) == c``."""
        out: dict[str, dict[str, Any]] = {}
        for section in SECTIONS:
            obj = getattr(self, section)
            out[section] = {f.name: (list(v) if isinstance(v := getattr(obj, f.name), tuple) else
                                     dict(v) if isinstance(v, dict) else v)
                            for f in dataclasses.fields(obj)}
        return out

    def replace(self, **changes: Any) -> EnvConfig:
        """A copy with some keys changed (flat or by section; validated; unknown keys raise ``ValueError``)."""
        return load_config(self, **changes)

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> EnvConfig:
        """Read a YAML file of config keys (any subset, nested by section or flat; the rest default)."""
        return load_config(Path(path))


# ---- value checks by field type -----------------------------------------------------------------------------


def _float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) and not hasattr(value, "__float__"):
        raise ValueError(f"config key {name!r} must be a number, got {value!r}")
    return check_finite(f"config key {name!r}", value)


_INT_MAX = {"grip_faces": 16, "squeeze_steps": 1_000_000, "hold_steps": 1_000_000}
"""Upper bounds of integer keys not bounded by their section (a pinch has a few faces; an episode a bounded length)."""


def _int(name: str, value: Any, minimum: int = 1) -> int:
    if isinstance(value, bool):
        raise ValueError(f"config key {name!r} must be an integer, got {value!r}")
    try:
        i = int(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"config key {name!r} must be an integer, got {value!r}") from None
    if i != value:
        raise ValueError(f"config key {name!r} must be an integer, got {value!r}")
    if i < minimum:
        raise ValueError(f"config key {name!r} must be >= {minimum}, got {value!r}")
    if name in _INT_MAX and i > _INT_MAX[name]:
        raise ValueError(f"config key {name!r} must be <= {_INT_MAX[name]}, got {value!r}")
    return i


def _bool(name: str, value: Any) -> bool:
    return check_bool(name, value)


def _range(name: str, value: Any) -> tuple[float, float]:
    if isinstance(value, (str, bytes)):
        raise ValueError(f"config key {name!r} must be a number or a [low, high] pair, got {value!r}")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        x = _float(name, value)
        return (x, x)
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"config key {name!r} must be a number or a [low, high] pair, got {value!r}") from None
    if len(items) != 2:
        raise ValueError(f"config key {name!r} must be a [low, high] pair, got {value!r}")
    lo, hi = _float(name, items[0]), _float(name, items[1])
    if lo > hi:
        raise ValueError(f"config key {name!r}: low {lo!r} exceeds high {hi!r}")
    return (lo, hi)


def _opt_str(name: str, value: Any) -> str | None:
    if value is None or isinstance(value, str):
        return value
    raise ValueError(f"config key {name!r} must be a string or null, got {value!r}")


def _str(name: str, value: Any) -> str:
    if isinstance(value, str):
        return value
    raise ValueError(f"config key {name!r} must be a string, got {value!r}")


def _opt_float(name: str, value: Any) -> float | None:
    return None if value is None else _float(name, value)


def _weights(name: str, value: Any) -> dict[str, float] | None:
    return None if value is None else check_class_weights(name, value)


_CHECKS = {"float": _float, "int": _int, "bool": _bool, "tuple[float, float]": _range, "str | None": _opt_str,
           "str": _str, "dict[str, float] | None": _weights, "float | None": _opt_float}


def _build_section(section: str, values: Mapping[str, Any]):
    """The section's object from its field values (each checked by its declared type first)."""
    cls = SECTIONS[section]
    kinds = {f.name: f.type for f in dataclasses.fields(cls)}
    checked = {}
    for name, value in values.items():
        if name not in kinds:
            flat_key(name)  # raises, naming it
        checked[name] = _CHECKS[kinds[name]](name, value)
    try:
        return cls(**checked)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith("config") else f"config section {section!r}: {msg}") from None


# ---- loading -----------------------------------------------------------------------------------------------


def _read_yaml(path: Path) -> dict[str, Any]:
    """A config file's mapping (``{}`` if empty), read by :mod:`pneunet_env.yamlio` (duplicate keys refused, YAML 1.1
    and 1.2 numbers, aliases bounded)."""
    from pneunet_env.yamlio import load_yaml_file

    data = load_yaml_file(path, "config file")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping of keys to values, got {type(data).__name__}")
    return data


def _nested(values: Mapping[str, Any], into: dict[str, dict[str, Any]]) -> None:
    """Merge ``values`` (nested by section and/or flat keys) into ``into`` (section -> field -> value)."""
    for key, value in values.items():
        if key in SECTIONS and isinstance(value, Mapping):
            for name, v in value.items():
                if not isinstance(name, str):
                    raise ValueError(f"unknown config key {name!r} in section {key!r}")
                section, fname = flat_key(name) if name not in {f.name for f in dataclasses.fields(SECTIONS[key])} \
                    else (key, name)
                if section != key:
                    raise ValueError(f"config key {name!r} belongs to section {section!r}, not {key!r}")
                into[key][fname] = v
        elif key in SECTIONS and isinstance(value, SECTIONS[key]):
            into[key] = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
        elif key in SECTIONS:
            raise ValueError(f"config section {key!r} must be a mapping of keys, got {value!r}")
        else:
            section, fname = flat_key(key)
            into[section][fname] = value


def _values_cut(build):
    """``build``, whose errors show over-long values cut (:func:`pneunet_env.yamlio.cut_message`: a 200 kB
    ``use_case`` is named by its start and its length, not echoed whole); the error itself is unchanged."""

    @wraps(build)
    def checked(*args: Any, **kwargs: Any):
        try:
            return build(*args, **kwargs)
        except (ValueError, TypeError) as exc:
            from pneunet_env.yamlio import cut_message

            if len(exc.args) == 1 and isinstance(exc.args[0], str) and (cut := cut_message(exc.args[0])) != exc.args[0]:
                exc.args = (cut,)
            raise

    return checked


@_values_cut
def load_config(config: EnvConfig | Mapping[str, Any] | str | os.PathLike | None = None, **overrides: Any) -> EnvConfig:
    """Build an :class:`EnvConfig` from defaults, then ``config``, then ``overrides``.

    Args:
        config: ``None`` (defaults), an :class:`EnvConfig`, a mapping of keys (nested by section, or flat), or the
            path of a YAML file holding such a mapping.
        overrides: keys to set on top (flat names such as ``max_pressure_kpa=40``, or a section's mapping such as
            ``task={"hold_steps": 10}``).

    Raises:
        ValueError: naming an unknown key or an invalid value.
    """
    values: dict[str, dict[str, Any]] = {s: {} for s in SECTIONS}
    if config is None:
        pass
    elif isinstance(config, EnvConfig):
        if not overrides:
            return config
        _nested({s: getattr(config, s) for s in SECTIONS}, values)
    elif isinstance(config, Mapping):
        _nested(config, values)
    elif isinstance(config, (str, os.PathLike)):
        _nested(_read_yaml(Path(config)), values)
    else:
        raise ValueError(f"config must be None, an EnvConfig, a mapping or a YAML path, got {type(config).__name__}")
    _nested(overrides, values)
    return EnvConfig(**{s: _build_section(s, v) for s, v in values.items()})
