"""EnvConfig: the YAML file equals the defaults, every key is validated, gym.make takes configs."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest
import yaml

import pneunet_env  # noqa: F401  (registers the environment)
from pneunet_env.config import DEFAULT_CONFIG_PATH, RANGE_FIELDS, SECTIONS, EnvConfig, load_config
from pneunet_env.physics.solver import SolverOptions
from pneunet_env.physics.units import PhysicalActuator


def test_default_yaml_equals_defaults_and_lists_every_key():
    data = yaml.safe_load(DEFAULT_CONFIG_PATH.read_text())
    assert list(data) == list(SECTIONS), "default.yaml must list every section, in order"
    for section, cls in SECTIONS.items():
        names = [f.name for f in dataclasses.fields(cls)]
        assert list(data[section]) == names, f"section {section}: every key, in order"
    assert EnvConfig.from_yaml(DEFAULT_CONFIG_PATH) == EnvConfig()
    assert load_config(DEFAULT_CONFIG_PATH) == EnvConfig()


def test_default_yaml_comments_every_key():
    for line in DEFAULT_CONFIG_PATH.read_text().splitlines():
        if line.startswith(" ") and ":" in line:
            assert "#" in line, f"default.yaml key without a comment: {line!r}"


def test_defaults_are_the_papers():
    cfg = EnvConfig()
    assert cfg.actuator == PhysicalActuator()
    assert cfg.actuator_params == PhysicalActuator().to_dimensionless()
    assert cfg.solver == SolverOptions()
    assert cfg.pressure_max == pytest.approx(1.2)
    assert cfg.episode_steps == cfg.task.squeeze_steps + cfg.task.hold_steps == 100


def test_default_stiffness_range_covers_the_papers_regimes():
    from pneunet_env.objects import stiffness_per_modulus

    cfg = EnvConfig()
    unit = stiffness_per_modulus(cfg.objects.object_thickness_mm[0], cfg.objects.object_curvature_per_m[0], cfg.scales)
    lo, hi = (m * unit for m in cfg.objects.object_shear_modulus_kpa)
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
        ("render_width", 8, "render.width"),
        ("render_width", 10**6, "render.width"),
        ("max_iter", 1.5, "max_iter"),
        ("solver_max_iter", 1e300, "max_iter"),
        ("terminate_on_slip", 1, "terminate_on_slip"),
    ],
)
def test_invalid_values_are_named(key, value, match):
    with pytest.raises(ValueError, match=match):
        load_config(**{key: value, "use_case": None})  # the ranges are checked as the objects' source


def test_ranges_accept_a_single_number_and_round_trip():
    cfg = load_config(object_thickness_mm=20, object_shear_modulus_kpa=[1, 2])
    assert cfg.objects.object_thickness_mm == (20.0, 20.0)
    assert cfg.objects.object_shear_modulus_kpa == (1.0, 2.0)
    assert load_config(cfg.to_dict()) == cfg
    assert load_config(cfg) == cfg
    assert all(isinstance(getattr(cfg.objects, n), tuple) for n in RANGE_FIELDS)


def test_precedence_defaults_then_config_then_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("hold_steps: 10\nsqueeze_steps: 5\n")
    cfg = load_config(path, hold_steps=7)
    t = cfg.task
    assert (t.squeeze_steps, t.hold_steps, t.max_pressure_kpa) == (5, 7, EnvConfig().task.max_pressure_kpa)
    assert EnvConfig().replace(hold_steps=3).task.hold_steps == 3
    with pytest.raises(ValueError, match="'nope'"):
        EnvConfig().replace(nope=1)


def test_config_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        EnvConfig().task.hold_steps = 3  # type: ignore[misc]


def test_gym_make_takes_path_dict_and_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("max_pressure_kpa: 40.0\nobserve_volume: true\n")
    env = gym.make("PneuNetGrasp-v1", config=str(path), max_pressure_step_kpa=2.0)
    cfg = env.unwrapped.config
    assert (cfg.task.max_pressure_kpa, cfg.task.max_pressure_step_kpa, cfg.task.observe_volume) == (40.0, 2.0, True)
    assert env.observation_space.shape == (2,)
    env.close()
    env = gym.make("PneuNetGrasp-v1", config={"hold_steps": 5})
    assert env.unwrapped.config.task.hold_steps == 5
    env.close()
    with pytest.raises(ValueError, match="'hold_step'"):
        gym.make("PneuNetGrasp-v1", hold_step=5)


def test_registered_time_limit_is_the_default_episode_length():
    spec = gym.spec("PneuNetGrasp-v1")
    assert spec.max_episode_steps == EnvConfig().episode_steps
    assert spec.entry_point == "pneunet_env.envs.grasp:PneuNetGraspEnv"
    env = gym.make("pneunet_env:PneuNetGrasp-v1")
    assert env.spec.max_episode_steps == EnvConfig().episode_steps
    env.close()


def test_non_mapping_yaml_is_rejected(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="mapping"):
        load_config(path)
    with pytest.raises(ValueError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")


def test_nested_and_flat_keys_are_one_config(tmp_path):
    nested = load_config({"task": {"max_pressure_kpa": 40.0}, "render": {"width": 64}, "solver": {"gtol": 1e-10}})
    flat = load_config(max_pressure_kpa=40.0, render_width=64, solver_gtol=1e-10)
    assert nested == flat == load_config(max_pressure_kpa=40.0, width=64, gtol=1e-10)
    assert nested.task.max_pressure_kpa == 40.0 and nested.render.width == 64 and nested.solver.gtol == 1e-10
    path = tmp_path / "nested.yaml"
    path.write_text("task:\n  hold_steps: 7\nobjects:\n  object_thickness_mm: 12\n")
    cfg = load_config(path)
    assert cfg.task.hold_steps == 7 and cfg.objects.object_thickness_mm == (12.0, 12.0)
    with pytest.raises(ValueError, match="'hold_steps' belongs to section 'task'"):
        load_config({"render": {"hold_steps": 3}})
    with pytest.raises(ValueError, match="section 'task' must be a mapping"):
        load_config({"task": 3})
    # field names are unique across sections, so every flat key means one thing
    names = [f.name for cls in SECTIONS.values() for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names))


def test_sections_are_the_objects_their_consumers_take():
    from pneunet_env.task import TaskParams

    cfg = EnvConfig()
    assert isinstance(cfg.solver, SolverOptions) and isinstance(cfg.actuator, PhysicalActuator)
    tp = TaskParams.from_config(cfg)
    assert tp.squeeze_steps == cfg.task.squeeze_steps and tp.pressure_max == pytest.approx(1.2)


def test_malformed_yaml_names_the_file(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("task: [1, 2\n")
    with pytest.raises(ValueError, match="bad.yaml"):
        load_config(path)


# ---------------------------------------------------------------------------------------------
# Class weights and booleans (issue 21): refused by name, never silently wrong
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("weights, match", [
    ({"apple": 1e308, "kiwifruit": 1e308}, "sum past the largest float"),  # was accepted: apples drawn 0 %
    ({"apple": 0.0, "kiwifruit": 0.0}, "must not all be zero"),
    ({"apple": float("nan"), "kiwifruit": 1.0}, "'apple' must be a finite number"),
    ({"apple": float("inf")}, "'apple' must be a finite number"),
    ({"apple": -1.0, "kiwifruit": 1.0}, "'apple' must be a finite number >= 0"),
    ({"apple": True}, "'apple' must be a number"),
    ({"apple": "1"}, "'apple' must be a number"),
])
def test_bad_class_weights_are_refused_by_name(weights, match):
    with pytest.raises(ValueError, match=match) as info:
        load_config(class_weights=weights)
    assert "class_weights" in str(info.value)
    # the same through the section's own constructor (which used to drop a NaN or negative weight silently)
    from pneunet_env.config import ObjectConfig

    with pytest.raises(ValueError, match="class_weights"):
        ObjectConfig(class_weights=weights)


def test_class_table_refuses_overflowing_and_invalid_weights():
    from pneunet_env.catalogue import class_table

    with pytest.raises(ValueError, match="sum past the largest float"):
        class_table((("apple", 1e308), ("kiwifruit", 1e308)))
    with pytest.raises(ValueError, match="'apple' must be a finite number >= 0"):
        class_table((("apple", float("nan")), ("kiwifruit", 1.0)))
    with pytest.raises(ValueError, match="'apple' must be a finite number >= 0"):
        class_table((("apple", -1.0), ("kiwifruit", 1.0)))
    # large weights that do not overflow draw by their ratio
    table = class_table((("apple", 1e307), ("kiwifruit", 3e307)))
    assert table.cumulative[0] == pytest.approx(0.25)


@pytest.mark.parametrize("key", ["terminate_on_damage", "terminate_on_slip", "observe_volume"])
@pytest.mark.parametrize("value", ["no", "false", "False", "0", 0, 1, None])
def test_boolean_keys_refuse_strings_and_numbers_by_name(key, value):
    from pneunet_env.config import ConfigTypeError, TaskConfig

    with pytest.raises(TypeError, match=f"config key '{key}' must be true or false"):
        load_config(**{key: value})
    with pytest.raises(ValueError, match=key):  # also the ValueError load_config documents
        load_config(**{key: value})
    with pytest.raises(ConfigTypeError, match=key):  # the dataclass itself: "no" used to be accepted, as true
        TaskConfig(**{key: value})


def test_use_case_must_be_a_string():
    from pneunet_env.config import ObjectConfig

    with pytest.raises(TypeError, match="'use_case' must be a string or null"):
        ObjectConfig(use_case=["kitchen"])


# ---------------------------------------------------------------------------------------------
# One rule for booleans, wherever typed (issue 32): a file, --set and a keyword argument agree
# ---------------------------------------------------------------------------------------------

# (the value as YAML text in a file and in --set, the same value as a keyword argument, what a boolean key reads)
BOOLEANS = [
    ("true", True, True), ("True", True, True), ("TRUE", True, True),
    ("false", False, False), ("False", False, False), ("FALSE", False, False),
    ("yes", "yes", None), ("no", "no", None), ("Yes", "Yes", None), ("NO", "NO", None),  # YAML 1.1's booleans
    ("on", "on", None), ("off", "off", None), ("On", "On", None), ("OFF", "OFF", None),
    ("1", 1, None), ("0", 0, None), ("1.0", 1.0, None),
    ("'yes'", "yes", None), ("'true'", "true", None), ('"false"', "false", None),  # strings
    ("null", None, None),
]


def _read_bool(key, text, value, tmp_path):
    """What ``key`` reads from each path: ``{path: bool or the error's message}``."""
    from agents.common.cli import parse_overrides

    path = tmp_path / "b.yaml"
    path.write_text(f"{key}: {text}\n")
    section = "solver" if key == "free_table" else "task"
    nested = tmp_path / "n.yaml"
    nested.write_text(f"{section}:\n  {key}: {text}\n")
    reads = {
        "file": lambda: load_config(path),
        "file, nested": lambda: load_config(nested),
        "--set": lambda: load_config(None, **parse_overrides([f"{key}={text}"])),
        "keyword": lambda: load_config(None, **{key: value}),
        "gym.make": lambda: gym.make("PneuNetGrasp-v1", **{key: value}).unwrapped.config,
    }
    out = {}
    for name, read in reads.items():
        try:
            out[name] = getattr(getattr(read(), section), key)
        except ValueError as exc:  # ConfigTypeError is one too
            out[name] = str(exc)
    return out


@pytest.mark.parametrize("key", ["observe_volume", "terminate_on_damage", "free_table"])
@pytest.mark.parametrize(("text", "value", "reads"), BOOLEANS)
def test_a_boolean_key_reads_the_same_from_a_file_set_and_a_keyword_argument(key, text, value, reads, tmp_path):
    """Before: ``yes``/``no``/``on``/``off`` in a file or ``--set`` were booleans (YAML 1.1), and the same value as a
    keyword argument (``observe_volume="yes"``) was refused: one value, two answers. Now one rule: ``true``/``false``
    (any of YAML's three capitalisations) or a Python ``bool``; anything else is refused on every path, naming the key
    and the value and saying what to write."""
    got = _read_bool(key, text, value, tmp_path)
    if reads is not None:
        assert got == dict.fromkeys(got, reads)
        return
    for path, message in got.items():
        assert isinstance(message, str), (path, message)
        assert key in message and "write true or false" in message, (path, message)
        assert repr(value) in message or text in message, (path, message)


def test_the_bool_message_names_the_value_and_its_kind():
    from pneunet_env.config import ConfigTypeError

    with pytest.raises(ConfigTypeError, match=r"'observe_volume' must be true or false, got 'yes' \(a string\): "
                                              "write true or false"):
        load_config(observe_volume="yes")
    with pytest.raises(ConfigTypeError, match=r"got 1 \(an integer\)"):
        load_config(observe_volume=1)


# ---------------------------------------------------------------------------------------------
# Unknown keys: the closest valid key (issue 32)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("typed", "meant"), [
    ("max_presure_kpa", "max_pressure_kpa"), ("observe_volum", "observe_volume"), ("Observe_Volume", "observe_volume"),
    ("task.max_pressure_kpa", "max_pressure_kpa"), ("usecase", "use_case"), ("free_tabel", "free_table"),
    ("render_widht", "render_width"), ("object_curvature_per_mm", "object_curvature_per_m"),
])
def test_an_unknown_key_names_the_closest_valid_key_in_a_file_set_and_keywords(typed, meant, tmp_path):
    """Before: every one of the 46 valid keys, and no "did you mean"."""
    from agents.common.cli import parse_overrides

    path = tmp_path / "c.yaml"
    path.write_text(f"{typed}: 1\n")
    for read in (lambda: load_config(path), lambda: load_config(None, **parse_overrides([f"{typed}=1"])),
                 lambda: load_config(None, **{typed: 1}), lambda: gym.make("PneuNetGrasp-v1", **{typed: 1})):
        with pytest.raises(ValueError) as info:
            read()
        message = str(info.value)
        assert f"unknown config key {typed!r}; did you mean {meant!r}" in message, message
        assert "valid keys" not in message and len(message) < 200  # the one key, not all 46


def test_an_unknown_key_nothing_is_close_to_lists_every_valid_key():
    with pytest.raises(ValueError, match="unknown config key 'zzz'; valid keys: actuator.") as info:
        load_config(zzz=1)
    assert "task.observe_volume" in str(info.value) and "did you mean" not in str(info.value)


def test_a_key_in_another_section_says_which():
    with pytest.raises(ValueError, match="unknown config key 'max_presure_kpa'; did you mean 'max_pressure_kpa' "
                                         r"\(section 'task'\)"):
        load_config({"task": {"max_presure_kpa": 1}})
