"""Every parameter of ``PneuNetGrasp-v0``, in physical units, validated; YAML loading.

:class:`EnvConfig` is a frozen dataclass: lengths in mm, pressures and moduli in kPa, densities in
kg/m^3, curvatures in 1/m. The environment converts them once, at construction, to the dimensionless
model (lengths / ``w``, stresses / ``mu``; see :mod:`pneunet_env.physics.units`). ``configs/env/default.yaml``
lists every field with its unit and a comment, and equals ``EnvConfig()`` (a test keeps them in step).

Object properties are ranges ``[low, high]`` sampled per episode (:func:`pneunet_env.task.sample_object`);
``low == high`` fixes the property, and a single number is read as such a range.

Load with :func:`load_config`: ``None`` (defaults), a mapping, a YAML path or an :class:`EnvConfig`,
then keyword overrides. An unknown key or an invalid value raises ``ValueError`` naming it.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from pneunet_env.physics.models import MODELS
from pneunet_env.physics.params import ActuatorParams, check_finite
from pneunet_env.physics.solver import SolverOptions
from pneunet_env.physics.units import PhysicalActuator, Scales

__all__ = ["EnvConfig", "load_config", "DEFAULT_CONFIG_PATH", "RANGE_FIELDS", "LOG_UNIFORM_FIELDS"]

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parents[1] / "configs" / "env" / "default.yaml"
"""``configs/env/default.yaml`` in a source checkout (the same values as ``EnvConfig()``)."""

RANGE_FIELDS = (
    "object_shear_modulus_kpa",
    "object_thickness_mm",
    "object_curvature_per_m",
    "object_density_kg_m3",
    "object_failure_strain",
)
"""The object's properties: ``(low, high)`` ranges, sampled once per episode."""

LOG_UNIFORM_FIELDS = ("object_shear_modulus_kpa", "object_density_kg_m3")
"""Ranges sampled log-uniformly (the others uniformly)."""

_INT_FIELDS = ("squeeze_steps", "hold_steps", "grip_faces", "render_width", "render_height", "render_chambers",
               "solver_max_iter", "solver_corrector_max_iter")
_BOOL_FIELDS = ("observe_volume", "terminate_on_damage", "terminate_on_slip")


@dataclass(frozen=True)
class EnvConfig:
    """All parameters of the environment (physical units at this edge). See ``configs/env/default.yaml``.

    Actuator (supplement Table 1): ``width_mm`` (w), ``chamber_height_mm`` (d), ``depth_mm`` (t),
    ``base_thickness_mm`` (h_b), ``side_thickness_mm`` (h_s), ``top_thickness_mm`` (h_m),
    ``shear_modulus_kpa`` (mu), ``base_modulus_kpa`` (E_b), ``poisson_ratio`` (nu), ``gent_limit`` (J).

    Control: ``max_pressure_kpa`` (p_max), ``max_pressure_step_kpa`` (pressure change per step at
    ``|action| = 1``). Task: ``squeeze_steps``, ``hold_steps``. Object ranges: see :data:`RANGE_FIELDS`.
    Damage and slip: ``crush_fraction``, ``friction_coefficient``, ``grip_faces``, ``gravity_m_s2``.
    Reward: ``reward_hold``, ``reward_success``, ``penalty_damage``, ``penalty_slip``. Episode ends:
    ``terminate_on_damage``, ``terminate_on_slip``. Observation: ``observe_volume``. Render:
    ``render_width``, ``render_height``, ``render_chambers``. Solver: ``solver_*`` (dimensionless, see
    :class:`pneunet_env.physics.solver.SolverOptions`).
    """

    # actuator (supplement Table 1)
    width_mm: float = 5.0
    chamber_height_mm: float = 5.0
    depth_mm: float = 5.0
    base_thickness_mm: float = 2.5
    side_thickness_mm: float = 2.5
    top_thickness_mm: float = 2.5
    shear_modulus_kpa: float = 50.0
    base_modulus_kpa: float = 3000.0
    poisson_ratio: float = 0.5
    gent_limit: float = 20.0
    # control
    max_pressure_kpa: float = 60.0
    max_pressure_step_kpa: float = 3.0
    # task
    squeeze_steps: int = 50
    hold_steps: int = 50
    # object (ranges, sampled per episode)
    object_shear_modulus_kpa: tuple[float, float] = (0.1, 1500.0)
    object_thickness_mm: tuple[float, float] = (10.0, 10.0)
    object_curvature_per_m: tuple[float, float] = (4.0, 4.0)
    object_density_kg_m3: tuple[float, float] = (1000.0, 1000.0)
    object_failure_strain: tuple[float, float] = (0.3, 0.3)
    # damage and slip
    crush_fraction: float = 1.0
    friction_coefficient: float = 0.5
    grip_faces: int = 2
    gravity_m_s2: float = 9.81
    # reward
    reward_hold: float = 0.02
    reward_success: float = 1.0
    penalty_damage: float = 2.0
    penalty_slip: float = 1.0
    # episode end
    terminate_on_damage: bool = True
    terminate_on_slip: bool = True
    # observation
    observe_volume: bool = False
    # render
    render_width: int = 480
    render_height: int = 360
    render_chambers: int = 6
    # solver (dimensionless; pneunet_env.physics.solver.SolverOptions)
    solver_gtol: float = 1e-11
    solver_max_iter: int = 200
    solver_corrector_max_iter: int = 12
    solver_max_step: float = 0.05
    solver_min_step: float = 1e-9
    solver_max_jump: float = 0.02
    solver_eig_floor: float = 1e-10
    # model size (pneunet_env.physics.models): "full", or "linear"/"auto" (single env only)
    model: str = "full"

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            name, value = f.name, getattr(self, f.name)
            if name == "model":
                if value not in MODELS:
                    raise ValueError(f"config key 'model' must be one of {MODELS}, got {value!r}")
            elif name in RANGE_FIELDS:
                object.__setattr__(self, name, _range(name, value))
            elif name in _BOOL_FIELDS:
                if not isinstance(value, bool):
                    raise ValueError(f"config key {name!r} must be true or false, got {value!r}")
            elif name in _INT_FIELDS:
                object.__setattr__(self, name, _int(name, value, minimum=1))
            else:
                object.__setattr__(self, name, _float(name, value))
        positive = ("width_mm", "chamber_height_mm", "depth_mm", "base_thickness_mm", "side_thickness_mm",
                    "top_thickness_mm", "shear_modulus_kpa", "base_modulus_kpa", "gent_limit", "max_pressure_kpa",
                    "max_pressure_step_kpa", "crush_fraction", "friction_coefficient", "gravity_m_s2",
                    "solver_gtol", "solver_max_step", "solver_min_step", "solver_max_jump", "solver_eig_floor")
        for name in positive:
            if getattr(self, name) <= 0.0:
                raise ValueError(f"config key {name!r} must be > 0, got {getattr(self, name)!r}")
        for name in ("reward_hold", "reward_success", "penalty_damage", "penalty_slip"):
            if getattr(self, name) < 0.0:
                raise ValueError(
                    f"config key {name!r} must be >= 0 (penalties are magnitudes, subtracted), "
                    f"got {getattr(self, name)!r}"
                )
        for name in RANGE_FIELDS:
            lo, hi = getattr(self, name)
            if lo <= 0.0:
                raise ValueError(f"config key {name!r} must be > 0, got range {[lo, hi]!r}")
        if self.max_pressure_step_kpa > self.max_pressure_kpa:
            raise ValueError(
                f"config key 'max_pressure_step_kpa' = {self.max_pressure_step_kpa!r} exceeds "
                f"'max_pressure_kpa' = {self.max_pressure_kpa!r}"
            )
        if self.render_chambers > 12:
            raise ValueError(f"config key 'render_chambers' must be <= 12, got {self.render_chambers!r}")
        if self.render_width < 32 or self.render_height < 32:
            raise ValueError(
                f"config keys 'render_width'/'render_height' must be >= 32 pixels, got "
                f"{self.render_width!r} x {self.render_height!r}"
            )
        # The object must fit the model: H kappa_obj < 1 (eq. 3.2) and w kappa_obj < pi.
        h_hi, c_hi = self.object_thickness_mm[1], self.object_curvature_per_m[1]
        if h_hi * 1e-3 * c_hi >= 1.0:
            raise ValueError(
                f"config keys 'object_thickness_mm' (up to {h_hi!r} mm) and 'object_curvature_per_m' (up to "
                f"{c_hi!r} /m) allow an object thicker than its outer radius (need H kappa_obj < 1)"
            )
        if self.width_mm * 1e-3 * c_hi >= math.pi:
            raise ValueError(
                f"config key 'object_curvature_per_m' (up to {c_hi!r} /m) gives w kappa_obj >= pi for "
                f"width_mm = {self.width_mm!r}"
            )
        # Actuator geometry and solver options are validated by their own classes (names prefixed here).
        try:
            _ = self.actuator_params
        except ValueError as exc:
            raise ValueError(f"config: invalid actuator ({exc})") from None
        try:
            _ = self.solver_options
        except ValueError as exc:
            raise ValueError(f"config: invalid solver_* keys ({exc})") from None

    # ---- derived, dimensionless -------------------------------------------------------------
    @property
    def episode_steps(self) -> int:
        """Steps in an episode: ``squeeze_steps + hold_steps`` (then ``truncated``)."""
        return self.squeeze_steps + self.hold_steps

    @cached_property
    def scales(self) -> Scales:
        """The model's scales: ``w`` (mm) and ``mu`` (kPa)."""
        return Scales(self.width_mm, self.shear_modulus_kpa)

    @cached_property
    def physical_actuator(self) -> PhysicalActuator:
        return PhysicalActuator(
            width_mm=self.width_mm,
            height_mm=self.chamber_height_mm,
            depth_mm=self.depth_mm,
            base_thickness_mm=self.base_thickness_mm,
            side_thickness_mm=self.side_thickness_mm,
            top_thickness_mm=self.top_thickness_mm,
            shear_modulus_kpa=self.shear_modulus_kpa,
            base_modulus_kpa=self.base_modulus_kpa,
            poisson_ratio=self.poisson_ratio,
            gent_limit=self.gent_limit,
        )

    @cached_property
    def actuator_params(self) -> ActuatorParams:
        """The dimensionless actuator (:class:`pneunet_env.physics.params.ActuatorParams`)."""
        return self.physical_actuator.to_dimensionless()

    @cached_property
    def solver_options(self) -> SolverOptions:
        return SolverOptions(
            gtol=self.solver_gtol,
            max_iter=self.solver_max_iter,
            corrector_max_iter=self.solver_corrector_max_iter,
            max_step=self.solver_max_step,
            min_step=self.solver_min_step,
            max_jump=self.solver_max_jump,
            eig_floor=self.solver_eig_floor,
        )

    @property
    def pressure_max(self) -> float:
        """``p~_max = p_max / mu``."""
        return self.max_pressure_kpa / self.shear_modulus_kpa

    @property
    def pressure_step(self) -> float:
        """Largest pressure change per step, ``dp~ = max_pressure_step / mu``."""
        return self.max_pressure_step_kpa / self.shear_modulus_kpa

    # ---- conversion ---------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain values (ranges as lists), in field order; ``EnvConfig(**c.to_dict()) == c``."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if f.name in RANGE_FIELDS else v
        return out

    def replace(self, **changes: Any) -> EnvConfig:
        """A copy with some keys changed (validated; unknown keys raise ``ValueError`` naming them)."""
        return load_config(self, **changes)

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> EnvConfig:
        """Read a YAML file of config keys (any subset; the rest default)."""
        return load_config(Path(path))

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))


def _float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) and not hasattr(value, "__float__"):
        raise ValueError(f"config key {name!r} must be a number, got {value!r}")
    return check_finite(f"config key {name!r}", value)


def _int(name: str, value: Any, minimum: int) -> int:
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
    return i


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


def _read_yaml(path: Path) -> dict[str, Any]:
    import yaml

    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(f"cannot read config file {str(path)!r}: {exc}") from None
    data = yaml.safe_load(text)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping of keys to values, got {type(data).__name__}")
    return data


def load_config(config: EnvConfig | Mapping[str, Any] | str | os.PathLike | None = None, **overrides: Any) -> EnvConfig:
    """Build an :class:`EnvConfig` from defaults, then ``config``, then ``overrides``.

    Args:
        config: ``None`` (defaults), an :class:`EnvConfig`, a mapping of keys, or the path of a YAML file.
        overrides: keys to set on top.

    Raises:
        ValueError: naming an unknown key or an invalid value.
    """
    if config is None:
        base: dict[str, Any] = {}
    elif isinstance(config, EnvConfig):
        base = config.to_dict()
    elif isinstance(config, Mapping):
        base = dict(config)
    elif isinstance(config, (str, os.PathLike)):
        base = _read_yaml(Path(config))
    else:
        raise ValueError(f"config must be None, an EnvConfig, a mapping or a YAML path, got {type(config).__name__}")
    merged = {**base, **overrides}
    valid = set(EnvConfig.keys())
    for key in merged:
        if not isinstance(key, str) or key not in valid:
            raise ValueError(f"unknown config key {key!r}; valid keys: {', '.join(EnvConfig.keys())}")
    return EnvConfig(**merged)
