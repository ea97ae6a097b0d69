"""``pneunet-grasp evaluate`` on a tiny grid; its tables, JSON and plots."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.common.cli import parse_overrides
from agents.evaluation.batch import draw_objects
from agents.evaluation.objects import catalogue_stiffness_range, draw_bins, stiffness_bins, stiffness_grid
from agents.evaluation.summaries import decade_table, regime_summary
from agents.policies.registry import DEFAULT_MODEL
from pneunet_env import PAPER_TASK, EnvConfig, load_config
from pneunet_env.cli import main
from pneunet_env.objects import stiffness_per_modulus

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def _headless_matplotlib(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_evaluate_tiny_grid_writes_rows_and_both_pngs(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    policies = ["ramp", "step", "best-ramp", "oracle", "rigid"]
    if DEFAULT_MODEL.is_file():  # the committed trained model, if present
        pytest.importorskip("stable_baselines3")
        policies.append(str(DEFAULT_MODEL))
    args = ["evaluate", "--stiffness-grid", "2", "--episodes", "1", "--k-min", "1e-5", "--k-max", "1e-2",
            "--schedule-stiffness", "1e-5", "1e-2", "--out", str(tmp_path), "--quiet",
            "--set", "use_case=null", "--set", "damage_rule=crush_fraction", "--set", "hold_rule=slab",
            "--set", "shape=ring"]  # the paper's task (PAPER_TASK)
    for p in policies:
        args += ["--policy", p]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "soft (< 1e-4)" in out and "stiff (>= 1e-3)" in out

    rows = json.loads((tmp_path / "evaluation.json").read_text())
    assert isinstance(rows, list) and len(rows) == 2 * len(policies)
    for r in rows:
        assert {"policy", "object_stiffness", "success_rate", "damage_rate", "slip_rate"} <= set(r)
        for key in ("success_rate", "damage_rate", "slip_rate"):
            assert 0.0 <= r[key] <= 1.0
        assert r["success_rate"] + r["damage_rate"] + r["slip_rate"] == pytest.approx(1.0)  # one outcome each
        assert r["solver_failures"] == 0
    assert sorted({r["object_stiffness"] for r in rows}) == pytest.approx([1e-5, 1e-2])
    by = {(r["policy"], r["object_stiffness"] > 1e-3): r for r in rows}
    # the physics at the default thresholds (docs/env.md): a stiff object is held by best-ramp, the oracle and the
    # rigid gripper; a k~ = 1e-5 gel is held by none (below the feasible stiffness 9.8e-4)
    for name in ("best-ramp", "oracle", "rigid"):
        assert by[(name, True)]["success_rate"] == 1.0
        assert by[(name, False)]["success_rate"] == 0.0
    assert by[("best-ramp", False)]["damage_rate"] == 1.0  # the pneu-net crushes the gel
    assert by[("rigid", False)]["slip_rate"] == 1.0  # the rigid jaw, stopped short of crushing, lets it slip

    summary = json.loads((tmp_path / "evaluation_summary.json").read_text())
    assert set(summary["regimes"]) == set(policies)
    assert summary["feasible_stiffness"] == pytest.approx(9.81e-4)
    for name in ("success_vs_stiffness.png", "schedules.png"):
        data = (tmp_path / name).read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 10_000


def test_evaluate_rejects_bad_input(tmp_path):
    with pytest.raises(SystemExit, match="unknown policy"):
        main(["evaluate", "--policy", "nope", "--out", str(tmp_path)])
    with pytest.raises(SystemExit, match="unknown config key"):
        main(["evaluate", "--policy", "ramp", "--set", "not_a_key=1", "--out", str(tmp_path)])
    with pytest.raises(SystemExit, match="grid size"):
        main(["evaluate", "--policy", "ramp", "--stiffness-grid", "0", "--out", str(tmp_path)])
    with pytest.raises(SystemExit, match="twice"):
        main(["evaluate", "--policy", "ramp", "--policy", "ramp", "--out", str(tmp_path)])


def test_stiffness_grid_spans_the_config_range():
    paper = load_config(**PAPER_TASK)
    g = stiffness_grid(paper, 5)
    unit = stiffness_per_modulus(10.0, 4.0)  # k~ per kPa of mu_obj at the paper's object (eq. 3.2)
    assert g[0] == pytest.approx(0.1 * unit) and g[-1] == pytest.approx(1500.0 * unit)
    assert g[0] == pytest.approx(6.8e-6, rel=0.02) and g[-1] == pytest.approx(0.10, rel=0.03)
    assert np.allclose(np.diff(np.log(g)), np.log(g[1] / g[0]))
    assert stiffness_grid(paper, 1, 1e-4, 1e-2) == pytest.approx([1e-3])


def test_stiffness_grid_spans_the_catalogue_on_the_default_task():
    # the default task draws hand-scale objects: the grid spans them, not the paper ring's unused ranges
    lo, hi = catalogue_stiffness_range(EnvConfig())
    assert lo == pytest.approx(1.56e-3, rel=0.01) and hi == pytest.approx(37.3, rel=0.01)
    g = stiffness_grid(EnvConfig(), 5)
    assert g[0] == pytest.approx(lo) and g[-1] == pytest.approx(hi)
    centres, edges = stiffness_bins(EnvConfig(), 4)
    assert edges[0] == pytest.approx(lo) and edges[-1] == pytest.approx(hi) and centres.size == 4
    assert centres == pytest.approx(np.sqrt(edges[:-1] * edges[1:]))
    # the env's own draws fall inside it
    k = np.asarray(draw_objects(EnvConfig(), list(range(2000))).stiffness)
    assert lo <= k.min() and k.max() <= hi


def test_bins_up_to_the_largest_float_have_finite_centres_without_a_warning():
    """``evaluate --k-max 1e308`` gave an overflow warning in the centres (the product of two edges); they are taken
    in log space now."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        centres, edges = stiffness_bins(EnvConfig(), 5, 1e-6, 1e308)
    assert np.isfinite(centres).all() and edges[-1] == pytest.approx(1e308) and (np.diff(centres) > 0).all()


def test_draw_bins_holds_drawn_objects_of_each_bin():
    cfg = EnvConfig()
    _, edges = stiffness_bins(cfg, 3)
    bins, drawn = draw_bins(cfg, edges, 2, seed=0, chunk=5000)
    assert [len(b) for b in bins] == [2, 2, 2] and drawn >= 5000
    k = np.asarray(draw_objects(cfg, [s for b in bins for s in b]).stiffness).reshape(3, 2)
    for i in range(3):
        assert ((edges[i] <= k[i]) & (k[i] < edges[i + 1])).all()
    assert draw_bins(cfg, edges, 2, seed=0, chunk=5000)[0] == bins  # fixed seeds


def test_parse_overrides_reads_yaml_values():
    assert parse_overrides(["object_density_kg_m3=[30, 1000]", "crush_fraction=7.5", "observe_volume=true"]) == {
        "object_density_kg_m3": [30, 1000], "crush_fraction": 7.5, "observe_volume": True}
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_overrides(["crush_fraction"])


def _row(policy, k, s, d, sl, n=1):
    return {"policy": policy, "label": policy, "object_stiffness": k, "success_rate": s, "damage_rate": d,
            "slip_rate": sl, "episodes": n}


def test_regime_summary_and_decade_table():
    rows = [_row("a", 2e-5, 0.0, 1.0, 0.0), _row("a", 5e-5, 0.5, 0.5, 0.0, n=2), _row("a", 5e-4, 0.0, 0.0, 1.0),
            _row("a", 2e-3, 1.0, 0.0, 0.0), _row("a", 3e-2, 1.0, 0.0, 0.0)]
    reg = regime_summary(rows)["a"]
    assert reg["soft"]["success_rate"] == pytest.approx(1 / 3)  # episode-weighted: (0 * 1 + 0.5 * 2) / 3
    assert reg["soft"]["episodes"] == 3
    assert reg["intermediate"]["slip_rate"] == 1.0
    assert reg["stiff"]["success_rate"] == 1.0
    assert reg["all"]["episodes"] == 6
    table = decade_table(rows)
    assert "1e-05 - 1e-04" in table and "1e-02 - 1e-01" in table
    assert table.count("\n") >= 8


def test_demo_default_task_by_regime_and_class(tmp_path, capsys):
    out_json = tmp_path / "demo.json"
    assert main(["demo", "--objects", "8", "--json", str(out_json), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "force-controlled" in out and "position-controlled" in out and "by object class" in out
    data = json.loads(out_json.read_text())
    assert set(data["summary"]) == {"best-ramp", "oracle", "rigid"} and len(data["regime"]) == 8
    eps = data["episodes"]
    # the same objects for every policy
    assert [e["stiffness"] for e in eps["best-ramp"]] == [e["stiffness"] for e in eps["oracle"]]
    assert [e["object_class"] for e in eps["rigid"]] == data["classes"]
    assert set(data["classes"]) <= {"apple", "kiwifruit", "soft_cheese", "gelatin_gel"}


def test_demo_main_job_runs_best_ramp_with_oracle_and_rigid(tmp_path, capsys):
    out_json = tmp_path / "demo.json"
    assert main(["demo", "--task", "paper", "--bins", "2", "--episodes", "2", "--k-min", "1e-5", "--k-max", "1e-1",
                 "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "best-ramp" in out and "oracle" in out and "rigid" in out
    assert "soft (k~ < 1e-4)" in out and "stiff (k~ >= 1e-3)" in out
    data = json.loads(out_json.read_text())
    assert set(data["policies"]) == {"best-ramp", "oracle", "rigid"}
    episodes = data["episodes"]
    assert len(episodes) == 3 * 2 * 2
    # the same objects for every policy
    ks = {p: [e["stiffness"] for e in episodes if e["policy"] == p] for p in data["policies"]}
    assert ks["best-ramp"] == ks["oracle"] == ks["rigid"]
    with pytest.raises(SystemExit, match="unknown policy"):
        main(["demo", "--policy", "nope"])
