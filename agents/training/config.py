"""The train config of ``pneunet-grasp train`` (:mod:`agents.training.train`): an rl-zoo3 file and its project file.

The config is two files. ``ppo.yaml`` is a plain rl-zoo3 hyperparameter file, so rl-zoo3 trains from it as it is::

    python -m rl_zoo3.train --algo ppo --env PneuNetGrasp-v1 --gym-packages pneunet_env \
        --conf-file configs/train/ppo.yaml

It maps the env id to rl-zoo3's keys (``policy``, ``n_envs``, ``n_timesteps``, ``normalize``, ``policy_kwargs``,
``env_kwargs``, ``env_wrapper``, ``vec_env_wrapper``, ``callback``, ``frame_stack``) and the algorithm's own keyword
arguments (``n_steps``, ``batch_size``, ``learning_rate``, ...; ``lin_<x>`` is rl-zoo3's linear schedule).
``policy_kwargs`` and ``normalize`` may be YAML mappings or rl-zoo3's strings (``"dict(net_arch=[64, 64])"``,
``"{'norm_obs': False}"``), read here without ``eval``. ``env_wrapper``, ``vec_env_wrapper`` and ``callback`` name
classes (``module.Class``, a ``{module.Class: {kwargs}}`` mapping, or a list of those), imported when training
starts. The pressure-setpoint action is ``env_wrapper: pneunet_env.wrappers.PressureSetpoint`` (the agent commands
a pressure, a rate-limited regulator follows it: :mod:`pneunet_env.wrappers`); on the batched env, which has no
per-env wrappers, its ``VecEnv`` form ``PressureSetpointVecEnv`` is used instead (an ``env_wrapper`` without a
``VecEnv`` form makes the run fall back to the ``dummy`` vec env, with a warning).

Both files are read by :mod:`pneunet_env.yamlio`, as every file of the package: a duplicated key is refused (naming
it and its line), ``3e-4`` and ``5e1`` are numbers (PyYAML alone, and so ``python -m rl_zoo3.train``, reads them as
strings: write ``3.0e-4`` or ``!!float 3e-4`` in a file rl-zoo3 must read too), aliases are bounded.

**What a train config can run.** A train config is data, not code: its strings are never evaluated, and the only
callables it can name are **classes** of the packages in :data:`CALLABLE_PACKAGES` (stable-baselines3, sb3-contrib,
Gymnasium, ``pneunet_env`` and ``agents``) that subclass the key's base (:data:`CALLABLE_BASES`):
``env_wrapper`` a ``gymnasium.Wrapper``, ``vec_env_wrapper`` a SB3 ``VecEnvWrapper``, ``callback`` a SB3
``BaseCallback``. Anything else (``subprocess.run``, ``os.system``, a function, a module whose name has a part
starting with ``_`` such as ``__main__``) is refused by name before it is imported. rl-zoo3's own classes
(``rl_zoo3.wrappers...``, ``rl_zoo3.callbacks...``) are refused too (importing some rl-zoo3 modules runs its
scripts); ``python -m rl_zoo3.train`` still reads such a file, with its own rules (rl-zoo3 imports any path). The
classes allowed still act as their keyword arguments say: SB3's ``CheckpointCallback(save_path=...)`` writes where
it is told. The ``nn.<Name>`` of ``policy_kwargs`` must be a ``torch.nn.Module`` class (``nn.ReLU``), and every
boolean keyword argument of the algorithm, of its policy and of ``normalize`` must be ``true`` or ``false`` (a
string such as ``"false"`` is refused by name: the algorithm would read it as true).

The keys only this command knows (rl-zoo3 would pass them to the algorithm, which rejects them) live beside it, in
``ppo.project.yaml`` (``<name>.project.yaml`` next to ``<name>.yaml``; optional; the same ``env id -> keys``
layout; unknown keys raise):

=====================  ==============================================================================
``algo``               ``ppo``, ``sac``, ``td3``, ``a2c`` (default: the file's name, ``ppo.yaml`` -> PPO)
``vec_env``            ``batched`` (the batched env, :mod:`pneunet_env.envs.sb3`) or ``dummy`` (SB3's
                       ``DummyVecEnv`` over ``gym.make``); ``batched`` falls back to ``dummy`` with a warning
                       if :mod:`pneunet_env.envs.sb3` is missing
``seed``               the run's seed, an integer >= 0 (training envs ``seed + i``, evaluation env
                       ``seed + 10_000``)
``eval_freq``          timesteps between evaluations (``EvalCallback``, ``is_success`` logged)
``n_eval_episodes``    episodes per evaluation, on objects drawn with a fixed seed (the same each time)
``n_eval_envs``        envs of the evaluation ``VecEnv``
``checkpoint_freq``    timesteps between checkpoints (model and ``VecNormalize`` statistics)
``max_train_minutes``  wall-clock budget of one invocation (training stops cleanly when it is spent)
``torch_threads``      ``torch.set_num_threads`` (default 1: the batched env already runs its numba threads
                       beside it; two torch threads ran training up to 10x slower on 2 cores; ``--threads``)
=====================  ==============================================================================

An older single-file config (these keys, and ``action: setpoint|rate``, inside the rl-zoo3 file) still loads, with
a ``FutureWarning``: ``action: setpoint`` reads as ``env_wrapper: pneunet_env.wrappers.PressureSetpoint``.

Nothing here imports torch or stable-baselines3 until training needs them (:func:`_import_class`,
:func:`_algo_kwargs`, :func:`_resolve_policy_kwargs`).
"""

from __future__ import annotations

import ast
import importlib
import inspect
import math
import re
import warnings
from pathlib import Path
from typing import Any

from pneunet_env.config import ConfigTypeError, check_bool
from pneunet_env.yamlio import load_yaml_file

__all__ = ["load_train_config", "project_config_path", "parse_literal", "action_mode", "LinearSchedule",
           "ENV_ID", "ALGOS", "PROJECT_KEYS", "ZOO_KEYS", "DEFAULTS", "SETPOINT_WRAPPER", "CALLABLE_PACKAGES",
           "CALLABLE_BASES", "PATCHING_MODULES"]

ENV_ID = "PneuNetGrasp-v1"
ALGOS = ("ppo", "sac", "td3", "a2c")
PROJECT_KEYS = ("algo", "vec_env", "seed", "eval_freq", "n_eval_episodes", "n_eval_envs", "checkpoint_freq",
                "max_train_minutes", "torch_threads")
"""The keys of ``<name>.project.yaml``: this command's own, unknown to rl-zoo3."""
ZOO_KEYS = ("policy", "n_envs", "n_timesteps", "normalize", "policy_kwargs", "env_kwargs", "env_wrapper",
            "vec_env_wrapper", "callback", "frame_stack")
"""rl-zoo3's keys of the main file that are not the algorithm's keyword arguments."""
ZOO_UNSUPPORTED = ("monitor_kwargs", "noise_type", "noise_std")
SETPOINT_WRAPPER = "pneunet_env.wrappers.PressureSetpoint"
DEFAULTS: dict[str, Any] = {
    "vec_env": "batched", "env_kwargs": {}, "seed": 0, "eval_freq": 20_000, "n_eval_episodes": 100,
    "n_eval_envs": 4, "checkpoint_freq": 50_000, "max_train_minutes": 10.0, "torch_threads": 1,
    "policy": "MlpPolicy", "n_envs": 8, "n_timesteps": 300_000, "normalize": False, "policy_kwargs": {},
}

CALLABLE_PACKAGES = ("stable_baselines3", "sb3_contrib", "gymnasium", "pneunet_env", "agents")
#: Modules that replace an allowed package's class in place when imported: rl-zoo3's ``gym_patches`` sets
#: ``gymnasium.wrappers.TimeLimit`` to its own subclass, so once rl-zoo3 is imported in the process the name
#: ``gymnasium.wrappers.TimeLimit`` resolves to a class defined there. The name a config writes must still lie in
#: :data:`CALLABLE_PACKAGES`; only the class found under it may come from one of these.
PATCHING_MODULES = ("rl_zoo3.gym_patches",)
"""The packages whose classes ``env_wrapper``, ``vec_env_wrapper`` and ``callback`` may name."""

CALLABLE_BASES: dict[str, tuple[str, str]] = {
    "env_wrapper": ("gymnasium", "Wrapper"),
    "vec_env_wrapper": ("stable_baselines3.common.vec_env", "VecEnvWrapper"),
    "callback": ("stable_baselines3.common.callbacks", "BaseCallback"),
}
"""``key -> (module, class)``: the base class each key's classes must subclass."""

NORMALIZE_BOOL_KEYS = ("training", "norm_obs", "norm_reward")
"""``VecNormalize``'s boolean keyword arguments (``normalize: {norm_obs: false}``)."""

_DOTTED = re.compile(r"[A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)+")


# ---------------------------------------------------------------------------------------------
# rl-zoo3's string values
# ---------------------------------------------------------------------------------------------


def parse_literal(name: str, value: Any) -> Any:
    """rl-zoo3's string values without ``eval``: ``"dict(a=1, b=[2])"``, ``"{'a': 1}"``, ``"nn.ReLU"``.

    Mappings and other YAML values pass through. ``dict(...)`` may hold literals and ``nn.<Activation>``
    names (kept as strings, resolved by :func:`_resolve_policy_kwargs`). ``ValueError`` names a bad one.
    """
    if not isinstance(value, str):
        return value
    text = value.strip()
    try:
        node = ast.parse(text, mode="eval").body
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise ValueError(f"train config key {name!r}: cannot parse {value!r}") from None
    return _literal(name, node, value)


def _literal(name: str, node: ast.AST, source: str) -> Any:
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args:
        if any(kw.arg is None for kw in node.keywords):
            raise ValueError(f"train config key {name!r}: {source!r}: dict(**...) is not read")
        return {kw.arg: _literal(name, kw.value, source) for kw in node.keywords}
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in ("nn", "th", "torch"):
        return f"nn.{node.attr}"
    if isinstance(node, ast.Dict):
        if any(k is None for k in node.keys):
            raise ValueError(f"train config key {name!r}: {source!r}: {{**...}} is not read")
        out = {}
        for k, v in zip(node.keys, node.values, strict=True):
            key = _literal(name, k, source)
            try:
                out[key] = _literal(name, v, source)
            except TypeError:
                raise ValueError(f"train config key {name!r}: {source!r} has an unhashable key {key!r}") from None
        return out
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_literal(name, e, source) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    try:
        return ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        raise ValueError(f"train config key {name!r}: {source!r} is not a literal (only dict(...), literals and "
                         "nn.<Activation> are read)") from None


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------


def project_config_path(path: str | Path) -> Path:
    """``DIR/NAME.project.yaml`` for ``DIR/NAME.yaml``: the keys of this command that rl-zoo3 does not know."""
    path = Path(path)
    return path.with_name(f"{path.stem}.project{path.suffix or '.yaml'}")


def _read_entry(path: Path, env_id: str, what: str) -> dict[str, Any]:
    data = load_yaml_file(path, what)  # ValueError naming the file: unreadable, bad YAML, a duplicate key
    if not isinstance(data, dict) or env_id not in data or not isinstance(data[env_id], dict):
        raise ValueError(f"{what} {str(path)!r} must map {env_id!r} to its hyperparameters (rl-zoo3 style)")
    return dict(data[env_id])


# ---------------------------------------------------------------------------------------------
# The classes a config names
# ---------------------------------------------------------------------------------------------


def _refuse(key: str, name: str, why: str) -> ValueError:
    module, cls = CALLABLE_BASES[key]
    return ValueError(f"train config key {key!r}: {name!r} {why}; a train config may name only classes of "
                      f"{', '.join(CALLABLE_PACKAGES)} that subclass {module}.{cls} (a train config is data, not "
                      "code)")


def _check_name(key: str, name: str) -> None:
    """Refuse, before any import, a name outside :data:`CALLABLE_PACKAGES` or with a private part (``__main__``)."""
    if not _DOTTED.fullmatch(name):
        raise _refuse(key, name, "is not a dotted name 'package.module.Class'")
    if name.split(".")[0] not in CALLABLE_PACKAGES:
        raise _refuse(key, name, "is outside the allowed packages")


def _class_specs(key: str, value: Any) -> list[tuple[str, dict[str, Any]]]:
    """rl-zoo3's ``env_wrapper``/``vec_env_wrapper``/``callback`` value -> ``[(dotted name, kwargs), ...]``; a name
    outside :data:`CALLABLE_PACKAGES` is refused here, before anything is imported."""
    if value is None:
        return []
    items = value if isinstance(value, list) else [value]
    out = []
    for item in items:
        if isinstance(item, dict) and len(item) == 1:
            name, kwargs = next(iter(item.items()))
            kwargs = {} if kwargs is None else kwargs
        else:
            name, kwargs = item, {}
        if not isinstance(name, str) or "." not in name or not isinstance(kwargs, dict):
            raise ValueError(f"train config key {key!r}: expected 'module.Class', {{'module.Class': {{kwargs}}}} or "
                             f"a list of those, got {item!r}")
        if not all(isinstance(k, str) and k.isidentifier() for k in kwargs):
            raise ValueError(f"train config key {key!r}: the keyword arguments of {name!r} must be names, got "
                             f"{sorted(map(repr, kwargs))}")
        _check_name(key, name)
        out.append((name, dict(kwargs)))
    return out


def _import_class(key: str, name: str):
    """The class ``name`` for config key ``key``: imported only from :data:`CALLABLE_PACKAGES`, and only if it is a
    class defined there that subclasses the key's base (:data:`CALLABLE_BASES`); ``ValueError`` naming it else."""
    _check_name(key, name)
    module, _, attr = name.rpartition(".")
    if any(part.startswith("_") for part in name.split(".")):
        raise _refuse(key, name, "has a private part")
    try:
        obj = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"train config key {key!r}: cannot import {name!r} ({exc})") from None
    if not isinstance(obj, type):
        raise _refuse(key, name, f"is not a class (a {type(obj).__name__})")
    defined_in = str(getattr(obj, "__module__", ""))
    if defined_in.split(".")[0] not in CALLABLE_PACKAGES and defined_in not in PATCHING_MODULES:
        raise _refuse(key, name, f"is defined in {obj.__module__}, outside the allowed packages")
    base_module, base_name = CALLABLE_BASES[key]
    base = getattr(importlib.import_module(base_module), base_name)
    if not issubclass(obj, base):
        raise _refuse(key, name, f"is not a {base_module}.{base_name}")
    return obj


def _wrapper_classes(hp: dict[str, Any], key: str) -> list[tuple[Any, dict[str, Any]]]:
    """``[(class, kwargs), ...]`` of the config's ``env_wrapper``, ``vec_env_wrapper`` or ``callback``."""
    return [(_import_class(key, name), kwargs) for name, kwargs in _class_specs(key, hp.get(key))]


def action_mode(hp: dict[str, Any]) -> str:
    """``"setpoint"`` if the config drives the env through :mod:`pneunet_env.wrappers`' setpoint wrapper, else
    ``"rate"`` (the env's own action): what :class:`agents.policies.sb3.SB3Policy` must apply to the model's output."""
    names = [n for key in ("env_wrapper", "vec_env_wrapper") for n, _ in _class_specs(key, hp.get(key))]
    return "setpoint" if any(n in (SETPOINT_WRAPPER, SETPOINT_WRAPPER + "VecEnv") for n in names) else "rate"


# ---------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------


def load_train_config(path: str | Path, env_id: str = ENV_ID, project: str | Path | None = None) -> dict[str, Any]:
    """Read an rl-zoo3 hyperparameter file and its ``<name>.project.yaml``: one flat dict, defaults filled in.

    Args:
        path: the rl-zoo3 file (``configs/train/ppo.yaml``).
        env_id: its entry.
        project: the project file (default :func:`project_config_path`; a missing default is no error).

    Raises:
        ValueError: a missing file or env entry, a duplicate key, an unknown algorithm or project key, a key in both
            files, a non-positive count, a class outside :data:`CALLABLE_PACKAGES`, or a malformed value (a wrong
            type: :class:`pneunet_env.config.ConfigTypeError`, also a ``TypeError``).
    """
    path = Path(path)
    main = _read_entry(path, env_id, "train config")
    legacy = sorted(k for k in main if k in PROJECT_KEYS or k == "action")
    proj_path = project_config_path(path) if project is None else Path(project)
    ours: dict[str, Any] = {}
    if project is not None or proj_path.is_file():
        ours = _read_entry(proj_path, env_id, "project config")
        unknown = sorted(map(str, set(ours) - set(PROJECT_KEYS)))
        if unknown:
            raise ValueError(f"project config {str(proj_path)!r}: unknown key(s) {unknown}; valid: "
                             f"{', '.join(PROJECT_KEYS)} (rl-zoo3's and the algorithm's keys go in {path.name})")
        both = sorted(set(ours) & set(main))
        if both:
            raise ValueError(f"train config key(s) {both} in both {str(path)!r} and {str(proj_path)!r}")
    if legacy:
        warnings.warn(f"train config {str(path)!r}: key(s) {legacy} belong in {proj_path.name} (rl-zoo3 passes "
                      "unknown keys to the algorithm); 'action: setpoint' is 'env_wrapper: "
                      f"{SETPOINT_WRAPPER}'", FutureWarning, stacklevel=2)
    bad_keys = sorted(repr(k) for k in main if not isinstance(k, str))
    if bad_keys:
        raise ValueError(f"train config {str(path)!r}: keys must be names, got {', '.join(bad_keys)}")
    unsupported = sorted(k for k in main if k in ZOO_UNSUPPORTED)
    if unsupported:
        raise ValueError(f"train config {str(path)!r}: rl-zoo3 key(s) {unsupported} are not supported by "
                         "pneunet-grasp train (python -m rl_zoo3.train reads them)")
    hp = {**DEFAULTS, **main, **ours}
    action = hp.pop("action", None)
    if action is not None:
        if action not in ("rate", "setpoint"):
            raise ValueError(f"train config key 'action' must be 'rate' or 'setpoint', got {action!r}")
        if action == "setpoint" and action_mode(hp) != "setpoint":
            hp["env_wrapper"] = ([*_raw_list(hp["env_wrapper"]), SETPOINT_WRAPPER] if hp.get("env_wrapper")
                                 else SETPOINT_WRAPPER)
    algo = hp.get("algo") or path.stem.split("_")[0].split(".")[0]
    if not isinstance(algo, str) or algo.lower() not in ALGOS:
        raise ValueError(f"train config {str(path)!r}: unknown algo {algo!r}; valid: {', '.join(ALGOS)}")
    hp["algo"] = algo.lower()
    if not isinstance(hp["policy"], str) or not hp["policy"]:
        raise ConfigTypeError(f"train config key 'policy' must be a policy name such as 'MlpPolicy', got "
                              f"{hp['policy']!r}")
    hp["normalize"] = parse_literal("normalize", hp["normalize"])
    if isinstance(hp["normalize"], bool):
        hp["normalize"] = {"norm_obs": True, "norm_reward": True} if hp["normalize"] else False
    elif not isinstance(hp["normalize"], dict):
        raise ValueError(f"train config key 'normalize' must be true/false or a mapping, got {hp['normalize']!r}")
    else:
        for key in NORMALIZE_BOOL_KEYS:
            if key in hp["normalize"]:
                check_bool(f"normalize.{key}", hp["normalize"][key])
    hp["policy_kwargs"] = parse_literal("policy_kwargs", hp["policy_kwargs"]) or {}
    if not isinstance(hp["policy_kwargs"], dict):
        raise ValueError(f"train config key 'policy_kwargs' must be a mapping, got {hp['policy_kwargs']!r}")
    if hp["vec_env"] not in ("batched", "dummy"):
        raise ValueError(f"train config key 'vec_env' must be 'batched' or 'dummy', got {hp['vec_env']!r}")
    if not isinstance(hp["env_kwargs"], dict):
        raise ValueError(f"train config key 'env_kwargs' must be a mapping, got {hp['env_kwargs']!r}")
    for key in ("env_wrapper", "vec_env_wrapper", "callback"):
        _class_specs(key, hp.get(key))
    if hp.get("frame_stack") is not None:
        hp["frame_stack"] = _count("frame_stack", hp["frame_stack"])
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        value = hp.get(key)
        if isinstance(value, str) and not (re.fullmatch(r"lin_[-+0-9.eE_]+", value) and _finite(value[4:])):
            raise ValueError(f"train config key {key!r}: a number or rl-zoo3's 'lin_<initial value>', "
                             f"got {hp[key]!r}")
        if isinstance(value, bool):
            raise ConfigTypeError(f"train config key {key!r} must be a number or 'lin_<initial value>', got "
                                  f"{value!r}")
    for key in ("n_envs", "n_timesteps", "eval_freq", "n_eval_episodes", "n_eval_envs", "checkpoint_freq",
                "torch_threads"):
        hp[key] = _count(key, hp[key])
    hp["seed"] = _seed("seed", hp["seed"])
    minutes = hp["max_train_minutes"]
    if isinstance(minutes, bool) or not isinstance(minutes, (int, float)):
        raise ConfigTypeError(f"train config key 'max_train_minutes' must be a number of minutes, got {minutes!r}")
    hp["max_train_minutes"] = float(minutes)
    if not hp["max_train_minutes"] > 0:
        raise ValueError(f"train config key 'max_train_minutes' must be > 0, got {hp['max_train_minutes']!r}")
    return hp


def _finite(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _raw_list(value: Any) -> list[Any]:
    return [] if value is None else list(value) if isinstance(value, list) else [value]


def _count(key: str, value: Any) -> int:
    """A positive integer (``3e6`` and ``!!float 3e6`` read as 3,000,000; a boolean, a fraction, ``inf`` refused)."""
    if isinstance(value, bool):
        raise ConfigTypeError(f"train config key {key!r} must be a positive integer, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"train config key {key!r} must be a positive integer, got {value!r}") from None
    if not math.isfinite(x) or x != int(x) or x < 1:
        raise ValueError(f"train config key {key!r} must be a positive integer, got {value!r}")
    return int(x)


def _seed(key: str, value: Any) -> int:
    """An integer >= 0 (``1.0`` is 1; ``1.5``, ``"abc"`` and ``true`` are refused, naming the key)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigTypeError(f"train config key {key!r} must be an integer >= 0, got {value!r}")
    if not math.isfinite(value) or value != int(value) or value < 0:
        raise ValueError(f"train config key {key!r} must be an integer >= 0, got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------------
# What the algorithm takes
# ---------------------------------------------------------------------------------------------


class LinearSchedule:
    """rl-zoo3's ``lin_<x>``: ``x`` times the remaining progress (1 at the start, 0 at the end)."""

    def __init__(self, initial_value: float) -> None:
        self.initial_value = float(initial_value)

    def __call__(self, progress_remaining: float) -> float:
        return progress_remaining * self.initial_value

    def __repr__(self) -> str:
        return f"LinearSchedule({self.initial_value})"


def _bool_parameters(cls: type) -> set[str]:
    """The keyword arguments of ``cls.__init__`` annotated ``bool``."""
    try:
        params = inspect.signature(cls.__init__).parameters
    except (TypeError, ValueError):  # pragma: no cover - every SB3 class has a signature
        return set()
    return {n for n, p in params.items() if p.annotation is bool or p.annotation == "bool"}


def _check_bools(what: str, cls: type, kwargs: dict[str, Any]) -> None:
    for name in sorted(_bool_parameters(cls) & set(kwargs)):
        check_bool(f"{what}.{name}" if what else name, kwargs[name])


def _algo_kwargs(hp: dict[str, Any]) -> dict[str, Any]:
    """The algorithm's keyword arguments: the main file's keys that are neither rl-zoo3's nor the project's.

    With stable-baselines3 installed, every one the algorithm (and every ``policy_kwargs`` key its policy) declares
    ``bool`` must be ``true`` or ``false``: :class:`pneunet_env.config.ConfigTypeError` names a string such as
    ``"false"``, which the algorithm would read as true."""
    skip = set(PROJECT_KEYS) | set(ZOO_KEYS)
    out = {k: v for k, v in hp.items() if k not in skip}
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if isinstance(out.get(key), str):
            out[key] = LinearSchedule(float(out[key][4:]))
    if isinstance(out.get("train_freq"), list):
        out["train_freq"] = tuple(out["train_freq"])
    try:
        import stable_baselines3
    except ImportError:  # pragma: no cover - training needs it; the check then has nothing to check against
        return out
    algo_cls = getattr(stable_baselines3, str(hp.get("algo", "")).upper(), None)
    if algo_cls is not None:
        _check_bools("", algo_cls, out)
        policy_cls = getattr(algo_cls, "policy_aliases", {}).get(hp.get("policy"))
        if policy_cls is not None and isinstance(hp.get("policy_kwargs"), dict):
            _check_bools("policy_kwargs", policy_cls, hp["policy_kwargs"])
    return out


def _resolve_policy_kwargs(kwargs: dict[str, Any]) -> dict[str, Any]:
    """``policy_kwargs`` with each ``"nn.<Name>"`` string replaced by the ``torch.nn`` class (which must be a
    ``torch.nn.Module``: ``nn.ReLU``; ``nn.init`` or ``nn.functional`` is refused by name)."""
    import torch.nn as nn

    out = dict(kwargs)
    for key, value in kwargs.items():
        if isinstance(value, str) and value.startswith("nn."):
            obj = getattr(nn, value[3:], None) if not value[3:].startswith("_") else None
            if obj is None:
                raise ValueError(f"policy_kwargs {key!r}: torch.nn has no {value[3:]!r}")
            if not (isinstance(obj, type) and issubclass(obj, nn.Module)):
                raise ValueError(f"policy_kwargs {key!r}: {value!r} is not a torch.nn.Module class (such as nn.ReLU)")
            out[key] = obj
    return out
