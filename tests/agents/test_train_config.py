"""The train config (:mod:`agents.training.config`): read by the one YAML reader (duplicate keys refused, YAML 1.2
numbers), only documented classes callable, boolean keyword arguments checked (issue 21). The rl-zoo3 layout, the
project file and the legacy form: ``test_train.py``."""

from __future__ import annotations

import pytest

from agents.training.config import (
    CALLABLE_PACKAGES,
    _algo_kwargs,
    _resolve_policy_kwargs,
    _wrapper_classes,
    load_train_config,
)
from pneunet_env.config import ConfigTypeError


def _config(tmp_path, body: str, project: str | None = None):
    path = tmp_path / "ppo.yaml"
    path.write_text("PneuNetGrasp-v1:\n" + "".join(f"  {line}\n" for line in body.strip().splitlines()))
    if project is not None:
        (tmp_path / "ppo.project.yaml").write_text(
            "PneuNetGrasp-v1:\n" + "".join(f"  {line}\n" for line in project.strip().splitlines()))
    return path


# ---------------------------------------------------------------------------------------------
# The one reader
# ---------------------------------------------------------------------------------------------


def test_a_duplicate_key_is_refused_naming_it_the_file_and_the_line(tmp_path):
    """Before: the second ``n_timesteps`` won, silently."""
    path = _config(tmp_path, "n_timesteps: 1000\nn_envs: 2\nn_timesteps: 2000000")
    with pytest.raises(ValueError, match=r"ppo\.yaml', line 4, column 3: duplicate key 'n_timesteps' \(first at "
                                         r"line 2\)"):
        load_train_config(path)
    path = _config(tmp_path, "n_envs: 2", project="seed: 1\nseed: 2")
    with pytest.raises(ValueError, match=r"ppo\.project\.yaml'.*duplicate key 'seed'"):
        load_train_config(path)


def test_yaml_1_2_numbers_are_numbers(tmp_path):
    """Before: ``learning_rate: 3e-4`` was the string '3e-4' (YAML 1.1), refused as not 'lin_<x>'."""
    hp = load_train_config(_config(tmp_path, "learning_rate: 3e-4\nn_timesteps: 2e6\nclip_range: lin_2e-1"))
    assert hp["learning_rate"] == 3e-4 and hp["n_timesteps"] == 2_000_000
    assert _algo_kwargs(hp)["clip_range"](1.0) == pytest.approx(0.2)


@pytest.mark.parametrize("body, project, match", [
    ("n_envs: true", None, "'n_envs' must be a positive integer"),  # was read as 1
    ("n_timesteps: .inf", None, "'n_timesteps' must be a positive integer"),  # was a raw OverflowError
    ("n_timesteps: 1.5", None, "'n_timesteps' must be a positive integer"),
    ("n_envs: 2", "seed: abc", "'seed' must be an integer >= 0"),  # was int('abc')'s message, naming nothing
    ("n_envs: 2", "seed: 1.5", "'seed' must be an integer >= 0"),  # was read as 1
    ("n_envs: 2", "seed: -1", "'seed' must be an integer >= 0"),
    ("n_envs: 2", "max_train_minutes: soon", "'max_train_minutes' must be a number"),
    ("learning_rate: lin_inf", None, "learning_rate"),
    ("learning_rate: true", None, "learning_rate"),
    ("policy: [MlpPolicy]", None, "'policy' must be a policy name"),
    ("normalize: {norm_obs: 'false'}", None, "'normalize.norm_obs' must be true or false"),  # was true
    ("policy_kwargs: \"dict(**{'a': 1})\"", None, "policy_kwargs"),
    ("policy_kwargs: \"{[1]: 2}\"", None, "policy_kwargs"),
])
def test_bad_values_are_refused_by_name(tmp_path, body, project, match):
    with pytest.raises(ValueError, match=match):
        load_train_config(_config(tmp_path, body, project))


# ---------------------------------------------------------------------------------------------
# Only documented classes: a train config is data, not code
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("key, name", [
    ("callback", "subprocess.run"),
    ("callback", "os.system"),
    ("env_wrapper", "builtins.eval"),
    ("vec_env_wrapper", "rl_zoo3.benchmark.Anything"),  # importing rl_zoo3.benchmark runs its benchmark script
    ("callback", "pneunet_env.cli.__main__.main"),  # a private part: importing __main__ would run the CLI
    ("env_wrapper", "agents.design.__main__.X"),
    ("env_wrapper", ".relative.Name"),
])
def test_a_name_outside_the_allowed_packages_is_refused_before_any_import(tmp_path, key, name, monkeypatch):
    """Before: ``callback: [{subprocess.run: {args: [...]}}]`` ran the command when training started."""
    import importlib

    imported = []
    real = importlib.import_module
    monkeypatch.setattr(importlib, "import_module", lambda mod, *a: imported.append(mod) or real(mod, *a))
    marker = tmp_path / "ran"
    path = _config(tmp_path, f"{key}: [{{{name}: {{args: [touch, {marker}]}}}}]")
    with pytest.raises(ValueError, match=f"train config key '{key}'.*{name.split('.')[0] or 'dotted'}") as info:
        load_train_config(path)
        _wrapper_classes(load_train_config(path), key)
    assert "data, not code" in str(info.value) and not marker.exists()
    with pytest.raises(ValueError, match=f"train config key '{key}'"):
        _wrapper_classes({key: name}, key)
    assert not any(m.startswith(("subprocess", "os", "builtins", "rl_zoo3")) or "__main__" in m for m in imported)


@pytest.mark.parametrize("key, name, why", [
    ("env_wrapper", "pneunet_env.wrappers.setpoint_to_rate", "is not a class"),
    ("env_wrapper", "pneunet_env.config.EnvConfig", "is not a gymnasium.Wrapper"),
    ("callback", "pneunet_env.wrappers.PressureSetpoint", "is not a stable_baselines3.common.callbacks.BaseCallback"),
    ("vec_env_wrapper", "pneunet_env.wrappers.PressureSetpoint", "is not a stable_baselines3.common.vec_env"),
    ("env_wrapper", "gymnasium.make", "is not a class"),
    ("callback", "stable_baselines3.common.callbacks.np", "is not a class"),  # a module re-exported by SB3
    ("env_wrapper", "pneunet_env.wrappers.nothing_here", "cannot import"),
])
def test_only_classes_of_the_right_base_are_imported(key, name, why):
    pytest.importorskip("stable_baselines3")
    with pytest.raises(ValueError, match=f"'{key}': '{name}' {why}" if why != "cannot import" else why):
        _wrapper_classes({key: name}, key)


def test_documented_classes_still_load(tmp_path):
    """rl-zoo3's layout keeps working for SB3's, sb3-contrib's, Gymnasium's and this package's classes."""
    pytest.importorskip("stable_baselines3")
    from gymnasium.wrappers import TimeLimit
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

    from pneunet_env.wrappers import PressureSetpoint, PressureSetpointVecEnv

    body = ("env_wrapper: [pneunet_env.wrappers.PressureSetpoint, {gymnasium.wrappers.TimeLimit: "
            "{max_episode_steps: 100}}]\n"
            "vec_env_wrapper: pneunet_env.wrappers.PressureSetpointVecEnv\n"
            "callback: [{stable_baselines3.common.callbacks.StopTrainingOnMaxEpisodes: {max_episodes: 5}}]")
    hp = load_train_config(_config(tmp_path, body))
    assert _wrapper_classes(hp, "env_wrapper") == [(PressureSetpoint, {}), (TimeLimit, {"max_episode_steps": 100})]
    assert _wrapper_classes(hp, "vec_env_wrapper") == [(PressureSetpointVecEnv, {})]
    assert _wrapper_classes(hp, "callback") == [(StopTrainingOnMaxEpisodes, {"max_episodes": 5})]
    if "sb3_contrib" in CALLABLE_PACKAGES:
        contrib = pytest.importorskip("sb3_contrib.common.wrappers")
        assert _wrapper_classes({"env_wrapper": "sb3_contrib.common.wrappers.TimeFeatureWrapper"},
                                "env_wrapper") == [(contrib.TimeFeatureWrapper, {})]


def test_a_class_that_rl_zoo3_patched_in_still_loads(monkeypatch):
    """Importing rl-zoo3 (its ``gym_patches``) replaces ``gymnasium.wrappers.TimeLimit`` with a subclass defined in
    rl-zoo3; a config naming Gymnasium's TimeLimit still loads then (CI met this when an earlier test in the same
    worker had imported rl-zoo3), while a class from another module placed there is still refused."""
    import gymnasium.wrappers

    patched = type("PatchedTimeLimit", (gymnasium.wrappers.TimeLimit,), {"__module__": "rl_zoo3.gym_patches"})
    monkeypatch.setattr(gymnasium.wrappers, "TimeLimit", patched)
    assert _wrapper_classes({"env_wrapper": "gymnasium.wrappers.TimeLimit"}, "env_wrapper") == [(patched, {})]
    foreign = type("TimeLimit", (gymnasium.Wrapper,), {"__module__": "rl_zoo3.wrappers"})
    monkeypatch.setattr(gymnasium.wrappers, "TimeLimit", foreign)
    with pytest.raises(ValueError, match="is defined in rl_zoo3.wrappers, outside the allowed packages"):
        _wrapper_classes({"env_wrapper": "gymnasium.wrappers.TimeLimit"}, "env_wrapper")


def test_policy_kwargs_nn_names_must_be_module_classes():
    pytest.importorskip("torch")
    import torch.nn as nn

    assert _resolve_policy_kwargs({"activation_fn": "nn.Tanh"})["activation_fn"] is nn.Tanh
    with pytest.raises(ValueError, match="'nn.init' is not a torch.nn.Module class"):  # was the module, passed on
        _resolve_policy_kwargs({"activation_fn": "nn.init"})
    with pytest.raises(ValueError, match="torch.nn has no"):
        _resolve_policy_kwargs({"activation_fn": "nn.__class__"})


# ---------------------------------------------------------------------------------------------
# Boolean keyword arguments
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("body, key", [
    ("use_sde: 'false'", "use_sde"),  # PPO would read the string as true
    ("normalize_advantage: 'no'", "normalize_advantage"),
    ("policy_kwargs: {ortho_init: 'no'}", "policy_kwargs.ortho_init"),
    ("policy_kwargs: \"dict(squash_output='False')\"", "policy_kwargs.squash_output"),
])
def test_string_booleans_of_the_algorithm_and_policy_are_refused_by_name(tmp_path, body, key):
    pytest.importorskip("stable_baselines3")
    hp = load_train_config(_config(tmp_path, body))
    with pytest.raises(ConfigTypeError, match=f"config key '{key}' must be true or false"):
        _algo_kwargs(hp)


def test_real_booleans_pass(tmp_path):
    pytest.importorskip("stable_baselines3")
    hp = load_train_config(_config(tmp_path, "use_sde: true\npolicy_kwargs: {ortho_init: false}"))
    assert _algo_kwargs(hp)["use_sde"] is True
