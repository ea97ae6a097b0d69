"""The policy registry: a name (or a model file) -> a policy and the environment it drives.

====================  ===============================================================  ==================
spec                  policy                                                           environment
====================  ===============================================================  ==================
``ramp``              :class:`~agents.scripted.LinearRamp` to ``p_max`` over 40 steps  ``PneuNetGrasp-v0``
``step``              :class:`~agents.scripted.StepPolicy` to ``p_max``                ``PneuNetGrasp-v0``
``best-ramp``         the ramp in ``agents/best_ramp.json`` (:mod:`agents.search`)      ``PneuNetGrasp-v0``
``oracle``            :class:`~agents.oracle.Oracle` (knows the object; not blind)      ``PneuNetGrasp-v0``
``rigid``             the jaw ramp in ``agents/best_rigid.json`` (:mod:`agents.search`) ``RigidGrasp-v0``
``PATH.zip``          a stable-baselines3 model, with its ``VecNormalize`` statistics   ``PneuNetGrasp-v0``
====================  ===============================================================  ==================

Parameters follow a colon, comma-separated: ``ramp:target_kpa=30,steps=20``, ``step:target_kpa=45``,
``best-ramp:path=runs/best.json``, ``oracle:resolution_kpa=0.25``, ``rigid:target_mm=9,steps=10``,
``rigid:path=...``. (``target=`` takes a fraction of ``p_max`` or of the jaw travel instead.)

A policy maps an observation (or a batch) to an action in ``Box(-1, 1, (1,))``, has ``predict`` (SB3's
signature) and ``begin_episode(info)`` (called with ``reset``'s ``info``; only the oracle uses it).

An SB3 model ``DIR/NAME.zip`` is loaded with the algorithm named in ``DIR/NAME.json`` (written by
``pneunet-grasp train``; else inferred from the saved policy class) and the observation statistics of
``DIR/NAME_vecnormalize.pkl`` (else ``DIR/vecnormalize.pkl``; none if neither exists). torch and
stable-baselines3 are imported only for such a model.
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.scripted import LinearRamp, StepPolicy, load_ramp
from pneunet_env.config import EnvConfig

__all__ = ["PolicyEntry", "REGISTRY", "make_policy", "parse_spec", "SB3Policy", "BEST_RAMP_PATH", "BEST_RIGID_PATH",
           "vecnormalize_path", "setpoint_to_rate", "ACTION_MODES"]

AGENTS_DIR = Path(__file__).resolve().parent
BEST_RAMP_PATH = AGENTS_DIR / "best_ramp.json"
"""The ``best-ramp`` policy's parameters (written by ``python -m agents.search``)."""
BEST_RIGID_PATH = AGENTS_DIR / "best_rigid.json"
"""The ``rigid`` policy's parameters (written by ``python -m agents.search --gripper rigid``)."""

PNEUNET_ENV = "PneuNetGrasp-v0"
RIGID_ENV = "RigidGrasp-v0"


@dataclass
class PolicyEntry:
    """A policy ready to run, and what it needs.

    Attributes:
        name: the spec it was made from (``best-ramp``, ``models/ppo.zip``, ...).
        label: a human-readable description (for tables and legends).
        policy: the policy object.
        env_id: the environment it drives (``PneuNetGrasp-v0`` or ``RigidGrasp-v0``).
        blind: whether it acts on the observation alone (the oracle does not).
        command: what the observation and action move: ``"pressure"`` or ``"jaw"``.
        env_kwargs: extra keyword arguments for ``gym.make`` (the rigid gripper's travel).
    """

    name: str
    label: str
    policy: Any
    env_id: str = PNEUNET_ENV
    blind: bool = True
    command: str = "pressure"
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    def make_env(self, config: EnvConfig):
        """``gym.make`` the policy's environment with ``config``."""
        import gymnasium as gym

        import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v0)
        return gym.make(self.env_id, config=config, **self.env_kwargs)


def parse_spec(spec: str) -> tuple[str, dict[str, str]]:
    """``"name:k=v,k2=v2"`` -> ``("name", {"k": "v", "k2": "v2"})``; ``ValueError`` on a malformed one."""
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"policy spec must be a non-empty string, got {spec!r}")
    name, _, rest = spec.strip().partition(":")
    params: dict[str, str] = {}
    if rest:
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            if not eq or not key.strip():
                raise ValueError(f"policy spec {spec!r}: parameters must be key=value, got {item!r}")
            params[key.strip()] = value.strip()
    return name.strip(), params


def _float(spec: str, key: str, value: str) -> float:
    try:
        return float(value)
    except ValueError:
        raise ValueError(f"policy spec {spec!r}: {key}={value!r} is not a number") from None


def _int(spec: str, key: str, value: str) -> int:
    x = _float(spec, key, value)
    if x != int(x):
        raise ValueError(f"policy spec {spec!r}: {key}={value!r} is not an integer")
    return int(x)


def _target(spec: str, params: dict[str, str], full_scale: float, unit_key: str, default: float) -> float:
    """A target as a fraction of full scale, from ``target=`` (fraction) or ``<unit_key>=`` (physical)."""
    if "target" in params and unit_key in params:
        raise ValueError(f"policy spec {spec!r}: give 'target' or {unit_key!r}, not both")
    if "target" in params:
        return _float(spec, "target", params.pop("target"))
    if unit_key in params:
        return _float(spec, unit_key, params.pop(unit_key)) / full_scale
    return default


def _check_empty(spec: str, params: dict[str, str], valid: str) -> None:
    if params:
        raise ValueError(f"policy spec {spec!r}: unknown parameter(s) {sorted(params)}; valid: {valid}")


def _ramp(spec, params, config):
    t = _target(spec, params, config.task.max_pressure_kpa, "target_kpa", 1.0)
    n = _int(spec, "steps", params.pop("steps", "40"))
    _check_empty(spec, params, "target, target_kpa, steps")
    pol = LinearRamp(t, n, config)
    return PolicyEntry(spec, f"ramp to {t * config.task.max_pressure_kpa:.3g} kPa over {n} steps", pol)


def _step(spec, params, config):
    t = _target(spec, params, config.task.max_pressure_kpa, "target_kpa", 1.0)
    _check_empty(spec, params, "target, target_kpa")
    return PolicyEntry(spec, f"step to {t * config.task.max_pressure_kpa:.3g} kPa", StepPolicy(t, config))


def _best_ramp(spec, params, config):
    path = Path(params.pop("path", BEST_RAMP_PATH))
    _check_empty(spec, params, "path")
    pol = load_ramp(path, config)
    label = f"best-ramp ({_describe(pol, config.task.max_pressure_kpa, 'kPa')})"
    return PolicyEntry(spec, label, pol)


def _describe(pol, full_scale: float, unit: str) -> str:
    if isinstance(pol, LinearRamp):
        return f"{pol.target * full_scale:.3g} {unit} over {pol.n_steps} steps"
    return f"step to {pol.target * full_scale:.3g} {unit}"


def _oracle(spec, params, config):
    from agents.oracle import Oracle

    res = _float(spec, "resolution_kpa", params.pop("resolution_kpa", "0.5"))
    _check_empty(spec, params, "resolution_kpa")
    return PolicyEntry(spec, "oracle (knows k~; best constant pressure)", Oracle(config, res), blind=False)


def _rigid(spec, params, config):
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    travel = _float(spec, "travel_mm", params.pop("travel_mm")) if "travel_mm" in params else None
    env_kwargs = {} if travel is None else {"jaw_travel_mm": travel}
    full = default_jaw_travel_mm(config) if travel is None else travel
    if "target" in params or "target_mm" in params:
        t = _target(spec, params, full, "target_mm", 0.5)
        n = _int(spec, "steps", params.pop("steps", "20"))
        pol = LinearRamp(t, n, config)
        _check_empty(spec, params, "target, target_mm, steps, travel_mm, path")
    else:
        path = Path(params.pop("path", BEST_RIGID_PATH))
        _check_empty(spec, params, "target, target_mm, steps, travel_mm, path")
        pol = _load_rigid(path, config, full)
    label = f"rigid gripper ({_describe(pol, full, 'mm')})"
    return PolicyEntry(spec, label, pol, env_id=RIGID_ENV, command="jaw", env_kwargs=env_kwargs)


def _load_rigid(path: Path, config: EnvConfig, travel_mm: float):
    """The saved jaw ramp; its target is stored in mm (travels differ between configs) and re-expressed here."""
    pol = load_ramp(path, config)
    data = json.loads(Path(path).read_text())
    if "target_mm" in data:
        target = min(float(data["target_mm"]) / travel_mm, 1.0)
        pol = LinearRamp(target, pol.n_steps, config) if isinstance(pol, LinearRamp) else StepPolicy(target, config)
    return pol


REGISTRY: dict[str, Callable[[str, dict[str, str], EnvConfig], PolicyEntry]] = {
    "ramp": _ramp,
    "step": _step,
    "best-ramp": _best_ramp,
    "oracle": _oracle,
    "rigid": _rigid,
}
"""Scripted policy names -> factories ``(spec, params, config) -> PolicyEntry``."""


def make_policy(spec: str, config: EnvConfig | None = None) -> PolicyEntry:
    """The policy named by ``spec`` (a registry name with optional parameters, or a ``*.zip`` SB3 model).

    Raises:
        ValueError: an unknown name, a bad parameter, or a missing model file (named).
    """
    config = EnvConfig() if config is None else config
    if isinstance(spec, str) and spec.strip().endswith(".zip"):
        path = Path(spec.strip())
        if not path.is_file():
            raise ValueError(f"policy {spec!r}: no such model file")
        pol = SB3Policy(path, config=config)
        return PolicyEntry(spec, f"{pol.algo}, pressure only ({path.name})", pol)
    name, params = parse_spec(spec)
    if name not in REGISTRY:
        raise ValueError(f"unknown policy {name!r}; valid: {', '.join(REGISTRY)} or a path to an SB3 model .zip")
    return REGISTRY[name](spec, dict(params), config)


# ---------------------------------------------------------------------------------------------
# stable-baselines3 models
# ---------------------------------------------------------------------------------------------


def vecnormalize_path(model_path: str | Path) -> Path | None:
    """``DIR/NAME_vecnormalize.pkl`` if it exists, else ``DIR/vecnormalize.pkl`` if it exists, else ``None``."""
    model_path = Path(model_path)
    for cand in (model_path.with_name(model_path.stem + "_vecnormalize.pkl"),
                 model_path.with_name("vecnormalize.pkl")):
        if cand.is_file():
            return cand
    return None


_ALGOS = ("PPO", "SAC", "TD3", "A2C", "DDPG")
ACTION_MODES = ("rate", "setpoint")
"""How a trained agent's output drives the env: ``rate`` is the env's own action (the pressure change);
``setpoint`` is a commanded pressure, followed by a rate-limited regulator (:func:`setpoint_to_rate`)."""


def setpoint_to_rate(setpoint, pressure_fraction, step_fraction: float) -> np.ndarray:
    """The env action that moves the pressure toward a commanded setpoint as fast as the env allows.

    Args:
        setpoint: the agent's output ``u`` in ``[-1, 1]`` (clipped), the target ``(u + 1)/2`` of ``p_max``.
        pressure_fraction: the current ``p / p_max`` (the observation's first entry), same leading shape.
        step_fraction: ``max_pressure_step_kpa / max_pressure_kpa``.

    Returns:
        ``clip(((u + 1)/2 - p) / step_fraction, -1, 1)``, float32, the shape of ``setpoint``.

    This is a proportional pressure regulator with a rate limit: a function of the pressure and the command only,
    so a policy using it still observes nothing but the pressure.
    """
    u = np.clip(np.asarray(setpoint, dtype=np.float64), -1.0, 1.0)
    p = np.asarray(pressure_fraction, dtype=np.float64).reshape(u.shape)
    return np.clip((0.5 * (u + 1.0) - p) / step_fraction, -1.0, 1.0).astype(np.float32)


def _model_meta(path: Path) -> dict[str, Any]:
    meta = path.with_suffix(".json")
    if meta.is_file():
        try:
            data = json.loads(meta.read_text())
        except json.JSONDecodeError:
            return {}
        return data if isinstance(data, dict) else {}
    return {}


def _infer_algo(path: Path) -> str:
    algo = _model_meta(path).get("algo")
    if isinstance(algo, str) and algo.upper() in _ALGOS:
        return algo.upper()
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(path, load_data=True, device="cpu")
    cls = data.get("policy_class") if data else None
    name = getattr(cls, "__name__", str(cls))
    for algo in ("SAC", "TD3"):
        if algo in name:
            return algo
    return "PPO"


class SB3Policy:
    """A trained stable-baselines3 model as a policy: normalises observations with its saved statistics.

    Args:
        path: the model ``.zip``.
        deterministic: act with the policy's mean (default) rather than a sample.
        vecnormalize: the ``VecNormalize`` pickle (default: :func:`vecnormalize_path`).
        action: ``"rate"`` or ``"setpoint"`` (:data:`ACTION_MODES`); default: the ``action`` of the model's
            metadata JSON (``pneunet-grasp train --export`` writes it), else ``"rate"``.
        config: the env's config (the setpoint regulator's step); the defaults if ``None``.
    """

    blind = True

    def __init__(self, path: str | Path, deterministic: bool = True, vecnormalize: str | Path | None = None,
                 action: str | None = None, config: EnvConfig | None = None) -> None:
        import stable_baselines3 as sb3
        import torch

        if torch.get_num_threads() > 2:  # one observation at a time: threads only add overhead
            torch.set_num_threads(1)
        self.path = Path(path)
        self.algo = _infer_algo(self.path)
        self.action_mode = str(action or _model_meta(self.path).get("action", "rate"))
        if self.action_mode not in ACTION_MODES:
            raise ValueError(f"model {str(path)!r}: action mode must be one of {ACTION_MODES}, "
                             f"got {self.action_mode!r}")
        config = EnvConfig() if config is None else config
        self.step_fraction = config.task.max_pressure_step_kpa / config.task.max_pressure_kpa
        self.model = getattr(sb3, self.algo).load(self.path, device="cpu")
        self.deterministic = deterministic
        vn = vecnormalize_path(self.path) if vecnormalize is None else Path(vecnormalize)
        self.vecnormalize_path = vn
        self._norm = None
        if vn is not None:
            with open(vn, "rb") as fh:
                self._norm = pickle.load(fh)

    def normalize(self, observation) -> np.ndarray:
        obs = np.asarray(observation, dtype=np.float32)
        if self._norm is None or not getattr(self._norm, "norm_obs", False):
            return obs
        return np.asarray(self._norm.normalize_obs(obs), dtype=np.float32)

    def _act(self, observation, deterministic: bool) -> np.ndarray:
        obs = np.asarray(observation, dtype=np.float32)
        out, _ = self.model.predict(self.normalize(obs), deterministic=deterministic)
        out = np.asarray(out, dtype=np.float32)
        if self.action_mode == "setpoint":
            return setpoint_to_rate(out, obs[..., :1], self.step_fraction)
        return np.clip(out, -1.0, 1.0)

    def __call__(self, observation) -> np.ndarray:
        """The env action (the pressure change) for an observation or a batch."""
        return self._act(observation, self.deterministic)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        return self._act(observation, deterministic), state

    def begin_episode(self, info: dict[str, Any] | None = None) -> None:
        """Blind: nothing to do."""

    def reset(self) -> None:
        """Stateless (an MLP on the pressure)."""

    def __repr__(self) -> str:
        return f"SB3Policy({self.algo}, {str(self.path)!r})"
