"""``evaluate``, ``demo``, ``map`` and ``search`` describe the task they run on (its objects, its damage rule in
words, regimes read off the mechanics), reject the other task's options with a one-line error naming the task,
and check matplotlib before any episode runs."""

from __future__ import annotations

import json
import sys

import pytest

from agents.common.words import damage_rule_text, rate_parts, task_description
from pneunet_env import PAPER_TASK
from pneunet_env.cli import require_extra
from pneunet_env.config import load_config


@pytest.fixture(autouse=True)
def _headless_matplotlib(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


def _strict_json(path):
    def no_nan(x):
        raise ValueError(f"{path} holds {x}")

    return json.loads(path.read_text(), parse_constant=no_nan)


# ------------------------------------------------------------------------------------------------ the task in words
def test_the_task_in_words():
    default = load_config()
    assert task_description(default).startswith("the catalogue's 'kitchen' use case (apple 30%")
    assert "hoop strain" in damage_rule_text(default) and "failure strain" in damage_rule_text(default)
    assert "class's failure stress" in damage_rule_text(default) and "crush_fraction" not in damage_rule_text(default)
    paper = load_config(**PAPER_TASK)
    assert task_description(paper).startswith("the paper's ring: R = 250 mm, H = 10 mm")
    assert "indentation delta exceeds 1 H" in damage_rule_text(paper)
    # whatever the objects, the rule printed is the config's
    assert "exceeds 7.5 H" in damage_rule_text(load_config(damage_rule="crush_fraction", crush_fraction=7.5))
    assert "hoop strain" in damage_rule_text(load_config(use_case=None))


def test_rate_parts_leave_out_empty_groups():
    assert rate_parts([("force", 0.75, 4), ("position", float("nan"), 0)]) == "force 75.0% of 4"
    assert rate_parts([("soft", None, 0), ("stiff", None, 0)]) == "no objects"


def test_evaluate_on_the_default_task_describes_it(tmp_path, cli):
    rc, out, err = cli(["evaluate", "--policy", "best-ramp", "--stiffness-grid", "2", "--episodes", "1",
                         "--objects", "4", "--no-plots", "--no-progress", "--out", str(tmp_path)])
    assert rc == 0, err
    assert "'kitchen' use case" in out and "hoop strain delta kappa_obj exceeds" in out
    assert "delta > 1 H" not in out and "H = 10 mm" not in out
    assert "nan" not in out.lower()
    assert "soft (< 1e-4)" not in out and "the paper's k~ bins" not in out  # no meaning at hand scale
    assert "force-controlled" in out and "position-controlled" in out  # the regimes, from the mechanics
    rows = _strict_json(tmp_path / "evaluation.json")
    assert rows and all(r["objects"] == "drawn" for r in rows)
    assert {c for r in rows for c in r["by_class"]} <= {"apple", "kiwifruit", "soft_cheese", "gelatin_gel"}
    for r in rows:  # each row's objects are the env's own, inside their bin
        lo, hi = r["k_range"]
        assert lo <= r["mean_object_stiffness"] < hi and r["object_stiffness"] == pytest.approx((lo * hi) ** 0.5)
    summary = _strict_json(tmp_path / "evaluation_summary.json")
    assert summary["task"]["damage_rule"] == "hoop_strain" and "kitchen" in summary["task"]["objects"]
    assert summary["regime_bounds"] is None and summary["feasible_stiffness"] is None
    assert "soft" not in summary["regimes"]["best-ramp"]
    assert "success_rate_soft" not in summary["distribution"]["best-ramp"]


def test_evaluate_prints_the_damage_rule_it_is_given(tmp_path, cli):
    rc, out, err = cli(["evaluate", "--policy", "ramp", "--stiffness-grid", "1", "--episodes", "1", "--no-plots",
                         "--no-progress", "--set", "damage_rule=crush_fraction", "--out", str(tmp_path)])
    assert rc == 0, err
    assert "indentation delta exceeds 1 H" in out and "damage_rule crush_fraction" in out
    assert "hoop strain" not in out and "nan" not in out.lower()


def test_demo_on_the_default_task_describes_it(cli):
    rc, out, err = cli(["demo", "--objects", "4", "--policy", "best-ramp", "--no-progress"])
    assert rc == 0, err
    assert "'kitchen' use case" in out and "hoop strain delta kappa_obj exceeds" in out
    assert "regime from the mechanics at 60 kPa" in out and "nan" not in out.lower()
    rc, out, err = cli(["demo", "--objects", "4", "--policy", "best-ramp", "--no-progress",
                         "--set", "damage_rule=crush_fraction"])
    assert rc == 0, err
    assert "damage_rule crush_fraction" in out and "hoop strain" not in out


# ------------------------------------------------------------------------------------------------ the other task's
@pytest.mark.parametrize("option", [["--k-min", "1e-4"], ["--k-max", "1"], ["--bins", "3"], ["--episodes", "2"],
                                    ["--bins", "3", "--k-min", "1e-4"]])
def test_paper_options_on_the_default_task_are_an_error_naming_the_task(option, cli):
    rc, out, err = cli(["demo", *option])
    assert rc == 2 and out == ""
    line = err.strip()
    assert "\n" not in line and "Traceback" not in err
    assert line.startswith("pneunet-grasp demo: error: ") and "--task paper" in line
    assert all(flag in line for flag in option if flag.startswith("--"))


def test_a_default_task_option_on_the_paper_task_is_an_error(cli):
    rc, _, err = cli(["demo", "--task", "paper", "--objects", "3"])
    assert rc == 2 and "--objects" in err and "--task paper" in err and err.count("\n") == 1


@pytest.mark.parametrize(("argv", "named"), [
    (["search", "--grid", "5"], "--sensitivity"),
    (["search", "--sensitivity", "--set", "crush_fraction=2"], "--set"),
    (["search", "--sensitivity", "--gripper", "rigid"], "--gripper"),
    (["map", "--density", "1000", "--density-radius", "20"], "--density-radius"),
    (["evaluate", "--no-plots", "--schedule-stiffness", "1e-2"], "--schedule-stiffness"),
])
def test_an_option_that_would_be_ignored_is_an_error(argv, named, cli, monkeypatch):
    import agents.evaluation.evaluate_cli
    import agents.evaluation.map_cli
    import agents.search.cli

    def no_work(*args, **kwargs):
        raise AssertionError("the work started")

    for module, name in ((agents.search.cli, "sensitivity_study"), (agents.search.cli, "search_ramp"),
                         (agents.evaluation.map_cli, "success_map"),
                         (agents.evaluation.evaluate_cli, "evaluate_policies")):
        monkeypatch.setattr(module, name, no_work)
    rc, out, err = cli(argv)
    assert rc == 2 and named in err and err.count("\n") == 1 and "Traceback" not in err


# ------------------------------------------------------------------------------------------------ matplotlib
@pytest.mark.parametrize(("argv", "work"), [
    (["evaluate", "--policy", "ramp"], ("agents.evaluation.evaluate_cli", "evaluate_policies")),
    (["map", "--grid", "1", "1"], ("agents.evaluation.map_cli", "success_map")),
    (["search", "--sensitivity"], ("agents.search.cli", "sensitivity_study")),
    (["search", "--plot", "x.png"], ("agents.search.cli", "search_ramp")),
])
def test_missing_matplotlib_stops_before_any_episode(argv, work, tmp_path, cli, monkeypatch):
    import importlib

    module = importlib.import_module(work[0])

    def no_work(*args, **kwargs):
        raise AssertionError("an episode ran before the check")

    monkeypatch.setattr(module, work[1], no_work)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    out_dir = tmp_path / "out"
    rc, out, err = cli([*argv, "--out", str(out_dir)])
    assert rc == 2 and out == "" and "Traceback" not in err
    line = err.strip()
    assert "\n" not in line and "matplotlib" in line and '".[plot]"' in line and "pneunet-env[plot]" in line
    assert not out_dir.exists()
    if argv[0] == "evaluate":
        assert "--no-plots" in line  # the way to do without


def test_require_extra_passes_when_the_module_imports():
    require_extra("x", "json", "plot")  # no exit


# ------------------------------------------------------------------------------------------------ the map's terms
DEFINITION = ("phi (blocked_fraction) is the share of the curl the free finger would make past the object's surface "
              "that the object blocks")


def _map_result() -> dict:
    """A 2 x 2 map's result, without running it: what :func:`agents.figures.maps.plot_map` and the summary read."""
    from agents.common.map_record import summarize
    from agents.common.words import phi_definition
    from agents.evaluation.maps import ROLES, _catalogue_boxes

    cfg = load_config()
    grid = [[0.0, 1.0], [1.0, 1.0]]
    result = {
        "youngs_modulus_kpa": [1.0, 1000.0], "radius_mm": [15.0, 40.0], "thickness_rule": "H = R/4",
        "thickness_ratio": 0.25, "density_kg_m3": 1000.0, "failure_strain": 0.3, "damage_rule": "hoop_strain",
        "damage": damage_rule_text(load_config(use_case=None)), "regime_boundary": phi_definition(60.0),
        "task": task_description(cfg), "episodes": 1, "roles": list(ROLES),
        "policies": {r: {"label": r, "env_id": "PneuNetGrasp-v1", "success": grid, "damage": [[1.0, 0.0], [0.0, 0.0]],
                         "slip": [[0.0, 0.0], [0.0, 0.0]]} for r in ROLES},
        "phi": [[0.1, 0.9], [0.2, 0.8]],
        "phi_fine": {"youngs_modulus_kpa": [1.0, 1000.0], "radius_mm": [15.0, 40.0], "phi": [[0.1, 0.9], [0.2, 0.8]]},
        "regime_pressure_kpa": 60.0, "jaw_nominal_radius_mm": 27.5, "window": grid,
        "catalogue": _catalogue_boxes(cfg), "density_row": None, "elapsed_s": 0.0,
    }
    result["summary"] = summarize(result)
    return result


def test_map_defines_phi_in_its_figure_and_summary(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from agents.evaluation.map_cli import _report
    from agents.figures.maps import plot_map

    seen = {}

    def savefig(fig, path, **kwargs):  # what the figure says, instead of a PNG
        seen["texts"] = [t.get_text() for t in fig.texts]
        seen["legend"] = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
        seen["title"] = fig._suptitle.get_text()

    monkeypatch.setattr(Figure, "savefig", savefig)
    result = _map_result()
    plot_map(result, tmp_path / "map.png")
    assert any("regime boundary phi = 1/2 at 60 kPa" in t and "force-controlled left" in t for t in seen["legend"])
    assert any("catalogue's 'kitchen' use case" in t for t in seen["legend"])
    caption = " ".join(seen["texts"])
    assert DEFINITION in caption and "phi < 1/2" in caption and "phi >= 1/2" in caption
    assert "force-controlled on the soft side" in caption and "position-controlled on the stiff side" in caption
    assert "hoop strain" in seen["title"] and "H = 10 mm" not in seen["title"]
    report = _report(result)
    assert DEFINITION in report and "hoop strain delta kappa_obj exceeds" in report and "'kitchen' use case" in report
    assert "window = the cells where the oracle succeeds" in report


@pytest.mark.slow  # a few seconds: three policies, one cell, episode by episode
def test_map_command_prints_and_writes_the_terms(tmp_path, cli):
    rc, out, err = cli(["map", "--grid", "1", "1", "--density", "1000", "--no-plot", "--no-progress",
                         "--out", str(tmp_path)])
    assert rc == 0, err
    assert DEFINITION in out and "force-controlled on the soft side" in out
    assert "hoop strain delta kappa_obj exceeds" in out and "'kitchen' use case" in out
    result = _strict_json(tmp_path / "map.json")
    assert DEFINITION in result["regime_boundary"] and "hoop strain" in result["damage"]
    assert "kitchen" in result["task"] and result["catalogue"]
