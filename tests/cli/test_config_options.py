"""``--config`` and ``--set`` of ``pneunet-grasp map`` and ``demo``: validated before any episode runs (one-line
errors), the map drawn for another actuator, and a tuned schedule shipped beside a config file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.common.cli import parse_overrides
from agents.evaluation.maps import map_config, task_config
from agents.policies.registry import BEST_RAMP_PATH, BEST_RIGID_PATH, make_policy, tuned_path
from pneunet_env.cli import main
from pneunet_env.config import load_config

BAD_OPTIONS = {
    "bad YAML": (["--set", "x=["], "x=["),
    "no equals sign": (["--set", "top_thickness_mm"], "top_thickness_mm"),
    "unknown key": (["--set", "no_such_key=1"], "no_such_key"),
    "bad value": (["--set", "shear_modulus_kpa=-3"], "shear_modulus_kpa"),
    "missing config": (["--config", "no/such/config.yaml"], "no/such/config.yaml"),
}


@pytest.fixture(autouse=True)
def _headless_matplotlib(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


def _config_with_ramp(tmp_path: Path, target: float = 0.5, n_steps: int = 10) -> Path:
    """``tmp_path/soft.yaml`` (another actuator) with ``soft.best_ramp.json`` beside it; the config's path."""
    cfg = tmp_path / "soft.yaml"
    cfg.write_text("actuator:\n  shear_modulus_kpa: 40.0\ntask:\n  max_pressure_kpa: 50.0\n")
    ramp = json.loads(BEST_RAMP_PATH.read_text()) if BEST_RAMP_PATH.is_file() else {"kind": "linear_ramp"}
    ramp.update(target=target, n_steps=n_steps, target_kpa=target * 50.0, max_pressure_kpa=50.0)
    (tmp_path / "soft.best_ramp.json").write_text(json.dumps(ramp))
    return cfg


# ------------------------------------------------------------------------------------------------ bad options
@pytest.mark.parametrize("command", ["map", "demo"])
@pytest.mark.parametrize("case", list(BAD_OPTIONS))
def test_bad_option_is_a_one_line_error_naming_it(command, case, tmp_path, capsys):
    args, named = BAD_OPTIONS[case]
    with pytest.raises(SystemExit) as exc:
        main([command, *args, "--out" if command == "map" else "--json", str(tmp_path / "out")])
    assert exc.value.code == 2  # an argument error's status; the message is on stderr, one line
    err = capsys.readouterr().err
    assert err.startswith(f"pneunet-grasp {command}: error: ") and err.count("\n") == 1
    assert named in err and named in str(exc.value) and "Traceback" not in err
    assert not (tmp_path / "out").exists()  # nothing ran


def test_parse_overrides_reads_yaml_values():
    assert parse_overrides(["a=1.5", "b=[1, 2]", "c=true", "d=null"]) == {"a": 1.5, "b": [1, 2], "c": True,
                                                                            "d": None}
    assert parse_overrides([]) == {} and parse_overrides(None) == {}


# ------------------------------------------------------------------------------------------------ the map's config
def test_map_config_keeps_its_defaults_and_takes_overrides_on_top(tmp_path):
    old = load_config(use_case=None, damage_rule="hoop_strain", object_curvature_per_m=[25.0, 1000.0 / 15.0],
                      object_thickness_mm=[3.75, 10.0])
    assert map_config() == old
    cfg = map_config(None, {"top_thickness_mm": 1.5, "max_pressure_kpa": 80.0, "use_case": "kitchen"},
                     radius_range_mm=(20.0, 50.0))
    assert cfg.actuator.top_thickness_mm == 1.5 and cfg.task.max_pressure_kpa == 80.0
    assert cfg.objects.use_case is None  # the map pins its objects: they stay from ranges
    assert cfg.objects.object_curvature_per_m == pytest.approx((20.0, 50.0))  # spans the radius axis, 50 to 20 mm
    assert cfg.objects.object_thickness_mm == pytest.approx((5.0, 12.5))
    task = task_config(None, {"max_pressure_kpa": 80.0})
    assert task.objects.from_catalogue and task.task.max_pressure_kpa == 80.0
    # the tuned ramp is defined in kPa: another p_max does not move it (issue 37)
    label = make_policy("best-ramp", task).label
    if BEST_RAMP_PATH.is_file():
        assert f"{json.loads(BEST_RAMP_PATH.read_text())['target_kpa']:.3g} kPa" in label


def test_map_draws_another_actuator(tmp_path):
    out = tmp_path / "map"
    rc = main(["map", "--grid", "1", "1", "--density", "1000", "--set", "shear_modulus_kpa=30", "--set",
               "top_thickness_mm=2", "--out", str(out)])
    assert rc == 0
    assert (out / "map.png").read_bytes().startswith(b"\x89PNG")
    result = json.loads((out / "map.json").read_text())
    assert result["config"]["actuator"]["shear_modulus_kpa"] == 30.0
    assert result["config"]["actuator"]["top_thickness_mm"] == 2.0
    assert set(result["policies"]) == {"oracle", "best-ramp", "rigid"}


# ------------------------------------------------------------------------------------------------ beside a config
def test_tuned_path_prefers_a_schedule_beside_the_config(tmp_path):
    cfg_path = _config_with_ramp(tmp_path)
    cfg = load_config(cfg_path)
    assert tuned_path(cfg, config_path=cfg_path) == tmp_path / "soft.best_ramp.json"
    assert tuned_path(cfg, "rigid", config_path=cfg_path) == BEST_RIGID_PATH  # none beside it: the package's
    assert tuned_path(cfg) == BEST_RAMP_PATH
    assert tuned_path(cfg, config_path=tmp_path / "other.yaml") == BEST_RAMP_PATH
    entry = make_policy("best-ramp", cfg, config_path=cfg_path)
    assert "25 kPa over 10 steps" in entry.label and "soft.best_ramp.json" in entry.label
    # an explicit path= still wins
    if BEST_RAMP_PATH.is_file():
        assert "soft.best_ramp.json" not in make_policy(f"best-ramp:path={BEST_RAMP_PATH}", cfg,
                                                        config_path=cfg_path).label


def test_rigid_schedule_beside_the_config(tmp_path):
    cfg_path = _config_with_ramp(tmp_path)
    (tmp_path / "soft.best_rigid.json").write_text(json.dumps({"kind": "linear_ramp", "target": 0.4, "n_steps": 7,
                                                               "gripper": "rigid", "target_mm": 3.0}))
    cfg = load_config(cfg_path)
    entry = make_policy("rigid", cfg, config_path=cfg_path)
    assert "3 mm over 7 steps" in entry.label and "soft.best_rigid.json" in entry.label
    assert "soft.best_rigid.json" not in make_policy("rigid:target_mm=3,steps=7", cfg, config_path=cfg_path).label


def test_demo_picks_up_the_ramp_beside_its_config(tmp_path, capsys):
    cfg_path = _config_with_ramp(tmp_path, target=0.5, n_steps=10)
    rc = main(["demo", "--config", str(cfg_path), "--set", "hold_steps=20", "--policy", "best-ramp", "--objects",
               "5"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "best-ramp (25 kPa over 10 steps; from soft.best_ramp.json)" in out  # 0.5 of the config's 50 kPa
    assert "50 hold steps" not in out and "20 hold steps" in out  # --set applied on top of --config
