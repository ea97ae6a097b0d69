"""``pneunet-grasp train --config configs/train/ppo.yaml``: train a stable-baselines3 agent on ``PneuNetGrasp-v0``.

The config is two files. ``ppo.yaml`` is a plain rl-zoo3 hyperparameter file, so rl-zoo3 trains from it as it is::

    python -m rl_zoo3.train --algo ppo --env PneuNetGrasp-v0 --gym-packages pneunet_env \
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

The keys only this command knows (rl-zoo3 would pass them to the algorithm, which rejects them) live beside it, in
``ppo.project.yaml`` (``<name>.project.yaml`` next to ``<name>.yaml``; optional; the same ``env id -> keys``
layout; unknown keys raise):

=====================  ==============================================================================
``algo``               ``ppo``, ``sac``, ``td3``, ``a2c`` (default: the file's name, ``ppo.yaml`` -> PPO)
``vec_env``            ``batched`` (the batched env, :mod:`pneunet_env.envs.sb3`) or ``dummy`` (SB3's
                       ``DummyVecEnv`` over ``gym.make``); ``batched`` falls back to ``dummy`` with a warning
                       if :mod:`pneunet_env.envs.sb3` is missing
``seed``               the run's seed (training envs ``seed + i``, evaluation env ``seed + 10_000``)
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

The run directory (``--run-dir``, default ``runs/<algo>``) receives ``config.yaml`` and ``config.project.yaml``
(the resolved hyperparameters, in the same two-file form: ``--config RUN_DIR/config.yaml`` trains the same run
again), ``run.json`` (seeds, versions, timesteps, wall time, each invocation), ``monitor/``, ``evaluations.npz``
(EvalCallback's log: rewards, lengths, successes), ``best_model.zip`` with ``best_model_vecnormalize.json`` (the
statistics as numbers) and ``.pkl`` (SB3's pickle), ``checkpoints/``, ``final_model.zip`` with
``final_model_vecnormalize.json`` and ``.pkl``, and ``training.png`` (success rate and return of each evaluation,
with matplotlib). ``--resume`` continues from the newest checkpoint (or ``--resume PATH.zip``) up to
``n_timesteps``. ``--export agents/models/ppo_pneunet`` copies the best model, its statistics (JSON) and a metadata
JSON there, each file written to a temporary name in that folder and then renamed over the old one (a failure
leaves the previous export whole): the policy registry (:mod:`agents.policies`) then loads
``agents/models/ppo_pneunet.zip`` by path.

torch and stable-baselines3 are imported only here (``pip install -e ".[rl]"``).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import os
import platform
import re
import time
import warnings
from pathlib import Path
from typing import Any

from agents.policies import (
    STATS_SUFFIX,
    NormalizationStats,
    atomic_write_bytes,
    load_pickled_vecnormalize,
    stage_file,
)

ENV_ID = "PneuNetGrasp-v0"
ALGOS = ("ppo", "sac", "td3", "a2c")
PROJECT_KEYS = ("algo", "vec_env", "seed", "eval_freq", "n_eval_episodes", "n_eval_envs", "checkpoint_freq",
                "max_train_minutes", "torch_threads")
"""The keys of ``<name>.project.yaml``: this command's own, unknown to rl-zoo3."""
OUR_KEYS = PROJECT_KEYS
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

__all__ = ["load_train_config", "project_config_path", "parse_literal", "train", "add_arguments", "run",
           "make_vec_env", "export", "action_mode", "LinearSchedule"]


# ---------------------------------------------------------------------------------------------
# Config
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
    except SyntaxError:
        raise ValueError(f"train config key {name!r}: cannot parse {value!r}") from None
    return _literal(name, node, value)


def _literal(name: str, node: ast.AST, source: str) -> Any:
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args:
        return {kw.arg: _literal(name, kw.value, source) for kw in node.keywords}
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in ("nn", "th", "torch"):
        return f"nn.{node.attr}"
    if isinstance(node, ast.Dict):
        return {_literal(name, k, source): _literal(name, v, source) for k, v in zip(node.keys, node.values,
                                                                                      strict=True)}
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_literal(name, e, source) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise ValueError(f"train config key {name!r}: {source!r} is not a literal (only dict(...), literals and "
                         "nn.<Activation> are read)") from None


def project_config_path(path: str | Path) -> Path:
    """``DIR/NAME.project.yaml`` for ``DIR/NAME.yaml``: the keys of this command that rl-zoo3 does not know."""
    path = Path(path)
    return path.with_name(f"{path.stem}.project{path.suffix or '.yaml'}")


def _read_entry(path: Path, env_id: str, what: str) -> dict[str, Any]:
    import yaml

    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ValueError(f"cannot read {what} {str(path)!r}: {exc}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} {str(path)!r} is not valid YAML: {exc}") from None
    if not isinstance(data, dict) or env_id not in data or not isinstance(data[env_id], dict):
        raise ValueError(f"{what} {str(path)!r} must map {env_id!r} to its hyperparameters (rl-zoo3 style)")
    return dict(data[env_id])


def _class_specs(key: str, value: Any) -> list[tuple[str, dict[str, Any]]]:
    """rl-zoo3's ``env_wrapper``/``vec_env_wrapper``/``callback`` value -> ``[(dotted name, kwargs), ...]``."""
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
        out.append((name, dict(kwargs)))
    return out


def _import_class(key: str, name: str):
    module, _, attr = name.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"train config key {key!r}: cannot import {name!r} ({exc})") from None


def action_mode(hp: dict[str, Any]) -> str:
    """``"setpoint"`` if the config drives the env through :mod:`pneunet_env.wrappers`' setpoint wrapper, else
    ``"rate"`` (the env's own action): what :class:`agents.policies.SB3Policy` must apply to the model's output."""
    names = [n for key in ("env_wrapper", "vec_env_wrapper") for n, _ in _class_specs(key, hp.get(key))]
    return "setpoint" if any(n in (SETPOINT_WRAPPER, SETPOINT_WRAPPER + "VecEnv") for n in names) else "rate"


def load_train_config(path: str | Path, env_id: str = ENV_ID, project: str | Path | None = None) -> dict[str, Any]:
    """Read an rl-zoo3 hyperparameter file and its ``<name>.project.yaml``: one flat dict, defaults filled in.

    Args:
        path: the rl-zoo3 file (``configs/train/ppo.yaml``).
        env_id: its entry.
        project: the project file (default :func:`project_config_path`; a missing default is no error).

    Raises:
        ValueError: a missing file or env entry, an unknown algorithm or project key, a key in both files, a
            non-positive count, or a malformed value.
    """
    path = Path(path)
    main = _read_entry(path, env_id, "train config")
    legacy = sorted(k for k in main if k in PROJECT_KEYS or k == "action")
    proj_path = project_config_path(path) if project is None else Path(project)
    ours: dict[str, Any] = {}
    if project is not None or proj_path.is_file():
        ours = _read_entry(proj_path, env_id, "project config")
        unknown = sorted(set(ours) - set(PROJECT_KEYS))
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
    algo = str(hp.get("algo") or path.stem.split("_")[0].split(".")[0]).lower()
    if algo not in ALGOS:
        raise ValueError(f"train config {str(path)!r}: unknown algo {algo!r}; valid: {', '.join(ALGOS)}")
    hp["algo"] = algo
    hp["normalize"] = parse_literal("normalize", hp["normalize"])
    if isinstance(hp["normalize"], bool):
        hp["normalize"] = {"norm_obs": True, "norm_reward": True} if hp["normalize"] else False
    elif not isinstance(hp["normalize"], dict):
        raise ValueError(f"train config key 'normalize' must be true/false or a mapping, got {hp['normalize']!r}")
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
        if isinstance(hp.get(key), str) and not re.fullmatch(r"lin_[-+0-9.eE]+", hp[key]):
            raise ValueError(f"train config key {key!r}: a number or rl-zoo3's 'lin_<initial value>', "
                             f"got {hp[key]!r}")
    for key in ("n_envs", "n_timesteps", "eval_freq", "n_eval_episodes", "n_eval_envs", "checkpoint_freq",
                "torch_threads"):
        hp[key] = _count(key, hp[key])
    hp["seed"] = int(hp["seed"])
    hp["max_train_minutes"] = float(hp["max_train_minutes"])
    if not hp["max_train_minutes"] > 0:
        raise ValueError(f"train config key 'max_train_minutes' must be > 0, got {hp['max_train_minutes']!r}")
    return hp


def _raw_list(value: Any) -> list[Any]:
    return [] if value is None else list(value) if isinstance(value, list) else [value]


class LinearSchedule:
    """rl-zoo3's ``lin_<x>``: ``x`` times the remaining progress (1 at the start, 0 at the end)."""

    def __init__(self, initial_value: float) -> None:
        self.initial_value = float(initial_value)

    def __call__(self, progress_remaining: float) -> float:
        return progress_remaining * self.initial_value

    def __repr__(self) -> str:
        return f"LinearSchedule({self.initial_value})"


def _algo_kwargs(hp: dict[str, Any]) -> dict[str, Any]:
    """The algorithm's keyword arguments: the main file's keys that are neither rl-zoo3's nor the project's."""
    skip = set(PROJECT_KEYS) | set(ZOO_KEYS)
    out = {k: v for k, v in hp.items() if k not in skip}
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if isinstance(out.get(key), str):
            out[key] = LinearSchedule(float(out[key][4:]))
    if isinstance(out.get("train_freq"), list):
        out["train_freq"] = tuple(out["train_freq"])
    return out


def _count(key: str, value: Any) -> int:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"train config key {key!r} must be a positive integer, got {value!r}") from None
    if x != int(x) or x < 1:
        raise ValueError(f"train config key {key!r} must be a positive integer, got {value!r}")
    return int(x)


def _resolve_policy_kwargs(kwargs: dict[str, Any]) -> dict[str, Any]:
    import torch.nn as nn

    out = dict(kwargs)
    for key, value in kwargs.items():
        if isinstance(value, str) and value.startswith("nn."):
            try:
                out[key] = getattr(nn, value[3:])
            except AttributeError:
                raise ValueError(f"policy_kwargs {key!r}: torch.nn has no {value[3:]!r}") from None
    return out


# ---------------------------------------------------------------------------------------------
# Environments
# ---------------------------------------------------------------------------------------------


def batched_available() -> bool:
    """Whether :mod:`pneunet_env.envs.sb3` (the SB3 adapter of the batched env) can be imported."""
    try:
        import pneunet_env.envs.sb3  # noqa: F401
    except ImportError:
        return False
    return True


def _wrapper_classes(hp: dict[str, Any], key: str) -> list[tuple[Any, dict[str, Any]]]:
    return [(_import_class(key, name), kwargs) for name, kwargs in _class_specs(key, hp.get(key))]


def make_vec_env(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None, wrap: bool = True):
    """The training or evaluation ``VecEnv`` (``hp["vec_env"]``), monitored, seeded, with the config's
    ``env_wrapper`` and ``vec_env_wrapper`` (``wrap=False``: the env's own actions; ``VecNormalize`` and
    ``frame_stack`` are applied by :func:`train`)."""
    import pneunet_env  # noqa: F401  (registers the env)

    env_wrappers = _wrapper_classes(hp, "env_wrapper") if wrap else []
    kind = hp["vec_env"]
    if kind == "batched" and not batched_available():
        warnings.warn("vec_env: batched needs pneunet_env.envs.sb3, which is missing; using dummy", stacklevel=2)
        kind = "dummy"
    if kind == "batched" and env_wrappers:
        vec_forms = [getattr(cls, "vec_env_form", None) for cls, _ in env_wrappers]
        if any(f is None for f in vec_forms):
            missing = [f"{cls.__module__}.{cls.__qualname__}" for (cls, _), f in zip(env_wrappers, vec_forms,
                                                                                    strict=True) if f is None]
            warnings.warn(f"vec_env: batched cannot apply the per-env wrapper(s) {missing} (no VecEnv form); "
                          "using dummy", stacklevel=2)
            kind = "dummy"
    if kind == "batched":
        venv = _make_batched(hp, n_envs, seed, monitor_dir)
        for cls, kwargs in env_wrappers:  # each env wrapper's VecEnv form, in the same order
            venv = getattr(importlib.import_module(cls.__module__), cls.vec_env_form)(venv, **kwargs)
    else:
        venv = _make_dummy(hp, n_envs, seed, monitor_dir, env_wrappers)
    for cls, kwargs in (_wrapper_classes(hp, "vec_env_wrapper") if wrap else []):
        venv = cls(venv, **kwargs)
    return venv


def _make_batched(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None):
    from stable_baselines3.common.vec_env import VecMonitor

    from pneunet_env.envs.sb3 import SB3VecEnv

    venv = SB3VecEnv(num_envs=n_envs, **hp["env_kwargs"])
    if monitor_dir is not None:
        monitor_dir.mkdir(parents=True, exist_ok=True)
    venv = VecMonitor(venv, filename=None if monitor_dir is None else str(monitor_dir / "batched"))
    venv.seed(seed)
    return venv


def _make_dummy(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None, env_wrappers):
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    def wrap_env(env):
        for cls, kwargs in env_wrappers:
            env = cls(env, **kwargs)
        return env

    if monitor_dir is not None:
        monitor_dir.mkdir(parents=True, exist_ok=True)
    return sb3_make_vec_env(ENV_ID, n_envs=n_envs, seed=seed, vec_env_cls=DummyVecEnv,
                            env_kwargs=dict(hp["env_kwargs"]), wrapper_class=wrap_env if env_wrappers else None,
                            monitor_dir=None if monitor_dir is None else str(monitor_dir))


# ---------------------------------------------------------------------------------------------
# Callbacks
# ---------------------------------------------------------------------------------------------


def _callbacks(hp, run_dir: Path, eval_env, seed: int, deadline: float, resuming: bool = False):
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback

    class SaveVecNormalize(BaseCallback):
        """On a new best model: save the VecNormalize statistics next to it (JSON, and SB3's pickle)."""

        def _on_step(self) -> bool:
            _save_stats(self.model, run_dir / "best_model")
            return True

    class SeededEval(EvalCallback):
        """EvalCallback on the same objects every time (the eval env is re-seeded before each evaluation).

        On a resumed run it starts from the earlier evaluations (``evaluations.npz`` keeps them all, and a new best
        model must beat the earlier best)."""

        def _init_callback(self) -> None:
            super()._init_callback()
            previous = run_dir / "evaluations.npz"
            if resuming and previous.is_file():
                import numpy as np

                data = np.load(previous)
                keep = [i for i, t in enumerate(data["timesteps"]) if t <= self.model.num_timesteps]  # a hard kill
                self.evaluations_timesteps = [int(data["timesteps"][i]) for i in keep]  # evaluated past the model
                self.evaluations_results = [list(data["results"][i]) for i in keep]
                self.evaluations_length = [list(data["ep_lengths"][i]) for i in keep]
                if "successes" in data:
                    self.evaluations_successes = [list(data["successes"][i]) for i in keep]
                pairs = zip(self.evaluations_timesteps, self.evaluations_results, strict=True)
                trained = [r for t, r in pairs if t > 0]
                if trained:  # step 0, the untrained start, is never the best model
                    self.best_mean_reward = float(max(np.mean(r) for r in trained))

        def _on_training_start(self) -> None:
            """A new run is evaluated before its first update too: step 0, the untrained policy, the learning curve's
            start. It is logged but cannot become the best model: what a run exports is a trained model (an
            untrained network may already command a good blind pressure, and would otherwise be exported as the
            "trained" one, as 0.7's first seed study found)."""
            super()._on_training_start()
            if not resuming and self.eval_freq > 0:
                calls, self.n_calls = self.n_calls, 0
                path, on_best = self.best_model_save_path, self.callback_on_new_best
                self.best_model_save_path, self.callback_on_new_best = None, None
                try:
                    self._on_step()
                finally:
                    self.n_calls = calls
                    self.best_model_save_path, self.callback_on_new_best = path, on_best
                    self.best_mean_reward = -float("inf")

        def _on_step(self) -> bool:
            if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
                self.eval_env.seed(seed)
            return super()._on_step()

    class WallClock(BaseCallback):
        """Stop training once the invocation's time budget is spent."""

        def _on_step(self) -> bool:
            if time.monotonic() > deadline:
                if self.verbose:
                    print(f"\ntime budget of {hp['max_train_minutes']:g} min spent at {self.num_timesteps} steps")
                return False
            return True

    n = hp["n_envs"]
    evaluation = SeededEval(eval_env, callback_on_new_best=SaveVecNormalize(),
                            n_eval_episodes=hp["n_eval_episodes"], eval_freq=max(1, hp["eval_freq"] // n),
                            log_path=str(run_dir), best_model_save_path=str(run_dir), deterministic=True,
                            verbose=1)
    checkpoints = CheckpointCallback(max(1, hp["checkpoint_freq"] // n), str(run_dir / "checkpoints"),
                                     name_prefix="model", save_vecnormalize=True)
    # the config's own callbacks (rl-zoo3's `callback` key), after ours
    extra = [cls(**kwargs) for cls, kwargs in _wrapper_classes(hp, "callback")]
    return [evaluation, checkpoints, WallClock(verbose=1), *extra]


def _save_stats(model, stem: Path) -> None:
    """``STEM_vecnormalize.json`` (numbers, what :mod:`agents.policies` loads) and ``STEM_vecnormalize.pkl``
    (SB3's ``VecNormalize.save``) for a model trained on a ``VecNormalize``; nothing otherwise."""
    vn = model.get_vec_normalize_env()
    if vn is not None:
        NormalizationStats.from_vecnormalize(vn).save(stem.with_name(stem.name + STATS_SUFFIX))
        vn.save(str(stem.with_name(stem.name + "_vecnormalize.pkl")))


# ---------------------------------------------------------------------------------------------
# Training
# ---------------------------------------------------------------------------------------------


_CKPT = re.compile(r"model_(\d+)_steps\.zip$")


def latest_checkpoint(run_dir: Path) -> Path | None:
    """The checkpoint with the most timesteps in ``run_dir/checkpoints`` (``None`` if there is none)."""
    found = [(int(m.group(1)), p) for p in (run_dir / "checkpoints").glob("model_*_steps.zip")
             if (m := _CKPT.search(p.name))]
    return max(found)[1] if found else None


def _checkpoint_stats(ckpt: Path) -> Path | None:
    m = _CKPT.search(ckpt.name)
    cand = ckpt.with_name(f"model_vecnormalize_{m.group(1)}_steps.pkl") if m else None
    if cand is not None and cand.is_file():
        return cand
    alt = ckpt.with_name(ckpt.stem + "_vecnormalize.pkl")
    return alt if alt.is_file() else None


def _versions() -> dict[str, str]:
    import gymnasium
    import numpy
    import stable_baselines3
    import torch

    import pneunet_env

    return {"python": platform.python_version(), "pneunet_env": pneunet_env.__version__,
            "stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__,
            "gymnasium": gymnasium.__version__, "numpy": numpy.__version__}


def train(hp: dict[str, Any], run_dir: Path, resume: Path | None = None, progress: bool = True,
          config_path: str | None = None) -> dict[str, Any]:
    """Train (or resume) one run; returns the run record written to ``run_dir/run.json``."""
    import numpy as np
    import stable_baselines3 as sb3
    import torch
    import yaml
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    t0 = time.monotonic()
    deadline = t0 + 60.0 * hp["max_train_minutes"]
    torch.set_num_threads(hp["torch_threads"])
    run_dir.mkdir(parents=True, exist_ok=True)
    seed = hp["seed"]
    set_random_seed(seed)
    algo_cls = getattr(sb3, hp["algo"].upper())
    venv = make_vec_env(hp, hp["n_envs"], seed, run_dir / "monitor")
    eval_env = make_vec_env(hp, hp["n_eval_envs"], seed + 10_000, None)
    norm = hp["normalize"]
    stats = None
    if resume is not None:
        stats = _checkpoint_stats(resume)  # SB3's pickle, in the run's own checkpoints (as trusted as the model)
    if norm:
        if stats is not None:
            venv = VecNormalize.load(str(stats), venv)
            venv.training = True
        else:
            venv = VecNormalize(venv, gamma=float(hp.get("gamma", 0.99)), **norm)
        eval_env = VecNormalize(eval_env, training=False, norm_obs=norm.get("norm_obs", True), norm_reward=False)
    if hp.get("frame_stack") is not None:
        venv = VecFrameStack(venv, hp["frame_stack"])
        eval_env = VecFrameStack(eval_env, hp["frame_stack"])
    algo_kwargs = _algo_kwargs(hp)
    if resume is not None:
        model = algo_cls.load(str(resume), env=venv, device="cpu")
        done = int(model.num_timesteps)
    else:
        model = algo_cls(hp["policy"], venv, seed=seed, device="cpu", verbose=0,
                         policy_kwargs=_resolve_policy_kwargs(hp["policy_kwargs"]), **algo_kwargs)
        done = 0
        model.save(str(run_dir / "initial_model.zip"))  # the untrained policy: step 0 of the learning curve
        _save_stats(model, run_dir / "initial_model")
    remaining = max(0, hp["n_timesteps"] - done)
    zoo = {k: v for k, v in hp.items() if k not in PROJECT_KEYS}
    (run_dir / "config.yaml").write_text(yaml.safe_dump({ENV_ID: zoo}, sort_keys=False))
    (run_dir / "config.project.yaml").write_text(yaml.safe_dump({ENV_ID: {k: hp[k] for k in PROJECT_KEYS}},
                                                                sort_keys=False))
    record_path = run_dir / "run.json"
    record = _read_record(record_path) if resume is not None else {}
    record.setdefault("invocations", [])
    record.update(algo=hp["algo"], env_id=ENV_ID, seed=seed, seeds={"train_envs": f"{seed} + i",
                  "eval_env": seed + 10_000, "torch_numpy_random": seed}, config_path=config_path,
                  hyperparameters=hp, action=action_mode(hp), versions=_versions(),
                  vec_env=type(venv.unwrapped if hasattr(venv, "unwrapped") else venv).__name__)
    if remaining > 0:
        callbacks = _callbacks(hp, run_dir, eval_env, seed + 10_000, deadline, resuming=resume is not None)
        model.learn(total_timesteps=remaining, callback=callbacks, progress_bar=progress,
                    reset_num_timesteps=resume is None)
    model.save(str(run_dir / "final_model.zip"))
    _save_stats(model, run_dir / "final_model")
    wall = time.monotonic() - t0
    evals = run_dir / "evaluations.npz"
    best = {}
    if evals.is_file():
        data = np.load(evals)
        trained = np.flatnonzero(data["timesteps"] > 0)  # step 0 is the untrained start, never the best model
        if len(trained):
            i = int(trained[np.argmax(data["results"][trained].mean(axis=1))])
            best = {"timesteps": int(data["timesteps"][i]), "mean_reward": float(data["results"][i].mean())}
            if "successes" in data and len(data["successes"]):
                best["success_rate"] = float(np.mean(data["successes"][i]))
    record["invocations"].append({"resumed_from": None if resume is None else str(resume), "start_timesteps": done,
                                  "end_timesteps": int(model.num_timesteps), "wall_s": round(wall, 1),
                                  "time_budget_min": hp["max_train_minutes"],
                                  "finished": int(model.num_timesteps) >= hp["n_timesteps"]})
    ref = reference_success(hp, seed + 10_000)
    record.update(timesteps=int(model.num_timesteps), best_eval=best,
                  best_ramp_eval_success_rate=ref,
                  total_wall_s=round(sum(i["wall_s"] for i in record["invocations"]), 1))
    write_record(record_path, record)
    venv.close()
    eval_env.close()
    plot_training(run_dir, reference=ref, reference_label="best-ramp on the same objects")
    return record


def _read_record(path: Path) -> dict[str, Any]:
    """A run's ``run.json``, or ``{}`` (with a warning) where it is missing or unreadable (a cut write)."""
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        warnings.warn(f"{path}: unreadable ({exc}); starting a new record", stacklevel=2)
        return {}
    return data if isinstance(data, dict) else {}


def write_record(path: Path, record: dict[str, Any]) -> None:
    """Write ``run.json`` whole or not at all: a temporary file in the same folder, then renamed over it."""
    atomic_write_bytes(path, (json.dumps(record, indent=1, default=str) + "\n").encode())


def reference_success(hp: dict[str, Any], seed: int, spec: str = "best-ramp") -> float | None:
    """The success rate of a scripted policy (``best-ramp``) on the evaluation objects of the run.

    The same vec env, seeds and episode split as :class:`EvalCallback`'s evaluations (the eval env's objects are
    drawn from per-env streams, the same whatever the episodes' lengths), so the numbers compare directly.
    """
    import numpy as np
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.policies import make_policy
    from pneunet_env.config import load_config

    try:
        policy = make_policy(spec, load_config(None, **hp["env_kwargs"])).policy
    except ValueError:
        return None
    venv = make_vec_env(hp, hp["n_eval_envs"], seed, None, wrap=False)  # the env's own action
    venv.seed(seed)
    successes: list[bool] = []

    def log(locals_, globals_):
        if locals_["done"]:
            successes.append(bool(locals_["info"].get("is_success", False)))

    evaluate_policy(policy, venv, n_eval_episodes=hp["n_eval_episodes"], deterministic=True, callback=log)
    venv.close()
    return float(np.mean(successes)) if successes else None


def plot_training(run_dir: Path, path: Path | None = None, reference: float | None = None,
                  reference_label: str = "best-ramp") -> Path | None:
    """Evaluation success rate and mean return vs timesteps (``run_dir/evaluations.npz``) -> ``run_dir/training.png``.

    ``reference``: a success rate to draw as a horizontal line (e.g. best-ramp's on the same evaluation objects).
    Returns ``None`` when there is nothing to plot or matplotlib is missing.
    """
    import numpy as np

    evals = run_dir / "evaluations.npz"
    if not evals.is_file():
        return None
    try:
        from agents.evaluate import _matplotlib

        plt = _matplotlib()
    except ImportError:
        return None
    data = np.load(evals)
    t = data["timesteps"]
    if not len(t):
        return None
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 4.6), sharex=True)
    if "successes" in data and len(data["successes"]):
        ax.plot(t, data["successes"].mean(axis=1), "o-", ms=3, color="#2ca02c", label="agent (deterministic)")
    if reference is not None:
        ax.axhline(reference, color="#1f5fbf", ls="--", lw=1.3, label=reference_label)
    trained = np.flatnonzero(t > 0) if (t > 0).any() else np.arange(len(t))  # the best model is a trained one
    best = int(trained[np.argmax(data["results"][trained].mean(axis=1))])
    ax.axvline(t[best], color="grey", ls=":", lw=1)
    ax.set_ylabel("success rate")
    vals = list(data["successes"].mean(axis=1)) if "successes" in data and len(data["successes"]) else []
    vals += [] if reference is None else [reference]
    if vals:
        ax.set_ylim(max(-0.02, min(vals) - 0.1), min(1.02, max(vals) + 0.1))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    ax2.plot(t, data["results"].mean(axis=1), "o-", ms=3, color="black")
    ax2.axvline(t[best], color="grey", ls=":", lw=1, label="best model (saved)")
    ax2.set_ylabel("mean return")
    ax2.set_xlabel("timesteps")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    n_eval = data["results"].shape[1]
    fig.suptitle(f"evaluation during training ({n_eval} episodes each, the same objects every time)", fontsize=9)
    fig.tight_layout()
    path = run_dir / "training.png" if path is None else path
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def export(run_dir: Path, dest: Path, record: dict[str, Any]) -> Path:
    """Copy the best model (else the final one), its statistics and a metadata JSON to ``dest.zip``,
    ``dest_vecnormalize.json`` and ``dest.json``.

    Each file is replaced atomically: every new file is first written in full (and flushed) to a temporary file in
    ``dest``'s folder, and only then are they renamed over the old ones (``os.replace``), so a failure while writing
    (a full disk, an interrupt) leaves the previous export whole and no temporary file behind. A statistics file of
    an earlier export is removed only when the new model has none, after the new model is in place, so a model is
    never paired with stale statistics.
    """
    src, stem = run_dir / "best_model.zip", run_dir / "best_model"
    model_timesteps = record["best_eval"].get("timesteps")
    if not src.is_file():
        src, stem = run_dir / "final_model.zip", run_dir / "final_model"
        model_timesteps = record["timesteps"]
    stats = _run_stats(stem)
    hyper = record["hyperparameters"]
    meta = {"algo": record["algo"], "action": record.get("action") or action_mode(hyper), "env_id": record["env_id"],
            "source": str(src), "seed": record["seed"], "model_timesteps": model_timesteps,
            "timesteps": record["timesteps"], "total_wall_s": record["total_wall_s"], "best_eval": record["best_eval"],
            "best_ramp_eval_success_rate": record.get("best_ramp_eval_success_rate"),
            "hyperparameters": hyper, "versions": record["versions"], "reproduce": record.get("command")}
    dest.parent.mkdir(parents=True, exist_ok=True)
    zip_path = dest.with_suffix(".zip")
    stats_dest = dest.with_name(dest.name + STATS_SUFFIX)
    outputs: list[tuple[Path, bytes | Path]] = [(zip_path, src)]
    if stats is not None:
        outputs.append((stats_dest, (json.dumps(stats.to_dict(), indent=1) + "\n").encode()))
    outputs.append((dest.with_suffix(".json"), (json.dumps(meta, indent=1, default=str) + "\n").encode()))
    staged: list[tuple[Path, Path]] = []
    try:
        for final, content in outputs:
            staged.append((stage_file(final, content), final))
        for tmp, final in staged:
            os.replace(tmp, final)
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
    if stats is None:
        stats_dest.unlink(missing_ok=True)
    return zip_path


def _run_stats(stem: Path) -> NormalizationStats | None:
    """The statistics saved beside a model of the run (JSON; a run of an older version has only SB3's pickle,
    which is read: it is the run's own output, in the folder of the model that is unpickled as well)."""
    js = stem.with_name(stem.name + STATS_SUFFIX)
    if js.is_file():
        return NormalizationStats.load(js)
    pkl = stem.with_name(stem.name + "_vecnormalize.pkl")
    if pkl.is_file():
        return NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(pkl))
    return None


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", required=True,
                        help="rl-zoo3 hyperparameter YAML (configs/train/ppo.yaml), or a shipped config's name (ppo, "
                             "sac); this command's own keys are read from NAME.project.yaml beside it")
    parser.add_argument("--run-dir", type=Path, default=None, help="output directory (default runs/<algo>)")
    parser.add_argument("--resume", nargs="?", const="latest", default=None, metavar="CHECKPOINT",
                        help="resume from CHECKPOINT.zip, or (no value) from the newest checkpoint of --run-dir")
    parser.add_argument("--timesteps", type=float, default=None, help="override n_timesteps")
    parser.add_argument("--n-envs", type=int, default=None, help="override n_envs")
    parser.add_argument("--seed", type=int, default=None, help="override seed")
    parser.add_argument("--eval-freq", type=float, default=None, help="override eval_freq (timesteps)")
    parser.add_argument("--n-eval-episodes", type=int, default=None, help="override n_eval_episodes")
    parser.add_argument("--checkpoint-freq", type=float, default=None, help="override checkpoint_freq (timesteps)")
    parser.add_argument("--max-minutes", type=float, default=None, help="override max_train_minutes")
    parser.add_argument("--vec-env", choices=("batched", "dummy"), default=None, help="override vec_env")
    parser.add_argument("--threads", type=int, default=None,
                        help="torch threads (override torch_threads; default 1: the batched env's numba threads run "
                             "beside it)")
    parser.add_argument("--seeds", type=int, default=None, metavar="N",
                        help="train N seeds (seed, seed+1, ...) in RUN_DIR/seed-K, then score each on held-out objects "
                             "with its untrained start and best-ramp: seeds.json, learning_curves.png; --export then "
                             "exports the median seed's model (agents.seeds)")
    parser.add_argument("--jobs", type=int, default=1, help="with --seeds: seeds trained at once, one process each")
    parser.add_argument("--objects", type=int, default=400,
                        help="with --seeds: held-out objects each seed's model is scored on (default 400, demo's)")
    parser.add_argument("--export", type=Path, default=None, metavar="PATH_STEM",
                        help="copy the best model to PATH_STEM.zip (+ _vecnormalize.json, .json), "
                             "e.g. agents/models/ppo_pneunet")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="set an environment config key in env_kwargs (repeatable; VALUE is YAML), e.g. "
                             "--set observe_volume=true")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _command(args: argparse.Namespace, run_dir: Path) -> str:
    """The command line of this invocation (recorded in run.json and the exported model's JSON)."""
    parts = ["pneunet-grasp train", f"--config {getattr(args, 'config_given', args.config)}", f"--run-dir {run_dir}"]
    for flag, value in (("--timesteps", args.timesteps), ("--n-envs", args.n_envs), ("--seed", args.seed),
                        ("--eval-freq", args.eval_freq), ("--n-eval-episodes", args.n_eval_episodes),
                        ("--checkpoint-freq", args.checkpoint_freq), ("--max-minutes", args.max_minutes),
                        ("--vec-env", args.vec_env), ("--threads", args.threads), ("--export", args.export)):
        if value is not None:
            parts.append(f"{flag} {value:g}" if isinstance(value, float) else f"{flag} {value}")
    parts += [f"--set {item}" for item in getattr(args, "overrides", [])]
    if args.resume is not None:
        parts.append("--resume" if args.resume == "latest" else f"--resume {args.resume}")
    return " ".join(parts)


def run(args: argparse.Namespace) -> int:
    try:
        from agents.resources import resolve_config

        args.config_given = getattr(args, "config_given", args.config)  # as typed: the run's record shows it
        args.config = str(resolve_config(args.config, "train"))
        hp = load_train_config(args.config)
        for key, value in (("n_timesteps", args.timesteps), ("n_envs", args.n_envs), ("seed", args.seed),
                           ("eval_freq", args.eval_freq), ("n_eval_episodes", args.n_eval_episodes),
                           ("checkpoint_freq", args.checkpoint_freq)):
            if value is not None:
                hp[key] = _count(key, value) if key != "seed" else int(value)
        if args.max_minutes is not None:
            if not args.max_minutes > 0:
                raise ValueError(f"--max-minutes must be > 0, got {args.max_minutes}")
            hp["max_train_minutes"] = float(args.max_minutes)
        if args.vec_env is not None:
            hp["vec_env"] = args.vec_env
        if args.threads is not None:
            hp["torch_threads"] = _count("--threads", args.threads)
        if args.overrides:
            from agents.evaluate import parse_overrides
            from pneunet_env.config import load_config

            env_kwargs = {**(hp.get("env_kwargs") or {}), **parse_overrides(args.overrides)}
            load_config(None, **env_kwargs)  # a bad key or value is named here, before training starts
            hp["env_kwargs"] = env_kwargs
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp train: {exc}") from None
    run_dir = args.run_dir or Path("runs") / hp["algo"]
    if args.seeds is not None:
        from agents.seeds import run_seeds

        return run_seeds(args, hp, run_dir)
    resume = None
    if args.resume is not None:
        resume = latest_checkpoint(run_dir) if args.resume == "latest" else Path(args.resume)
        if resume is None or not resume.is_file():
            raise SystemExit(f"pneunet-grasp train: no checkpoint to resume from ({args.resume} in {run_dir})")
    print(f"training {hp['algo'].upper()} on {ENV_ID} ({hp['vec_env']} vec env, {hp['n_envs']} envs) for "
          f"{hp['n_timesteps']} timesteps, at most {hp['max_train_minutes']:g} min; seed {hp['seed']}; -> {run_dir}"
          + (f"; resuming from {resume}" if resume else ""))
    record = train(hp, run_dir, resume, progress=not args.no_progress, config_path=str(args.config))
    record["command"] = _command(args, run_dir)
    write_record(run_dir / "run.json", record)
    inv = record["invocations"][-1]
    print(f"{inv['end_timesteps']} timesteps ({inv['end_timesteps'] - inv['start_timesteps']} this run) in "
          f"{inv['wall_s']:.0f} s; best evaluation: {record['best_eval']}")
    if args.export is not None:
        path = export(run_dir, args.export, record)
        print(f"exported {export_source(run_dir)} to {path}")
    return 0


def export_source(run_dir: Path) -> str:
    """What :func:`export` copies from ``run_dir``, in words."""
    if (run_dir / "best_model.zip").is_file():
        return "the best evaluation's model"
    return "the final model (no evaluation ran, so there is no best model)"
