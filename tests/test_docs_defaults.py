"""The env docstrings table today's default task, and the tables equal ``EnvConfig()`` and the catalogue.

``PneuNetGraspEnv``'s docstring has a Default Task table (one row per config key) and a Catalogue table (one row per
class the default use case draws); ``pneunet_env.envs.rigid``'s has the jaw's defaults. Each row is parsed here and
compared with the value the code uses, so the docs cannot go stale silently.
"""

from __future__ import annotations

import dataclasses
import math
import re

import gymnasium as gym
import pytest

import pneunet_env
from pneunet_env.catalogue import load_catalogue, use_case_weights
from pneunet_env.config import EnvConfig
from pneunet_env.envs import rigid
from pneunet_env.envs.grasp import PneuNetGraspEnv

DEFAULT = EnvConfig()


def section(doc: str, title: str) -> str:
    """The text of ``## title`` up to the next ``## `` heading."""
    m = re.search(rf"^\s*## {re.escape(title)}\n(.*?)(?=^\s*## |\Z)", doc, re.S | re.M)
    assert m, f"no '## {title}' section"
    return m.group(1)


def table(text: str) -> list[list[str]]:
    """The rows of the first Markdown table in ``text`` (cells stripped; the header and the rule dropped)."""
    rows = [line.strip() for line in text.splitlines() if line.strip().startswith("|")]
    cells = [[c.strip() for c in row.strip("|").split("|")] for row in rows]
    assert len(cells) > 2 and set(cells[1][0]) <= {"-", ":"}, "no table"
    return cells[2:]


def value(cell: str):
    """A table cell as a value: ````x```` a string, ``true``/``false`` a bool, else a number."""
    if cell.startswith("``") and cell.endswith("``"):
        return cell.strip("`")
    if cell in ("true", "false"):
        return cell == "true"
    return float(cell)


def config_value(key: str):
    for name in ("objects", "task"):
        sec = getattr(DEFAULT, name)
        if key in {f.name for f in dataclasses.fields(sec)}:
            return getattr(sec, key)
    raise AssertionError(f"{key!r} is not a key of the objects or task section")


def span(cell: str) -> tuple[float, float]:
    lo, hi = cell.split("-")
    return float(lo), float(hi)


GRASP_DOC = PneuNetGraspEnv.__doc__


def test_default_task_table_equals_the_config():
    rows = table(section(GRASP_DOC, "Default Task"))
    documented = {}
    for key_cell, val_cell, *_ in rows:
        key = key_cell.strip("`")
        documented[key] = value(val_cell)
        want = config_value(key)
        if isinstance(want, bool) or isinstance(want, str):
            assert documented[key] == want, f"{key}: documented {val_cell}, EnvConfig() has {want!r}"
        else:
            assert documented[key] == pytest.approx(want), f"{key}: documented {val_cell}, EnvConfig() has {want!r}"
    must = {"use_case", "damage_rule", "max_pressure_kpa", "max_pressure_step_kpa", "squeeze_steps", "hold_steps",
            "reward_hold", "reward_success", "penalty_damage", "penalty_slip", "terminate_on_damage",
            "terminate_on_slip", "observe_volume"}
    assert must <= set(documented), f"the table lacks {sorted(must - set(documented))}"


def test_catalogue_table_equals_the_default_use_case():
    weights = use_case_weights(DEFAULT.objects.use_case)
    cat = load_catalogue()
    rows = table(section(GRASP_DOC, "Catalogue"))
    assert [r[0] for r in rows] == list(weights), "the table's classes are not the default use case's, in order"
    for name, weight, e, r, h, rho, eps, sigma in rows:
        c = cat[name]
        assert float(weight) == pytest.approx(weights[name], abs=0.005), name
        for cell, want, what in ((e, c.youngs_modulus_kpa, "E"), (r, c.radius_mm, "R"), (h, c.thickness_mm, "H"),
                                 (rho, c.density_kg_m3, "rho"), (eps, c.failure_strain, "eps_f"),
                                 (sigma, c.failure_stress_kpa, "sigma_f")):
            assert span(cell) == pytest.approx(want), f"{name} {what}: documented {cell}, catalogue has {want}"


def test_inline_numbers_equal_the_config():
    steps = DEFAULT.task.squeeze_steps + DEFAULT.task.hold_steps
    m = re.search(r"``squeeze_steps \+ hold_steps`` = (\d+) steps", GRASP_DOC)
    assert m and int(m.group(1)) == steps == gym.spec(pneunet_env.ENV_ID).max_episode_steps
    m = re.search(r"``hold_steps \* reward_hold \+ reward_success = ([\d.]+)``", GRASP_DOC)
    tc = DEFAULT.task
    assert m and float(m.group(1)) == pytest.approx(tc.hold_steps * tc.reward_hold + tc.reward_success)
    m = re.search(r"``p~ = ([\d.]+)``", GRASP_DOC)
    assert m and float(m.group(1)) == pytest.approx(DEFAULT.pressure_max)


def test_damage_rule_and_version_history_are_the_default_tasks():
    damage = GRASP_DOC[GRASP_DOC.index("**Damage**"):]
    assert f"``damage_rule: {DEFAULT.task.damage_rule}``" in damage.split("\n\n")[0]
    history = section(GRASP_DOC, "Version History")
    assert re.search(r"v0 \(0\.5\): the default objects changed", history), "the 0.5 change of default objects"
    assert "kitchen" in history and "hoop-strain" in history


def test_rigid_defaults_table_equals_the_env():
    env = gym.make(pneunet_env.RIGID_ENV_ID).unwrapped
    got = {"``jaw_travel_mm``": env.jaw_travel_mm, "``jaw_step_mm``": env.jaw_step_mm,
           "nominal radius (mm)": 1e3 / env.nominal_curvature_per_m, "``damage_rule``": env.config.task.damage_rule,
           "episode steps": env.config.episode_steps}
    rows = {r[0]: r[1] for r in table(section(rigid.__doc__, "Default Task"))}
    assert set(rows) == set(got)
    for key, cell in rows.items():
        doc = value(cell)
        if isinstance(doc, str):
            assert doc == got[key], key
        else:  # printed to its shown digits
            assert math.isclose(doc, got[key], rel_tol=1e-9), f"{key}: documented {cell}, the env has {got[key]!r}"
    assert gym.spec(pneunet_env.RIGID_ENV_ID).max_episode_steps == env.config.episode_steps


def test_the_parser_sees_a_stale_row():
    """The check itself: a row whose value differs from the config is caught."""
    stale = GRASP_DOC.replace("| ``max_pressure_kpa``      | 60 ", "| ``max_pressure_kpa``      | 40 ")
    assert stale != GRASP_DOC
    rows = {r[0].strip("`"): value(r[1]) for r in table(section(stale, "Default Task"))}
    assert rows["max_pressure_kpa"] != config_value("max_pressure_kpa")
