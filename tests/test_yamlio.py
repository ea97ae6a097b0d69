"""The one YAML/JSON reader (:mod:`pneunet_env.yamlio`) and every reader that uses it: env configs, the catalogue,
``--set`` values, saved ramps and model sidecars (train configs: ``tests/agents/test_train_config.py``).

Each case names what it refuses; the hypothesis properties feed arbitrary text and bytes to the readers (only
``ValueError``/``TypeError``, never a hang) and check that a number reads the same in a file and in ``--set``.
"""

from __future__ import annotations

import json
import math
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneunet_env.config import load_config
from pneunet_env.yamlio import (
    MAX_ALIASES,
    MAX_DEPTH,
    MAX_INPUT_BYTES,
    MAX_JSON_BYTES,
    dump_yaml,
    load_json,
    load_json_file,
    load_yaml,
    load_yaml_file,
    parse_value,
)

QUICK = settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
HANG_LIMIT_S = 20.0  # a hang guard, as in test_fuzz.py: no input may take this long to be read or refused


def _bomb(levels: int = 9, width: int = 9) -> str:
    """The "billion laughs": ``width ** levels`` strings from a few hundred bytes of YAML."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------
# Duplicate keys
# ---------------------------------------------------------------------------------------------


def test_duplicate_yaml_key_names_the_key_the_source_and_both_lines():
    with pytest.raises(ValueError, match=r"x\.yaml', line 3, column 1: duplicate key 'n' \(first at line 1\)"):
        load_yaml("n: 1\nm: 2\nn: 3\n", "file 'x.yaml'")
    with pytest.raises(ValueError, match="duplicate key 'b'"):  # nested, and in flow style
        load_yaml("a: {b: 1, b: 2}\n")
    with pytest.raises(ValueError, match="duplicate key 1.0"):  # equal as values: 1 and 1.0 would collapse
        load_yaml("1: a\n1.0: b\n")
    with pytest.raises(ValueError, match="duplicate key 'a'"):  # a quoted and a plain key
        load_yaml("a: 1\n'a': 2\n")
    # a merge key is no duplicate: the mapping's own keys override the merged ones, as YAML says
    assert load_yaml("base: &b {x: 1, y: 2}\nc:\n  <<: *b\n  y: 3\n")["c"] == {"x": 1, "y": 3}


def test_duplicate_key_in_an_env_config_file_names_the_file_and_line(tmp_path):
    path = tmp_path / "env.yaml"
    path.write_text("task:\n  hold_steps: 10\n  hold_steps: 20\n")
    with pytest.raises(ValueError, match=r"env\.yaml', line 3.*duplicate key 'hold_steps'"):
        load_config(path)


def test_duplicate_json_key_names_the_key_the_source_and_the_line():
    with pytest.raises(ValueError, match=r"r\.json': duplicate key 'target' in the object that starts at line 2"):
        load_json('{"a": 1,\n "b": {"target": 0.4,\n       "target": 0.9}}', "ramp file 'r.json'")
    assert load_json('{"a": {"b": 1}, "c": {"b": 2}}') == {"a": {"b": 1}, "c": {"b": 2}}  # the same key, two objects


def test_a_ramp_file_with_a_duplicate_key_is_refused(tmp_path):
    """Before: ``json.loads`` kept the second ``target``, silently."""
    from agents.policies.scripted import load_ramp

    path = tmp_path / "ramp.json"
    path.write_text('{"kind": "linear_ramp", "target": 0.4, "n_steps": 10, "target": 0.9}')
    with pytest.raises(ValueError, match=r"ramp\.json'.*duplicate key 'target'"):
        load_ramp(path)


def test_a_statistics_sidecar_with_a_duplicate_key_is_refused(tmp_path):
    from agents.policies.sb3 import NormalizationStats

    path = tmp_path / "s_vecnormalize.json"
    path.write_text('{"format": "pneunet_env/vecnormalize-stats/1", "format": "other"}')
    with pytest.raises(ValueError, match="duplicate key 'format'"):
        NormalizationStats.load(path)


# ---------------------------------------------------------------------------------------------
# Numbers: the same in a file and in --set
# ---------------------------------------------------------------------------------------------

NUMBERS = [
    ("5e1", 50.0), ("3e-4", 3e-4), ("1E3", 1000.0), ("1.0e+3", 1000.0), ("-2.5e-3", -2.5e-3), (".5", 0.5),
    ("1.", 1.0), ("1_000.5", 1000.5), ("+7.25", 7.25), ("12", 12), ("-3", -3), ("1_000", 1000), ("0x1F", 31),
    ("0o17", 15), ("0b101", 5), ("0", 0), (".inf", math.inf), ("-.inf", -math.inf), ("1e999", math.inf),
]


@pytest.mark.parametrize("text, value", NUMBERS)
def test_number_forms_read_as_numbers_in_a_file_and_in_set(text, value, tmp_path):
    from agents.common.cli import parse_overrides

    path = tmp_path / "n.yaml"
    path.write_text(f"k: {text}\nl: [{text}]\n")
    in_file = load_yaml_file(path)
    in_set = parse_overrides([f"k={text}"])["k"]
    assert in_file == {"k": value, "l": [value]} and in_set == value
    assert type(in_file["k"]) is type(in_set) is type(value)


def test_nan_reads_as_a_float_and_quoted_numbers_stay_strings():
    assert math.isnan(parse_value(".nan"))
    assert parse_value("'5e1'") == "5e1" and parse_value('"0x10"') == "0x10"
    assert parse_value("2024-01-31") == "2024-01-31"  # no dates: plain data only
    assert parse_value("lin_3e-4") == "lin_3e-4" and parse_value("0x") == "0x"


@pytest.mark.parametrize("text", ["017", "-010", "08", "1:30", "190:20:30", "1:30.5"])
def test_numbers_read_differently_by_yaml_1_1_and_1_2_are_refused_by_name(text):
    with pytest.raises(ValueError, match=f"the number '{text}' is ambiguous"):
        parse_value(text, f"--set 'k={text}'")
    assert parse_value(f"'{text}'") == text  # quoted: a string


def test_set_5e1_is_a_number_for_the_env_config():
    """Before: ``--set object_density_kg_m3=5e1`` gave the string '5e1', which the config refused."""
    from agents.common.cli import parse_overrides

    over = parse_overrides(["object_density_kg_m3=5e1", "max_pressure_kpa=4.5e1", "use_case=null"])
    cfg = load_config(**over)
    assert cfg.objects.object_density_kg_m3 == (50.0, 50.0) and cfg.task.max_pressure_kpa == 45.0


def test_booleans_are_true_and_false_and_null_reads_as_yaml_reads_it():
    assert [parse_value(t) for t in ("true", "True", "TRUE", "false", "False", "FALSE")] == [True] * 3 + [False] * 3
    assert [parse_value(t) for t in ("null", "~", "", "Null")] == [None] * 4
    assert [parse_value(t) for t in ("'yes'", '"on"', "y", "n")] == ["yes", "on", "y", "n"]  # quoted, or not 1.1's


@pytest.mark.parametrize("text", ["yes", "Yes", "YES", "no", "No", "NO", "on", "On", "ON", "off", "Off", "OFF"])
def test_yaml_1_1_booleans_are_refused_as_ambiguous(text):
    """Before: read as booleans (YAML 1.1, as PyYAML reads them) in a file and ``--set``, while a keyword argument
    refused "yes": one value, two answers. They are strings in YAML 1.2: refused, like ``017`` and ``1:30``."""
    meant = "true" if text.lower() in ("yes", "on") else "false"
    with pytest.raises(ValueError, match=rf"--set 'k={text}'.*'{text}' is {meant} in YAML 1.1 .* write true or false"):
        parse_value(text, f"--set 'k={text}'")
    with pytest.raises(ValueError, match=rf"c.yaml', line 2, column 6: key 'k': '{text}' is {meant}"):
        load_yaml(f"a:\n  k: {text}\n", "config file 'c.yaml'")
    with pytest.raises(ValueError, match=rf"line 1, column 5: '{text}' is {meant}"):  # in a list: its line
        load_yaml(f"[1, {text}]")
    assert load_yaml(dump_yaml({"k": text})) == {"k": text}  # written quoted: read back as the string


# ---------------------------------------------------------------------------------------------
# Aliases, depth, size: refused before they expand
# ---------------------------------------------------------------------------------------------


def test_alias_bomb_is_refused_before_it_expands():
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"bomb\.yaml', line \d+, column \d+: its aliases expand it past"):
        load_yaml(_bomb(), "file 'bomb.yaml'")
    assert time.perf_counter() - t0 < HANG_LIMIT_S


def test_alias_bomb_in_set_is_refused_naming_the_option():
    """Before: ``--set`` returned the bomb, and the config's checks ran past 60 s expanding it."""
    from agents.common.cli import parse_overrides

    value = "{" + ", ".join(line for line in _bomb().strip().split("\n")) + "}"
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"--set 'object_density_kg_m3=.*aliases expand it past"):
        parse_overrides([f"object_density_kg_m3={value}"])
    assert time.perf_counter() - t0 < HANG_LIMIT_S


def test_alias_bomb_in_an_env_config_file_is_refused(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text("objects:\n  class_weights: null\n" + _bomb())
    with pytest.raises(ValueError, match=r"bomb\.yaml'.*aliases expand it past"):
        load_config(path)


def test_a_few_aliases_are_fine_and_too_many_or_recursive_ones_are_refused():
    assert load_yaml("a: &x [1, 2]\nb: *x\nc: *x\n") == {"a": [1, 2], "b": [1, 2], "c": [1, 2]}
    many = "a: &x 1\nb: [" + ", ".join(["*x"] * (MAX_ALIASES + 1)) + "]\n"
    with pytest.raises(ValueError, match=f"more than {MAX_ALIASES} aliases"):
        load_yaml(many)
    with pytest.raises(ValueError, match="recursive alias"):
        load_yaml("a: &x [1, *x]\n")
    with pytest.raises(ValueError, match="recursive alias"):
        load_yaml("a: &x {b: *x}\n")
    with pytest.raises(ValueError, match="line 1.*undefined alias"):
        load_yaml("a: *nothing\n", "s")
    long = "a: &x " + "y" * 100_000 + "\nb: [" + ", ".join(["*x"] * 100) + "]\n"  # 10 MB if expanded
    with pytest.raises(ValueError, match="aliases expand it past"):
        load_yaml(long)


def test_depth_and_size_are_bounded():
    assert load_yaml("[" * MAX_DEPTH + "]" * MAX_DEPTH) is not None
    with pytest.raises(ValueError, match=f"nested deeper than {MAX_DEPTH}"):
        load_yaml("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1))
    with pytest.raises(ValueError, match="nested deeper"):
        load_yaml("[" * 100_000)  # no RecursionError from PyYAML's recursive composer
    with pytest.raises(ValueError, match=f"larger than the {MAX_INPUT_BYTES:,} bytes"):
        load_yaml("a: 1\n" + "#" * MAX_INPUT_BYTES)
    with pytest.raises(ValueError, match="nested too deeply"):
        load_json("[" * 100_000 + "]" * 100_000, "deep.json")
    with pytest.raises(ValueError, match=f"larger than the {MAX_JSON_BYTES:,} bytes"):
        load_json(" " * (MAX_JSON_BYTES + 1))


def test_a_big_file_is_refused_without_reading_it_all(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_bytes(b"a: 1\n" + b"#" * (4 * MAX_INPUT_BYTES))
    with pytest.raises(ValueError, match=r"big\.yaml': larger than"):
        load_yaml_file(path, "config file")
    with pytest.raises(ValueError, match=r"cannot read config file '.*missing\.yaml'"):
        load_yaml_file(tmp_path / "missing.yaml", "config file")
    with pytest.raises(ValueError, match=r"cannot read JSON file '.*missing\.json'"):
        load_json_file(tmp_path / "missing.json")


# ---------------------------------------------------------------------------------------------
# Plain data only; every error a named ValueError
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, tag", [
    ("!!python/object/apply:os.system ['true']", "python/object/apply:os.system"),
    ("!!python/name:os.system ''", "python/name:os.system"),
    ("!!binary aGVsbG8=", "binary"),
    ("!!set {a: null}", "set"),
    ("!!timestamp 2024-01-31", "timestamp"),
    ("!!omap [a: 1]", "omap"),
    ("!custom 1", "!custom"),
])
def test_tags_other_than_plain_data_are_refused_by_name(text, tag):
    with pytest.raises(ValueError, match=f"--set 'k=.*the tag '.*{tag}.*' is not read"):
        parse_value(text, f"--set 'k={text}'")


def test_explicit_plain_tags_still_read():
    assert parse_value("!!float 3e6") == 3e6 and parse_value("!!int '0x10'") == 16 and parse_value("!!str 12") == "12"
    with pytest.raises(ValueError, match="cannot read 'maybe' as true or false"):
        parse_value("!!bool maybe")
    with pytest.raises(ValueError, match="as an integer"):
        parse_value("!!int 1.5")
    with pytest.raises(ValueError, match="as an integer"):
        parse_value("!!int " + "9" * 5000)  # past Python's digit limit: named, not a raw ValueError


@pytest.mark.parametrize("value, match", [
    ("[", r"cannot read --set 'x=\[': not valid YAML \(line 1, column 2\)"),
    ("{a: 1", "not valid YAML"),
    ("a: b: c", "not valid YAML"),
    ("'open", "not valid YAML"),
    ("\x00", "not valid YAML"),
    ("a\n---\nb", "single document"),
    ("? [1]\n: 2", "unhashable key"),
])
def test_syntax_errors_name_the_source_and_the_position(value, match):
    with pytest.raises(ValueError, match=match):
        parse_value(value, f"--set 'x={value}'")


def test_bytes_are_decoded_and_bad_bytes_named():
    assert load_yaml("k: é\n".encode()) == {"k": "é"}
    assert load_yaml("k: 1\n".encode("utf-16")) == {"k": 1}
    with pytest.raises(ValueError, match="b.yaml.*not valid YAML"):
        load_yaml(b"k: \xff\xfe\xfa\n", "b.yaml")
    with pytest.raises(ValueError, match="b.json.*not JSON"):
        load_json(b'{"k": "\xff"}', "b.json")
    with pytest.raises(TypeError, match="expected text"):
        load_yaml(3)  # type: ignore[arg-type]


def test_dump_yaml_quotes_what_would_read_as_something_else():
    data = {"s": ["5e1", "3e-4", "017", "1:30", "yes", "null", "0x1F", "text"], "f": [3e-4, 1e300, -0.0, 1.5],
            "i": [0, -7, 10**20], "b": [True, False], "n": None, "nested": {"k": ["v"]}}
    assert load_yaml(dump_yaml(data)) == data


# ---------------------------------------------------------------------------------------------
# Hypothesis: arbitrary input, and numbers
# ---------------------------------------------------------------------------------------------

# text near YAML's grammar: its punctuation, anchors and aliases, tags, numbers, words, newlines and indents
YAMLISH = st.lists(st.sampled_from([
    "a", "b", "k", ":", ": ", "-", "- ", ",", "[", "]", "{", "}", "&x ", "*x", "&y ", "*y", "!!int ", "!!str ",
    "!!python/object:os.system ", "<<", "? ", "'", '"', "#", "|", ">", "\n", "\n  ", "\n    ", " ", "\t", "1", "0",
    "5e1", "0x1F", "017", "1:30", ".inf", "~", "null", "yes", "---", "...", "%YAML 1.1\n", "\\", "\x00", "é",
]), max_size=40).map("".join)


def _reads_or_refuses(read, data) -> None:
    t0 = time.perf_counter()
    try:
        read(data)
    except (ValueError, TypeError):
        pass
    assert time.perf_counter() - t0 < HANG_LIMIT_S


@QUICK
@given(text=st.one_of(st.text(max_size=200), YAMLISH))
def test_any_text_reads_or_raises_value_error(text):
    _reads_or_refuses(load_yaml, text)
    _reads_or_refuses(lambda t: parse_value(t, "--set"), text)
    _reads_or_refuses(load_json, text)


@QUICK
@given(data=st.binary(max_size=200))
def test_any_bytes_read_or_raise_value_error(data):
    _reads_or_refuses(load_yaml, data)
    _reads_or_refuses(load_json, data)


@QUICK
@given(text=st.one_of(st.text(max_size=60), YAMLISH))
def test_any_set_value_reads_or_raises_value_error_naming_it(text):
    from agents.common.cli import parse_overrides

    try:
        parse_overrides([f"hold_steps={text}"])
    except (ValueError, TypeError) as exc:
        assert str(exc).startswith(("--set", "cannot read --set")) and "hold_steps=" in str(exc), exc


@QUICK
@given(value=st.one_of(st.floats(allow_nan=False, width=64), st.integers(min_value=-(10**30), max_value=10**30)))
def test_a_number_reads_the_same_in_a_file_and_in_set(value, tmp_path_factory):
    texts = [repr(value)]
    if isinstance(value, float) and math.isfinite(value):
        texts += [f"{value:e}", f"{value:.17E}", f"{value:.3e}".replace("e+0", "e").replace("e-0", "e-")]
    elif isinstance(value, int):
        sign = "-" if value < 0 else ""
        texts += [f"{sign}{abs(value):#x}", f"{sign}{abs(value):#o}", f"{sign}{abs(value):#b}", f"{value:_}"]
    path = tmp_path_factory.mktemp("n") / "n.yaml"
    for text in texts:
        expected = float(text.replace("_", "")) if isinstance(value, float) else value
        if not math.isfinite(value):  # repr(inf) is 'inf', not YAML's '.inf': a string, the same in both
            expected = text
        path.write_text(f"k: {text}\n")
        assert load_yaml_file(path)["k"] == parse_value(text) == expected, text
        assert load_yaml(dump_yaml({"k": value}))["k"] == value


@QUICK
@given(value=st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=False), st.text(max_size=10)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=5), inner, max_size=4)),
    max_leaves=20))
def test_plain_data_round_trips_through_dump_yaml_and_json(value):
    assert load_yaml(dump_yaml({"v": value})) == {"v": value}
    assert load_json(json.dumps({"v": value})) == {"v": value}


YAML_VALUES = st.one_of(YAMLISH.filter(lambda t: "\n" not in t), st.sampled_from([
    "5e1", "3e-4", "[1, 2]", "[2, 1]", "{a: 1}", "yes", "'no'", "null", ".nan", "-.inf", "1e999", "0x10", "017",
    "&a [1, *a]", "!!binary aGk=", "[[[[1]]]]", "{apple: 1e308, kiwifruit: 1e308}", "kitchen", "''",
]))


@QUICK
@given(lines=st.lists(st.tuples(st.sampled_from(["hold_steps", "observe_volume", "class_weights", "use_case",
                                                 "object_density_kg_m3", "task", "objects", "render_width",
                                                 "max_pressure_kpa", "nonsense", "1"]), YAML_VALUES), max_size=4))
def test_any_env_config_file_loads_or_raises_value_or_type_error(lines, tmp_path_factory):
    path = tmp_path_factory.mktemp("c") / "c.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in lines))
    _reads_or_refuses(load_config, path)


@QUICK
@given(lines=st.lists(st.tuples(st.sampled_from(["n_envs", "n_timesteps", "seed", "learning_rate", "normalize",
                                                 "policy_kwargs", "callback", "env_wrapper", "env_kwargs", "policy",
                                                 "frame_stack", "max_train_minutes", "use_sde"]), YAML_VALUES),
                      max_size=4))
def test_any_train_config_file_loads_or_raises_value_or_type_error(lines, tmp_path_factory):
    from agents.training.config import load_train_config

    path = tmp_path_factory.mktemp("t") / "ppo.yaml"
    path.write_text("PneuNetGrasp-v1:\n" + "".join(f"  {k}: {v}\n" for k, v in lines))
    _reads_or_refuses(load_train_config, path)
