"""A designer's own objects: ``--catalogue PATH`` / ``objects.catalogue``, a user catalogue in the packaged file's
format whose classes may lack sources (then reported "unsourced"); the design study honours a config's own objects."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import yaml

import pneunet_env  # noqa: F401  (registers the ids)
from pneunet_env import load_config
from pneunet_env.catalogue import load_catalogue
from pneunet_env.config import ConfigTypeError
from pneunet_env.data import __file__ as DATA_INIT


def _packaged() -> dict:
    from pathlib import Path

    return yaml.safe_load((Path(DATA_INIT).parent / "objects.yaml").read_text())


@pytest.fixture
def fruit(tmp_path):
    """Apples and kiwis copied from the packaged catalogue, and one class without sources."""
    d = _packaged()["classes"]
    bare = {k: v for k, v in d["kiwifruit"].items() if k != "sources"}
    path = tmp_path / "fruit.yaml"
    path.write_text(yaml.safe_dump({"schema_version": 1, "classes": {"apple": d["apple"], "my_kiwi": bare},
                                    "use_cases": {"default": "bowl", "bowl": {"weights": {"apple": 1, "my_kiwi": 3}},
                                                  "apples": {"weights": {"apple": 1}}}}))
    return path


def test_a_user_catalogue_may_lack_sources_and_the_packaged_one_may_not(fruit):
    classes = load_catalogue(fruit)
    assert classes["my_kiwi"].sources == () and classes["apple"].sources
    from pneunet_env.catalogue import _classes

    with pytest.raises(ValueError, match="field 'sources' is missing"):
        _classes(yaml.safe_load(fruit.read_text()), "packaged")  # the packaged file's rule


def test_the_env_draws_only_the_catalogues_classes(fruit):
    cfg = load_config(catalogue=str(fruit), use_case="bowl")
    assert cfg.objects.table.names == ("apple", "my_kiwi")
    env = gym.make("PneuNetGrasp-v1", config=cfg)
    drawn = {env.reset(seed=s)[1]["object_class"] for s in range(40)}
    assert drawn == {"apple", "my_kiwi"}
    one = load_config(catalogue=str(fruit), use_case="apples")
    assert {gym.make("PneuNetGrasp-v1", config=one).reset(seed=s)[1]["object_class"] for s in range(5)} == {"apple"}
    # the vector env draws the same objects as the single env from a user catalogue too
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

    vec = PneuNetGraspVectorEnv(3, config=cfg, backend="numpy")
    _, info = vec.reset(seed=7)
    assert set(np.asarray(info["object_class"]).tolist()) <= {0, 1}


@pytest.mark.parametrize("value, match", [
    ("/no/such/catalogue.yaml", "cannot read catalogue file '/no/such/catalogue.yaml'"),
    (5, "config key 'catalogue' must be a string or null, got 5"),
    ("", "config key 'catalogue' must be a path"),
])
def test_a_bad_catalogue_is_named(value, match):
    with pytest.raises((ValueError, ConfigTypeError), match=match):
        load_config(catalogue=value)


def test_a_file_that_is_not_a_catalogue_or_lacks_the_use_case_is_named(tmp_path, fruit):
    bad = tmp_path / "bad.yaml"
    bad.write_text("classes: 5\n")
    with pytest.raises(ValueError, match="bad.yaml: 'classes' must be a non-empty mapping"):
        load_config(catalogue=str(bad), use_case="x")
    with pytest.raises(ValueError, match=r"'use_case' must be one of \['apples', 'bowl'\] of the catalogue"):
        load_config(catalogue=str(fruit), use_case="kitchen")


def test_the_demo_says_unsourced_and_tunes_for_the_catalogue(fruit, cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, out, err = cli(["demo", "--catalogue", str(fruit), "--objects", "4", "--no-progress"])
    assert rc == 0
    assert "the catalogue fruit.yaml's 'bowl' use case (apple 25%, my kiwi 75%; UNSOURCED: my_kiwi" in out
    assert f"pneunet-grasp search --catalogue {fruit} --out best_ramp.json" in err  # tuned for these objects


def test_the_kitchens_schedule_does_not_fit_the_same_names_in_another_file(fruit):
    from agents.policies.registry import BEST_RAMP_PATH, schedule_origin

    d = _packaged()
    kitchen = {"schema_version": 1, "classes": d["classes"], "use_cases": d["use_cases"]}
    other = fruit.with_name("copy.yaml")
    other.write_text(yaml.safe_dump(kitchen))
    assert schedule_origin(BEST_RAMP_PATH, load_config())[1] is True
    assert schedule_origin(BEST_RAMP_PATH, load_config(catalogue=str(other), use_case="kitchen"))[1] is False


@pytest.mark.slow
def test_the_design_study_honours_a_configs_own_objects_and_a_catalogue(tmp_path, fruit):
    from agents.design import main

    ranges = tmp_path / "ranges.yaml"
    ranges.write_text("objects:\n  use_case: null\n  object_shear_modulus_kpa: [5, 500]\n"
                      "  object_curvature_per_m: [40, 60]\n  object_thickness_mm: [3, 5]\n")
    small = ["--trials", "1", "--objects", "4", "--held-out", "4", "--top", "1", "--quiet"]
    assert main(["--config", str(ranges), "--out", str(tmp_path / "r"), *small]) == 0
    res = json.loads((tmp_path / "r" / "design.json").read_text())
    assert res["study"] == "design-ranges" and res["settings"]["use_case"] is None  # not the kitchen
    assert main(["--catalogue", str(fruit), "--out", str(tmp_path / "c"), *small]) == 0
    res = json.loads((tmp_path / "c" / "design.json").read_text())
    assert res["study"] == "design-bowl" and res["settings"]["catalogue"] == str(fruit)
