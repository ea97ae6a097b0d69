"""EnvConfig: the YAML file equals the defaults, every key is validated, gym.make takes configs."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest
import yaml

import pneunet_env  # noqa: F401  (registers the environment)
from pneunet_env.config import DEFAULT_CONFIG_PATH, RANGE_FIELDS, EnvConfig, load_config
from pneunet_env.physics.solver import SolverOptions
from pneunet_env.physics.units import PhysicalActuator


def test_default_yaml_equals_defaults_and_lists_every_key():
    data = yaml.safe_load(DEFAULT_CONFIG_PATH.read_text())
    assert list(data) == list(EnvConfig.keys()), "default.yaml must list every key, in field order"
    assert EnvConfig.from_yaml(DEFAULT_CONFIG_PATH) == EnvConfig()
    assert load_config(DEFAULT_CONFIG_PATH) == EnvConfig()


def test_default_yaml_comments_every_key():
    for line in DEFAULT_CONFIG_PATH.read_text().splitlines():
        if line and not line.startswith("#") and ":" in line:
            assert "#" in line, f"default.yaml key without a comment: {line!r}"


def test_defaults_are_the_papers():
    cfg = EnvConfig()
    assert cfg.physical_actuator == PhysicalActuator()
    assert cfg.actuator_params == PhysicalActuator().to_dimensionless()
    assert cfg.solver_options == SolverOptions()
    assert cfg.pressure_max == pytest.approx(1.2)
    assert cfg.episode_steps == cfg.squeeze_steps + cfg.hold_steps == 100


def test_default_stiffness_range_covers_the_papers_regimes():
    from pneunet_env.objects import stiffness_per_modulus

    cfg = EnvConfig()
    unit = stiffness_per_modulus(cfg.object_thickness_mm[0], cfg.object_curvature_per_m[0], cfg.scales)
    lo, hi = (m * unit for m in cfg.object_shear_modulus_kpa)
    assert lo <= 1e-5 and hi >= 1e-1


def test_unknown_key_is_named():
    with pytest.raises(ValueError, match="unknown config key 'max_presure_kpa'"):
        load_config(max_presure_kpa=10.0)
    with pytest.raises(ValueError, match="'bogus'"):
        load_config({"bogus": 1})


def test_unknown_key_in_yaml_is_named(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("hold_steps: 10\nsqueeze_step: 5\n")
    with pytest.raises(ValueError, match="'squeeze_step'"):
        load_config(path)


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("max_pressure_kpa", -1.0, "max_pressure_kpa"),
        ("max_pressure_kpa", float("nan"), "max_pressure_kpa"),
        ("max_pressure_step_kpa", 100.0, "max_pressure_step_kpa"),
        ("hold_steps", 0, "hold_steps"),
        ("hold_steps", 2.5, "hold_steps"),
        ("squeeze_steps", "ten", "squeeze_steps"),
        ("observe_volume", "yes", "observe_volume"),
        ("friction_coefficient", 0.0, "friction_coefficient"),
        ("penalty_damage", -1.0, "penalty_damage"),
        ("object_shear_modulus_kpa", [10.0, 1.0], "object_shear_modulus_kpa"),
        ("object_shear_modulus_kpa", [0.0, 1.0], "object_shear_modulus_kpa"),
        ("object_density_kg_m3", [1.0, 2.0, 3.0], "object_density_kg_m3"),
        ("object_thickness_mm", "thick", "object_thickness_mm"),
        ("object_thickness_mm", [10.0, 300.0], "object_thickness_mm"),
        ("object_curvature_per_m", 700.0, "object_curvature_per_m"),
        ("side_thickness_mm", 6.0, "side_thickness"),
        ("gent_limit", 0.0, "gent_limit"),
        ("solver_min_step", 1.0, "min_step"),
        ("render_width", 8, "render_width"),
    ],
)
def test_invalid_values_are_named(key, value, match):
    with pytest.raises(ValueError, match=match):
        load_config(**{key: value})


def test_ranges_accept_a_single_number_and_round_trip():
    cfg = load_config(object_thickness_mm=20, object_shear_modulus_kpa=[1, 2])
    assert cfg.object_thickness_mm == (20.0, 20.0)
    assert cfg.object_shear_modulus_kpa == (1.0, 2.0)
    assert EnvConfig(**cfg.to_dict()) == cfg
    assert load_config(cfg) == cfg
    assert all(isinstance(getattr(cfg, n), tuple) for n in RANGE_FIELDS)


def test_precedence_defaults_then_config_then_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("hold_steps: 10\nsqueeze_steps: 5\n")
    cfg = load_config(path, hold_steps=7)
    assert (cfg.squeeze_steps, cfg.hold_steps, cfg.max_pressure_kpa) == (5, 7, EnvConfig().max_pressure_kpa)
    assert EnvConfig().replace(hold_steps=3).hold_steps == 3
    with pytest.raises(ValueError, match="'nope'"):
        EnvConfig().replace(nope=1)


def test_config_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        EnvConfig().hold_steps = 3  # type: ignore[misc]


def test_gym_make_takes_path_dict_and_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("max_pressure_kpa: 40.0\nobserve_volume: true\n")
    env = gym.make("PneuNetGrasp-v0", config=str(path), max_pressure_step_kpa=2.0)
    cfg = env.unwrapped.config
    assert (cfg.max_pressure_kpa, cfg.max_pressure_step_kpa, cfg.observe_volume) == (40.0, 2.0, True)
    assert env.observation_space.shape == (2,)
    env.close()
    env = gym.make("PneuNetGrasp-v0", config={"hold_steps": 5})
    assert env.unwrapped.config.hold_steps == 5
    env.close()
    with pytest.raises(ValueError, match="'hold_step'"):
        gym.make("PneuNetGrasp-v0", hold_step=5)


def test_registered_time_limit_is_the_default_episode_length():
    spec = gym.spec("PneuNetGrasp-v0")
    assert spec.max_episode_steps == EnvConfig().episode_steps
    assert spec.entry_point == "pneunet_env.envs.grasp:PneuNetGraspEnv"
    env = gym.make("pneunet_env:PneuNetGrasp-v0")
    assert env.spec.max_episode_steps == EnvConfig().episode_steps
    env.close()


def test_non_mapping_yaml_is_rejected(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="mapping"):
        load_config(path)
    with pytest.raises(ValueError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
