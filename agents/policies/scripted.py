"""Scripted, blind pressure schedules for ``PneuNetGrasp-v1``.

Each policy maps the environment's observation (whose first entry is the normalised pressure
``p / p_max``) to an action in ``Box(-1, 1, (1,))``; the environment turns an action ``a`` into the
pressure change ``a * max_pressure_step_kpa``. The policies are deterministic and stateless (the
pressure they read is their only memory), so one instance serves any number of episodes, and
``predict`` accepts a batch of observations as well, like a stable-baselines3 model.

Targets are fractions of ``max_pressure_kpa`` (the observation's units); :meth:`from_kpa` converts.
The same policies drive the rigid gripper of :mod:`pneunet_env.envs.rigid`, whose observation is the jaw's
indentation over its travel: there a target is a fraction of the travel.

Every policy here also has ``begin_episode(info)``, called by :func:`agents.evaluation.episodes.run_episode` with
the ``info`` of ``reset``: a blind policy ignores it (the oracle of :mod:`agents.policies.oracle` reads the
object from it). :func:`load_ramp` reads a ramp saved as JSON by :mod:`agents.search`
(``agents/best_ramp.json`` is the ``best-ramp`` policy). A saved schedule is defined in kPa (mm for the jaw): its
fraction is only another way to write it, so changing ``max_pressure_kpa`` never moves it (:func:`ramp_target`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig
from pneunet_env.files import atomic_write_json
from pneunet_env.yamlio import load_json_file

__all__ = ["LinearRamp", "StepPolicy", "load_ramp", "ramp_target", "save_ramp", "jsonable", "MAX_RAMP_STEPS",
           "SCALES"]

MAX_RAMP_STEPS = 10**9
"""The longest ramp, in steps: far beyond any episode (``squeeze_steps`` and ``hold_steps`` are at most 10**6 each),
and small enough that ``target / n_steps`` is an ordinary float."""


def _check_target(target: Any) -> float:
    """``target`` as a float in ``[0, 1]``; ``TypeError``/``ValueError`` naming it otherwise (NaN and inf too)."""
    if target is None or isinstance(target, (bool, np.bool_, str, bytes)):
        raise TypeError(f"target must be a number (a fraction of max_pressure_kpa in [0, 1]), got {target!r}")
    try:
        value = float(target)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"target must be a number (a fraction of max_pressure_kpa in [0, 1]), got {target!r}") \
            from None
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"target must be a fraction of max_pressure_kpa in [0, 1], got {target!r}")
    return value


def _check_steps(n_steps: Any) -> int:
    """``n_steps`` as an int in ``[1, MAX_RAMP_STEPS]`` (a whole float such as ``40.0`` is accepted); ``TypeError`` or
    ``ValueError`` naming it otherwise (NaN, inf, fractions, booleans, strings, too large)."""
    if n_steps is None or isinstance(n_steps, (bool, np.bool_, str, bytes)):
        raise TypeError(f"n_steps must be an integer in [1, {MAX_RAMP_STEPS}], got {n_steps!r}")
    if isinstance(n_steps, (int, np.integer)):
        n = int(n_steps)
    else:
        try:
            x = float(n_steps)
        except (TypeError, ValueError, OverflowError):
            raise TypeError(f"n_steps must be an integer in [1, {MAX_RAMP_STEPS}], got {n_steps!r}") from None
        if not math.isfinite(x) or x != math.floor(x) or abs(x) > 2 * MAX_RAMP_STEPS:
            raise ValueError(f"n_steps must be an integer in [1, {MAX_RAMP_STEPS}], got {n_steps!r}")
        n = int(x)
    if not 1 <= n <= MAX_RAMP_STEPS:
        raise ValueError(f"n_steps must be an integer in [1, {MAX_RAMP_STEPS}], got {n_steps!r}")
    return n


class _TargetPolicy:
    """Shared plumbing: a target pressure and the env's action scale."""

    def __init__(self, target: float, config: EnvConfig | None = None) -> None:
        target = _check_target(target)
        config = EnvConfig() if config is None else config
        self.target = target
        # the change of p/p_max that an action of 1 makes
        self.step_fraction = config.task.max_pressure_step_kpa / config.task.max_pressure_kpa

    def _next(self, p: np.ndarray) -> np.ndarray:  # the pressure fraction wanted after this step
        raise NotImplementedError

    def __call__(self, observation) -> np.ndarray:
        """The action for one observation (shape ``(1,)``) or a batch (shape ``(N, 1)``), float32."""
        obs = np.asarray(observation, dtype=np.float64)
        p = obs[..., 0]
        change = self._next(p) - p
        # holding: the observation is float32, so the target is seen to within its rounding; an exact 0 holds the
        # pressure (a change inside the rounding would creep the pressure by ~1e-8 a step, and re-solve every step)
        change = np.where(np.abs(change) <= np.spacing(p.astype(np.float32)), 0.0, change)
        return np.clip(change / self.step_fraction, -1.0, 1.0)[..., None].astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """stable-baselines3's ``predict`` signature: ``(action, state)``."""
        return self(observation), state

    def reset(self) -> None:
        """Nothing to reset (stateless); present for symmetry with stateful policies."""

    def begin_episode(self, info: dict[str, Any] | None = None) -> None:
        """Called with ``reset``'s ``info`` at each episode's start; a blind policy ignores it."""


class LinearRamp(_TargetPolicy):
    """Raise the pressure linearly from 0 to ``target`` over ``n_steps`` steps, then hold it.

    Args:
        target: the final pressure, a fraction of ``max_pressure_kpa`` in ``[0, 1]``.
        n_steps: steps to reach it from 0 (an integer in ``[1, MAX_RAMP_STEPS]``). A ramp steeper than the largest
            step (``max_pressure_step_kpa``) is limited by it.
        config: the environment's config (for its action scale); the defaults if ``None``.
    """

    def __init__(self, target: float, n_steps: int, config: EnvConfig | None = None) -> None:
        super().__init__(target, config)
        self.n_steps = _check_steps(n_steps)
        self.increment = self.target / self.n_steps

    @classmethod
    def from_kpa(cls, target_kpa: float, n_steps: int, config: EnvConfig | None = None) -> LinearRamp:
        config = EnvConfig() if config is None else config
        return cls(target_kpa / config.task.max_pressure_kpa, n_steps, config)

    def _next(self, p):
        up = np.minimum(p + self.increment, self.target)
        return np.where(p <= self.target, up, self.target)

    def __repr__(self) -> str:
        return f"LinearRamp(target={self.target:g}, n_steps={self.n_steps})"

    def to_dict(self) -> dict[str, Any]:
        """``{"kind": "linear_ramp", "target": ..., "n_steps": ...}`` (``target`` a fraction of the maximum)."""
        return {"kind": "linear_ramp", "target": self.target, "n_steps": self.n_steps}


class StepPolicy(_TargetPolicy):
    """Go to ``target`` as fast as the action allows (a pressure step), then hold it.

    Args:
        target: the pressure, a fraction of ``max_pressure_kpa`` in ``[0, 1]``.
        config: the environment's config (for its action scale); the defaults if ``None``.
    """

    @classmethod
    def from_kpa(cls, target_kpa: float, config: EnvConfig | None = None) -> StepPolicy:
        config = EnvConfig() if config is None else config
        return cls(target_kpa / config.task.max_pressure_kpa, config)

    def _next(self, p):
        return np.full_like(p, self.target)

    def __repr__(self) -> str:
        return f"StepPolicy(target={self.target:g})"

    def to_dict(self) -> dict[str, Any]:
        """``{"kind": "step", "target": ...}``."""
        return {"kind": "step", "target": self.target}


def save_ramp(policy: LinearRamp | StepPolicy, path: str | os.PathLike, **metadata: Any) -> Path:
    """Write ``policy.to_dict()`` and ``metadata`` (how it was found, its score) as JSON; returns the path."""
    data = {**policy.to_dict(), **metadata}
    return atomic_write_json(path, data, default=jsonable)  # written whole or not at all


def jsonable(x: Any) -> Any:
    """``json.dumps``'s ``default``: numpy scalars and arrays, and paths, as plain JSON values."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"cannot write {type(x).__name__} to JSON")


SCALES = {"kPa": ("target_kpa", "max_pressure_kpa"), "mm": ("target_mm", "jaw_travel_mm")}
"""A schedule file's physical target and the full scale a fraction is of, by unit: the pressure (kPa, of
``max_pressure_kpa``) or the rigid jaw's closing (mm, of ``jaw_travel_mm``)."""


def _physical(data: dict[str, Any], key: str, source: str, *, positive: bool = False) -> float | None:
    """``data[key]`` as a finite number (``> 0`` if ``positive``, else ``>= 0``), ``None`` if absent; ``ValueError``
    naming ``source``, the key and the value otherwise."""
    if key not in data:
        return None
    value = data[key]
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= 0 if positive else value < 0):
        raise ValueError(f"{source}: {key} must be a finite number {'> 0' if positive else '>= 0'}, got {value!r}")
    return float(value)


def ramp_target(data: dict[str, Any], source: str, full_scale: float, unit: str = "kPa") -> float:
    """A saved schedule's target, as the fraction of ``full_scale`` that :class:`LinearRamp` and :class:`StepPolicy`
    take (``full_scale``: the running config's ``max_pressure_kpa``, or the jaw travel in mm).

    **A schedule is defined in physical units**: ``target_kpa`` (``target_mm`` for the jaw, ``unit="mm"``). A fraction,
    ``target``, is only another way to write it: of the scale the file records (``max_pressure_kpa``,
    ``jaw_travel_mm``), or, in a file that records neither the physical target nor that scale (:func:`save_ramp`'s
    form), of ``full_scale``. So a new maximum never moves a tuned schedule (``--set max_pressure_kpa=40`` keeps
    ``agents/best_ramp.json``'s 35.1 kPa). A file's own target and fraction are returned bit for bit where the scales
    agree.

    Raises:
        ValueError: naming ``source``: a key that is not a finite number; a file whose two targets disagree (its
            ``target`` times its recorded scale is not its physical target: both are named); a physical target above
            ``full_scale`` (refused, not clipped: clipping would move the schedule).
        TypeError: ``target`` is not a number (:class:`LinearRamp`'s message).
    """
    if unit not in SCALES:
        raise ValueError(f"unit must be one of {sorted(SCALES)}, got {unit!r}")
    key, scale_key = SCALES[unit]
    physical = _physical(data, key, source)
    scale = _physical(data, scale_key, source, positive=True)
    fraction = _check_target(data["target"]) if "target" in data else None
    if physical is None and fraction is None:
        raise ValueError(f"{source} lacks the key 'target' (or {key!r})")
    if physical is not None and fraction is not None and scale is not None \
            and not math.isclose(fraction * scale, physical, rel_tol=1e-9, abs_tol=1e-12):
        raise ValueError(f"{source}: its two targets disagree: {key} = {physical:g} {unit}, but target = {fraction:g} "
                         f"of {scale_key} = {scale:g} is {fraction * scale:g} {unit}; give one of them (or make them "
                         "agree)")
    if fraction is not None and (scale is None and physical is None or scale == full_scale):
        return fraction  # a fraction of this config's scale, as written (it agrees with the physical target)
    if physical is None:
        physical = fraction * scale
    if physical > full_scale * (1.0 + 1e-12):
        what = "max_pressure_kpa" if unit == "kPa" else "the jaw travel"
        raise ValueError(f"{source}: its target, {physical:g} {unit}, is above {what} = {full_scale:g} {unit}: a "
                         f"schedule is defined in {unit}, and is not rescaled or clipped to a new maximum; tune one "
                         f"for this config (pneunet-grasp search), or raise {what}")
    return min(physical / full_scale, 1.0)


def load_ramp(path: str | os.PathLike, config: EnvConfig | None = None, *, full_scale: float | None = None,
              unit: str = "kPa") -> LinearRamp | StepPolicy:
    """The ramp saved by :func:`save_ramp` or ``pneunet-grasp search`` (``kind`` ``linear_ramp`` or ``step``), for
    ``config``'s action scale; its target in physical units (:func:`ramp_target`), as a fraction of ``full_scale``
    (default: ``config``'s ``max_pressure_kpa``; the jaw travel in mm with ``unit="mm"``).

    Raises:
        ValueError: the file is missing, not JSON, or does not describe a ramp; its two targets disagree; its target is
            above ``full_scale`` (all named).
    """
    path = Path(path)
    config = EnvConfig() if config is None else config
    data = load_json_file(path, "ramp file")  # ValueError naming it: unreadable, not JSON, a duplicate key
    if not isinstance(data, dict):
        raise ValueError(f"ramp file {str(path)!r} must hold a JSON object, got {type(data).__name__}")
    kind = data.get("kind")
    if kind not in ("linear_ramp", "step"):
        raise ValueError(f"ramp file {str(path)!r}: unknown kind {kind!r} (expected 'linear_ramp' or 'step')")
    if kind == "linear_ramp" and "n_steps" not in data:
        raise ValueError(f"ramp file {str(path)!r} lacks the key 'n_steps'")
    full = config.task.max_pressure_kpa if full_scale is None else float(full_scale)
    target = ramp_target(data, f"ramp file {str(path)!r}", full, unit)
    if kind == "linear_ramp":
        return LinearRamp(target, data["n_steps"], config)
    return StepPolicy(target, config)
