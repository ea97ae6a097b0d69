"""No silent fallback for a tuned schedule (issue 37, item 4): a config's own ramp that is missing or unreadable is
named, a ramp file whose two targets disagree is refused, and a schedule is defined in kPa (mm for the jaw), so a new
``max_pressure_kpa`` never moves it; the shipped schedules give the kPa they gave before."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from agents.policies.registry import (
    BEST_RAMP_PAPER_PATH,
    BEST_RAMP_PATH,
    BEST_RIGID_PAPER_PATH,
    BEST_RIGID_PATH,
    make_policy,
)
from agents.policies.scripted import LinearRamp, StepPolicy, load_ramp, save_ramp
from pneunet_env import PAPER_TASK
from pneunet_env.cli import main
from pneunet_env.config import load_config
from pneunet_env.envs.rigid import default_jaw_travel_mm

ROOT = Path(__file__).resolve().parents[2]
ENV_CONFIGS = ROOT / "configs" / "env"
DESIGNED = sorted(ENV_CONFIGS.glob("designed-*.yaml"))


def _kpa(entry, config) -> float:
    return entry.policy.target * config.task.max_pressure_kpa


def _copy_without_ramp(tmp_path: Path, name: str = "designed-kitchen") -> Path:
    """A designed config copied alone (its ``.best_ramp.json`` left behind)."""
    copy = tmp_path / f"{name}.yaml"
    shutil.copyfile(ENV_CONFIGS / f"{name}.yaml", copy)
    return copy


# --------------------------------------------------------------------------------------- the shipped schedules, kept
@pytest.mark.parametrize("config_path", [None, ENV_CONFIGS / "default.yaml", *DESIGNED],
                         ids=lambda p: "none" if p is None else p.stem)
@pytest.mark.parametrize("task", ["default", "paper"])
def test_shipped_schedules_give_the_same_kpa_and_mm_as_before(config_path, task):
    """Each config's best-ramp and rigid are the schedules their files hold, bit for bit: the fraction the file
    writes (which ``target_kpa / max_pressure_kpa`` gives back exactly), and the jaw's ``target_mm`` over the travel."""
    cfg = load_config(config_path, **(PAPER_TASK if task == "paper" else {}))
    ramp = make_policy("best-ramp", cfg, config_path=config_path)
    if config_path is not None and config_path.stem.startswith("designed-"):
        ramp_file = config_path.with_name(f"{config_path.stem}.best_ramp.json")
    else:
        ramp_file = BEST_RAMP_PAPER_PATH if task == "paper" else BEST_RAMP_PATH
    data = json.loads(ramp_file.read_text())
    assert ramp.policy.target == data["target"] and ramp.policy.n_steps == data["n_steps"] == (
        50 if ramp_file == BEST_RAMP_PAPER_PATH else 20)
    assert _kpa(ramp, cfg) == pytest.approx(data["target_kpa"], rel=1e-12)
    rigid = make_policy("rigid", cfg, config_path=config_path)
    rdata = json.loads((BEST_RIGID_PAPER_PATH if task == "paper" else BEST_RIGID_PATH).read_text())
    if default_jaw_travel_mm(cfg) == rdata["jaw_travel_mm"]:
        assert rigid.policy.target == rdata["target"]  # the file's own fraction, bit for bit, where the scales agree
    assert rigid.policy.target * default_jaw_travel_mm(cfg) == pytest.approx(rdata["target_mm"], rel=1e-12)


def test_shipped_schedules_in_kpa():
    """The table of what the demo runs, in kPa (mm): unchanged by issue 37."""
    got = {}
    for path in [None, *DESIGNED]:
        cfg = load_config(path)
        got[path.stem if path else "default"] = round(_kpa(make_policy("best-ramp", cfg, config_path=path), cfg), 6)
    paper = load_config(None, **PAPER_TASK)
    got["paper"] = round(_kpa(make_policy("best-ramp", paper), paper), 6)
    assert got == {"default": 35.1, "paper": 42.0, "designed-catalogue_uniform": 44.936, "designed-kitchen": 39.456,
                   "designed-lab_bench": 42.744}


# ------------------------------------------------------------------------------------ (c) a schedule is defined in kPa
def test_a_new_maximum_never_moves_a_tuned_schedule():
    """Before: ``--set max_pressure_kpa=40`` turned the tuned 33.9 kPa into 22.6 kPa (the fraction re-applied), while
    the rigid jaw kept its millimetres."""
    cfg = load_config(None, max_pressure_kpa=40.0)
    ramp = make_policy("best-ramp", cfg)
    assert _kpa(ramp, cfg) == pytest.approx(35.1, rel=1e-12) and "35.1 kPa over 20 steps" in ramp.label
    assert make_policy("rigid", cfg).policy.target * default_jaw_travel_mm(cfg) == pytest.approx(7.832)
    designed = ENV_CONFIGS / "designed-kitchen.yaml"
    cfg = load_config(designed, max_pressure_kpa=150.0)
    assert _kpa(make_policy("best-ramp", cfg, config_path=designed), cfg) == pytest.approx(39.456, rel=1e-9)


def test_a_schedule_above_the_new_maximum_is_refused_not_clipped():
    with pytest.raises(ValueError, match=r"best_ramp\.json'.*35\.1 kPa, is above max_pressure_kpa = 30 kPa"):
        make_policy("best-ramp", load_config(None, max_pressure_kpa=30.0))


def test_a_jaw_schedule_beyond_the_travel_is_refused_not_clipped(tmp_path):
    path = tmp_path / "jaw.json"
    path.write_text(json.dumps({"kind": "linear_ramp", "target": 0.5, "n_steps": 5, "target_mm": 30.0,
                                "jaw_travel_mm": 60.0}))
    with pytest.raises(ValueError, match=r"30 mm, is above the jaw travel = 17\.6 mm"):
        make_policy(f"rigid:path={path}", load_config())


def test_the_demo_runs_the_tuned_kpa_under_another_maximum(capsys):
    rc = main(["demo", "--set", "max_pressure_kpa=40", "--policy", "best-ramp", "--objects", "1"])
    assert rc == 0
    assert "best-ramp (35.1 kPa over 20 steps)" in capsys.readouterr().out


def test_a_fraction_only_ramp_is_a_fraction_of_the_running_maximum(tmp_path):
    """:func:`save_ramp`'s form (no kPa, no maximum recorded) is a schedule relative to the config, as written."""
    path = save_ramp(LinearRamp(0.5, 10), tmp_path / "r.json")
    assert load_ramp(path, load_config(None, max_pressure_kpa=40.0)).target == 0.5
    # with the maximum it was written for, it is that many kPa
    data = {**json.loads(path.read_text()), "max_pressure_kpa": 60.0}
    path.write_text(json.dumps(data))
    assert load_ramp(path, load_config(None, max_pressure_kpa=40.0)).target == pytest.approx(0.75)


def test_a_ramp_given_in_kpa_alone_is_read_in_kpa(tmp_path):
    """Before: ``target_kpa`` without ``target`` was refused (``lacks the key 'target'``)."""
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"kind": "step", "target_kpa": 30.0}))
    pol = load_ramp(path, load_config(None, max_pressure_kpa=40.0))
    assert isinstance(pol, StepPolicy) and pol.target == 0.75


def test_search_writes_the_maximum_its_fraction_is_of(tmp_path):
    import numpy as np

    from agents.search.ramp import Candidate, save_best

    cfg = load_config(None, max_pressure_kpa=50.0)
    best = Candidate(0.5, 10, 1.0, 0.0, 0.0, 1.0, np.ones(2, bool), np.ones(2), np.ones(2))
    path = save_best(best, tmp_path / "best.json", cfg, "pneunet", 2, 0, {}, 0.0)
    data = json.loads(path.read_text())
    assert (data["target"], data["target_kpa"], data["max_pressure_kpa"]) == (0.5, 25.0, 50.0)
    assert load_ramp(path, load_config(None, max_pressure_kpa=25.0)).target == 1.0  # 25 kPa, at another maximum


# ------------------------------------------------------------------------------------ (b) two targets that disagree
def test_a_ramp_file_whose_two_targets_disagree_is_refused_naming_both(tmp_path):
    """Before: editing ``target_kpa`` was ignored, because ``target`` (a fraction) won."""
    data = json.loads(BEST_RAMP_PATH.read_text())
    data["target_kpa"] = 30.0  # edited; target still says 0.585 of 60 kPa
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"edited\.json'.*disagree: target_kpa = 30 kPa, but target = 0\.585 of "
                                         r"max_pressure_kpa = 60 is 35\.1 kPa"):
        make_policy(f"best-ramp:path={path}")
    data["target"] = 0.5  # both edited, and agreeing: 30 kPa
    path.write_text(json.dumps(data))
    assert _kpa(make_policy(f"best-ramp:path={path}"), load_config()) == pytest.approx(30.0)


def test_a_jaw_file_whose_two_targets_disagree_is_refused(tmp_path):
    data = {**json.loads(BEST_RIGID_PATH.read_text()), "target_mm": 5.0}
    path = tmp_path / "jaw.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"target_mm = 5 mm, but target = 0\.445 of jaw_travel_mm = 17\.6"):
        make_policy(f"rigid:path={path}")


@pytest.mark.parametrize("key, value", [("target_kpa", "30"), ("target_kpa", -1.0), ("max_pressure_kpa", 0.0),
                                        ("max_pressure_kpa", True), ("target_kpa", None)])
def test_a_ramp_files_physical_numbers_are_checked_by_name(tmp_path, key, value):
    data = {**json.loads(BEST_RAMP_PATH.read_text()), key: value}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=rf"bad\.json'.*{key} must be a finite number"):
        load_ramp(path)


# ----------------------------------------------------------------------- (a) a config's own ramp, missing or unreadable
def test_a_designed_config_without_its_ramp_is_refused_not_run_with_another_actuators(tmp_path):
    """Before: ``best-ramp (5.15 kPa over 20 steps)``: Table 1's fraction of the designed maximum, not the design's
    2.58 kPa."""
    copy = _copy_without_ramp(tmp_path)
    with pytest.raises(ValueError) as info:
        make_policy("best-ramp", load_config(copy), config_path=copy)
    msg = str(info.value)
    assert str(tmp_path / "designed-kitchen.best_ramp.json") in msg and "is missing" in msg
    assert "another actuator" in msg and "agents/best_ramp.json (35.1 kPa over 20 steps)" in msg
    assert "pneunet-grasp search --config" in msg and "best-ramp:path=" in msg
    # with its ramp beside it again, it runs the design's
    shutil.copyfile(ENV_CONFIGS / "designed-kitchen.best_ramp.json", tmp_path / "designed-kitchen.best_ramp.json")
    cfg = load_config(copy)
    assert _kpa(make_policy("best-ramp", cfg, config_path=copy), cfg) == pytest.approx(39.456)
    # the jaw's schedule does not depend on the pneu-net: the package's, as before
    (tmp_path / "designed-kitchen.best_ramp.json").unlink()
    assert "7.83 mm" in make_policy("rigid", cfg, config_path=copy).label
    # the package's schedule named explicitly runs, in its kPa (and the kPa rule still applies: 35.1 kPa > 30 kPa)
    assert _kpa(make_policy(f"best-ramp:path={BEST_RAMP_PATH}", cfg, config_path=copy), cfg) == pytest.approx(35.1)
    low = load_config(copy, max_pressure_kpa=30.0)
    with pytest.raises(ValueError, match="above max_pressure_kpa = 30"):
        make_policy(f"best-ramp:path={BEST_RAMP_PATH}", low, config_path=copy)


def test_the_demo_names_the_missing_ramp_in_one_line(tmp_path, capsys):
    copy = _copy_without_ramp(tmp_path, "designed-lab_bench")
    try:
        rc = main(["demo", "--config", str(copy), "--objects", "1"])
    except SystemExit as exc:
        rc = exc.code
    err = capsys.readouterr().err
    assert rc not in (0, None) and "designed-lab_bench.best_ramp.json" in err and "Traceback" not in err


def test_a_config_of_table1s_actuator_without_a_ramp_runs_the_packages(tmp_path):
    copy = tmp_path / "mine.yaml"
    shutil.copyfile(ENV_CONFIGS / "default.yaml", copy)
    cfg = load_config(copy)
    assert _kpa(make_policy("best-ramp", cfg, config_path=copy), cfg) == pytest.approx(35.1)


def _unreadable(tmp_path: Path, kind: str, name: str) -> Path:
    side = tmp_path / name
    if kind == "folder":
        side.mkdir()
    elif kind == "device":
        os.symlink("/dev/zero", side)
    elif kind == "dangling":
        os.symlink(tmp_path / "nowhere.json", side)
    return side


@pytest.mark.parametrize("kind, what", [("folder", "a folder"), ("device", "not a regular file"),
                                        ("dangling", "a link to nothing")])
@pytest.mark.parametrize("policy, suffix", [("best-ramp", "best_ramp"), ("rigid", "best_rigid")])
def test_a_config_ramp_that_cannot_be_read_is_named_never_skipped(tmp_path, kind, what, policy, suffix):
    """Before: a folder, or a link to ``/dev/zero``, in place of the config's ramp fell back to the package's."""
    if kind == "device" and not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    copy = _copy_without_ramp(tmp_path)
    side = _unreadable(tmp_path, kind, f"designed-kitchen.{suffix}.json")
    with pytest.raises(ValueError, match=what) as info:
        make_policy(policy, load_config(copy), config_path=copy)
    assert str(side) in str(info.value)
