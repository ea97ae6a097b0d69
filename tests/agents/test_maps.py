"""``pneunet-grasp map`` on a tiny grid: map.json and map.png, the rates, the regime fraction, every policy."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.evaluation.maps import ROLES, blocked_fraction_grid, map_config, object_options
from agents.policies.registry import BEST_RAMP_PATH, BEST_RIGID_PATH
from pneunet_env.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def _headless_matplotlib(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


def _policy_args() -> list[str]:
    """The tuned schedules when their files exist; stand-ins otherwise (the files are written by agents.search)."""
    args = []
    if not BEST_RAMP_PATH.is_file():
        args += ["--blind", "ramp:target_kpa=30,steps=40"]
    if not BEST_RIGID_PATH.is_file():
        args += ["--rigid", "rigid:target_mm=10,steps=20"]
    return args


def test_object_options_pin_the_object():
    o = object_options(300.0, 20.0, density_kg_m3=30.0, failure_strain=0.2)
    assert o["object_shear_modulus_kpa"] == pytest.approx(100.0)
    assert o["object_curvature_per_m"] == pytest.approx(50.0)
    assert o["object_thickness_mm"] == pytest.approx(5.0)  # H = R/4
    assert o["object_density_kg_m3"] == 30.0 and o["object_failure_strain"] == 0.2


def test_blocked_fraction_rises_with_the_modulus_and_crosses_one_half():
    E = np.logspace(0, np.log10(3000), 12)
    phi = blocked_fraction_grid(E, [15.0, 40.0], map_config())
    assert phi.shape == (2, 12)
    assert np.isfinite(phi).all() and ((phi >= 0) & (phi <= 1)).all()
    assert (np.diff(phi, axis=1) > 0).all()
    assert (phi[:, 0] < 0.5).all() and (phi[:, -1] > 0.5).all()  # both regimes lie on the map


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_map_command_on_a_tiny_grid(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    args = ["map", "--grid", "3", "2", "--episodes", "1", "--density", "1000", "30", "--out", str(tmp_path),
            "--no-progress", *_policy_args()]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "feasible window" in out and "map.png" in out

    assert (tmp_path / "map.png").read_bytes()[:8] == PNG_MAGIC
    result = json.loads((tmp_path / "map.json").read_text())  # strict JSON: no NaN
    assert result["roles"] == list(ROLES) and set(result["policies"]) == set(ROLES)
    E, R = result["youngs_modulus_kpa"], result["radius_mm"]
    assert len(E) == 3 and len(R) == 2 and E[0] == pytest.approx(0.1) and R == pytest.approx([15.0, 40.0])
    for role in ROLES:
        p = result["policies"][role]
        rates = {k: np.array(p[k], dtype=float) for k in ("success", "damage", "slip")}
        for a in rates.values():
            assert a.shape == (2, 3) and ((a >= 0) & (a <= 1)).all()
        assert (rates["success"] + rates["damage"] + rates["slip"] <= 1.0 + 1e-9).all()
        assert p["solver_failures"] == 0
        assert role in result["summary"]
    phi = np.array(result["phi"], dtype=float)
    assert phi.shape == (2, 3) and (np.diff(phi, axis=1) > 0).all()  # phi rises with E at every radius
    assert np.array_equal(np.array(result["window"]) > 0.5, np.array(result["policies"]["oracle"]["success"]) >= 0.5)
    row = result["density_row"]
    assert row["density_kg_m3"] == [30.0, 1000.0] and set(row["policies"]) == set(ROLES)
    assert np.array(row["policies"]["oracle"]["success"]).shape == (2, 3)
    assert result["catalogue"] and all({"name", "youngs_modulus_kpa", "radius_mm"} <= set(b)
                                       for b in result["catalogue"])
