"""The actuator design study (agents.design): scores, the Optuna study (default storage, resume, two workers), and
every new input's bad values."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

optuna = pytest.importorskip("optuna")

from agents.design import (  # noqa: E402
    DESIGN_SPACE,
    P_TILDE_MAX,
    design_config,
    elastomers,
    evaluate_design,
    main,
    parse_bounds,
    perturbed_config,
    reference_regimes,
    table1_design,
)
from agents.design.study import _pareto  # noqa: E402
from agents.evaluation.batch import episode_seeds  # noqa: E402
from pneunet_env import load_config  # noqa: E402

SMALL = ["--objects", "8", "--held-out", "8", "--top", "1", "--quiet",
         "--bound", "top_thickness_mm=1.5:2.5", "--bound", "chamber_height_mm=5:6"]


def test_every_elastomer_has_a_source_and_a_gent_limit():
    table = elastomers()
    assert "table1" in table and len(table) >= 4
    for e in table.values():
        assert e.shear_modulus_kpa > 0 and e.gent_limit > 0 and len(e.source) > 10, e


def test_each_elastomer_carries_the_range_its_data_support():
    """J over the fit windows (stretch <= 2 and <= 3.5 around the nominal <= 3) and the data sheet's mu: the corners
    a design is scored at; the paper's Table 1 material has no data, so no range."""
    from agents.design.space import elastomers as table

    eco = table()["ecoflex_00_10"]
    assert eco.gent_limit_range == (13.4, 24.7) and eco.datasheet_mu_kpa == 31.5
    assert [(mu, j) for _, mu, j in eco.corners()] == [(7.6, 13.4), (7.6, 24.7), (31.5, 22.0)]
    assert table()["table1"].corners() == []
    for e in table().values():
        if e.gent_limit_range is not None:
            assert e.gent_limit_range[0] <= e.gent_limit <= e.gent_limit_range[1], e.name


def test_a_design_is_scored_at_its_worst_corner_and_its_window_centre():
    from agents.design.space import PRESSURE_ERROR_KPA, wall_stretch

    seeds = episode_seeds(24)
    ref = reference_regimes(seeds)
    s = evaluate_design({**table1_design(), "elastomer": "ecoflex_00_30"}, seeds, ref)
    assert len(s.corners) == 4 + 3 + 2  # walls x modulus, the material's three, the regulator either way
    for k in ("force", "position", "all"):
        vals = [c[k] for c in s.corners.values() if not np.isnan(c[k])]
        assert s.worst_corner[k] == (min(vals) if vals else s.worst_corner[k])
    assert f"pressure -{PRESSURE_ERROR_KPA:g} kPa" in s.corners and f"pressure +{PRESSURE_ERROR_KPA:g} kPa" in s.corners
    lo, hi = s.window_kpa
    step = s.pressures_kpa[1] - s.pressures_kpa[0]
    assert lo <= s.pressure_kpa <= hi and abs(s.pressure_kpa - (lo + hi) / 2) <= step / 2 + 1e-9  # the centre
    assert s.wall_stretch == wall_stretch(design_config(s.params), s.pressure_kpa) > 1.0
    assert s.outside_data is (s.wall_stretch > 3.0)
    t1 = evaluate_design(table1_design(), seeds, ref, pressure_error_kpa=0.0)
    assert t1.outside_data is None and len(t1.corners) == 4 + 2  # no material data: the paper's own material
    from agents.design.score import design_rank

    assert design_rank(s)[0] <= min(s.worst_corner["force"], s.worst_corner["position"])


def test_tied_scores_give_no_importance_and_say_why_without_a_warning(recwarn):
    """Under the worst-corner score most designs of a small study hold nothing: PED-ANOVA then warns that its target
    and region select the same designs (importances all equal). The report says so instead of printing Optuna's
    warning or charting equal bars."""
    from agents.design.study import TIED_IMPORTANCE, _importance

    study = optuna.create_study(directions=["maximize"] * 3)
    for i in range(12):
        t = study.ask()
        t.suggest_float("top_thickness_mm", 1.0, 3.75)
        t.suggest_float("width_mm", 5.0, 15.0)
        t.set_user_attr("score", {"score": 0.0 if i else 0.5})
        study.tell(t, [0.0, 0.0, 0.0])
    assert _importance(study) == ({}, TIED_IMPORTANCE)
    assert not [w for w in recwarn if "same set of trials" in str(w.message)]


def test_design_space_bounds_are_sourced():
    for b in DESIGN_SPACE:
        assert 0 < b.low < b.high and b.source


def test_design_config_scales_the_pressure_with_the_modulus():
    soft = design_config({"shear_modulus_kpa": 20.0, "gent_limit": 10.0})
    assert soft.task.max_pressure_kpa == pytest.approx(P_TILDE_MAX * 20.0)
    assert soft.pressure_max == pytest.approx(P_TILDE_MAX)
    assert soft.pressure_step == pytest.approx(0.06)
    t1 = design_config(table1_design())
    assert t1.task.max_pressure_kpa == 60.0 and t1.task.max_pressure_step_kpa == 3.0
    assert t1.actuator == load_config().actuator
    p = perturbed_config(t1, [1.1, 0.9, 1.0, 1.2])
    assert p.actuator.top_thickness_mm == pytest.approx(2.75) and p.actuator.shear_modulus_kpa == pytest.approx(60)
    assert p.task.max_pressure_kpa == 60.0  # the schedule's kPa are the nominal design's


@pytest.mark.slow
def test_table1_design_scores_what_the_shipped_search_found():
    # the batched score of Table 1's actuator on the search's 200 objects, at the shipped ramp's target, is
    # agents/best_ramp.json's, to the object (the design's coarser grid need not find the search's refined target)
    seeds = episode_seeds(200)
    ramp = json.loads(open("agents/best_ramp.json").read())
    s = evaluate_design(table1_design(), seeds, reference_regimes(seeds), target=ramp["target"])
    shipped = ramp["score"]
    assert s.blind["all"] == shipped["success_rate"]
    assert s.blind["force"] == pytest.approx(shipped["success_rate_force"])
    assert (s.objects["force"], s.objects["position"]) == (shipped["objects_force"], shipped["objects_position"])
    assert s.oracle["all"] >= s.blind["all"]
    assert s.window_kpa[0] <= s.pressure_kpa <= s.window_kpa[1]


def test_pareto_front():
    pts = np.array([[1, 0], [0, 1], [0.5, 0.5], [0.4, 0.4], [1, 0]])
    assert _pareto(pts).tolist() == [True, True, True, False, True]


@pytest.mark.slow
def test_study_with_the_embedded_storage_then_resumed(tmp_path, capsys):
    out = tmp_path / "kitchen"
    assert main(["--trials", "2", "--out", str(out), *SMALL]) == 0
    res = json.loads((out / "design.json").read_text())
    assert res["trials"] == 2 and (out / "study.db").is_file()
    labels = [d["label"] for d in res["designs"]]
    assert labels in (["table1", "rank-1"], ["table1", "rank-1", "requirement"])
    assert res["designs"][0]["params"]["elastomer"] == "table1"
    if "requirement" in labels:  # the best design is not buildable: the ranks are the buildable ones
        rows = {d["label"]: d for d in res["designs"]}
        assert rows["rank-1"]["search"]["outside_data"] is False
        assert rows["requirement"]["search"]["outside_data"] is not False
    for name in ("pareto.png", "curves.png", "importance.png", "designs/rank-1.yaml", "designs/rank-1.best_ramp.json"):
        assert (out / name).is_file(), name
    cfg = load_config(out / "designs" / "rank-1.yaml")  # an env config gym.make takes
    assert cfg.task.max_pressure_kpa == pytest.approx(P_TILDE_MAX * cfg.actuator.shear_modulus_kpa)
    first = json.loads((out / "design.json").read_text())["all"]
    # resumed: the two designs kept, two more run
    assert main(["--trials", "4", "--out", str(out), *SMALL]) == 0
    res = json.loads((out / "design.json").read_text())
    assert res["trials"] == 4
    assert [a["params"] for a in res["all"][:2]] == [a["params"] for a in first]
    # a study is resumed only with its own settings
    with pytest.raises(SystemExit, match="other settings"):
        main(["--trials", "5", "--out", str(out), *SMALL[:-4]])


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_journal_storage_and_export(tmp_path):
    out = tmp_path / "j"
    exp = tmp_path / "designed.yaml"
    assert main(["--trials", "2", "--out", str(out), "--storage", f"journal:{tmp_path / 'j.log'}", "--export",
                 str(exp), *SMALL]) == 0
    assert (tmp_path / "j.log").is_file() and not (out / "study.db").exists()
    assert exp.is_file() and exp.with_suffix(".best_ramp.json").is_file()


@pytest.fixture
def four_cores(monkeypatch):
    """--jobs 2 and 3 taken on a machine of fewer cores (the bound is checked in the command, not the workers)."""
    import agents.common.workers

    monkeypatch.setattr(agents.common.workers, "usable_cores", lambda: 4, raising=False)
    monkeypatch.setattr(agents.common.workers, "available_memory", lambda: None, raising=False)


@pytest.mark.slow
def test_two_workers_share_one_study(tmp_path, four_cores):
    out = tmp_path / "two"
    assert main(["--trials", "6", "--jobs", "2", "--out", str(out), *SMALL]) == 0
    study = optuna.load_study(study_name="design-kitchen", storage=f"sqlite:///{out / 'study.db'}")
    done = [t for t in study.trials if t.state.is_finished()]
    assert len(done) >= 6
    assert len({t.user_attrs["worker"] for t in done if "worker" in t.user_attrs}) == 2


@pytest.mark.parametrize("argv, match", [
    (["--trials", "0"], "trials"),
    (["--trials", "-3"], "trials"),
    (["--jobs", "0"], "jobs"),
    (["--objects", "0"], "objects"),
    (["--held-out", "0"], "held_out"),
    (["--seed", "-1"], "seed"),
    (["--use-case", "garage"], "garage"),
    (["--class-weights", "apple"], "class-weights"),
    (["--class-weights", "apple=heavy"], "apple"),
    (["--class-weights", "plutonium=1"], "plutonium"),
    (["--storage", "nonsense"], "storage"),
    (["--storage", "journal:"], "journal"),
    (["--storage", "ftp://x/y"], "storage"),
    (["--bound", "top_thickness_mm"], "KEY=LOW:HIGH"),
    (["--bound", "colour=1:2"], "colour"),
    (["--bound", "top_thickness_mm=3:1"], "LOW < HIGH"),
    (["--bound", "top_thickness_mm=a:2"], "numbers"),
    (["--bound", "top_thickness_mm=0.1:2"], "manufacturable"),
    (["--bound", "top_thickness_mm=nan:2"], "finite"),
    (["--bound", "grip_faces=2.5:3"], "whole"),
    (["--bound", "grip_faces=3:2"], "whole LOW <= HIGH"),
    (["--bound", "grip_faces=1:3"], "manufacturable"),
    (["--bound", "finger_width_mm=1:12"], "manufacturable"),
    (["--bound", "length_mm=90:1000"], "manufacturable"),
    (["--export", "x.txt"], "yaml"),
    (["--worker", "--report"], "exclude"),
    (["--pressure-error-kpa", "-1"], "pressure_error_kpa must be a finite number >= 0"),
    (["--pressure-error-kpa", "nan"], "pressure_error_kpa must be a finite number >= 0"),
    (["--pressure-error-kpa", "inf"], "pressure_error_kpa must be a finite number >= 0"),
])
def test_bad_values_are_refused_before_any_work(tmp_path, argv, match):
    with pytest.raises(SystemExit, match=match):
        main(["--out", str(tmp_path / "o"), "--quiet", *argv])
    assert not (tmp_path / "o" / "design.json").exists()


def test_parse_bounds():
    assert parse_bounds(["width_mm=6:8"]) == {"width_mm": (6.0, 8.0)}
    assert parse_bounds([]) == {}
    assert parse_bounds(["grip_faces=3:3"]) == {"grip_faces": (3.0, 3.0)}  # a whole number may be fixed


def test_the_finger_in_3d_is_designed_within_sourced_ranges():
    # the finger's width, length and count are design parameters (issue 33, item 3); Table 1's finger lies inside
    space = {b.key: b for b in DESIGN_SPACE}
    t1 = table1_design()
    assert (t1["finger_width_mm"], t1["length_mm"], t1["grip_faces"]) == (10.0, 90.0, 2)
    for key in ("finger_width_mm", "length_mm", "grip_faces"):
        b = space[key]
        assert b.low <= t1[key] <= b.high and len(b.source) > 40, b
    assert space["grip_faces"].integer and not space["length_mm"].integer
    # the width sets the cavity's depth t = b - 2 h_s; the grip reads b, length and count from the config
    cfg = design_config({**t1, "finger_width_mm": 20.0, "side_thickness_mm": 3.0, "length_mm": 110.0,
                         "grip_faces": 3})
    a = cfg.actuator
    assert a.depth_mm == pytest.approx(14.0) and a.finger_width_mm == pytest.approx(20.0)
    assert a.length_mm == 110.0 and cfg.task.grip_faces == 3
    assert design_config(t1).actuator == load_config().actuator  # Table 1 unchanged
    with pytest.raises(ValueError, match="finger_width_mm = 8.0 with side_thickness_mm = 3.75 leaves a cavity"):
        design_config({**t1, "finger_width_mm": 8.0, "side_thickness_mm": 3.75})


def test_the_designed_finger_is_no_wider_than_the_narrowest_object(tmp_path):
    # the hold rule presses the finger's whole width on the object: a study caps the width at the narrowest object
    from agents.design.space import narrowest_object_mm
    from agents.design.study import StudySpec, _space

    assert narrowest_object_mm(load_config(use_case="kitchen")) == 30.0  # the 15 mm gels and cheeses, as spheres
    ranges = load_config(use_case=None, object_curvature_per_m=[40.0, 80.0], shape="sphere")
    assert narrowest_object_mm(ranges) == pytest.approx(25.0)  # 2 R at 80 /m
    ring = load_config(use_case=None, shape="ring", object_length_mm=12.0)
    assert narrowest_object_mm(ring) == 12.0
    cap = StudySpec(out=tmp_path, use_case=None, config=None)
    lo, hi = _space(cap)["finger_width_mm"]
    space = {b.key: b for b in DESIGN_SPACE}
    assert lo == space["finger_width_mm"].low and hi == min(space["finger_width_mm"].high,
                                                            narrowest_object_mm(cap.base_config()))


def test_a_finger_wider_than_every_width_allowed_is_refused_by_name(tmp_path):
    """Objects narrower than the narrowest finger width (10 mm): the hold rule would press more finger on them than they
    have, so a study (and the checks' width sweep) is refused with both sizes named, before any work, not run with the
    width silently left above the object (0.15 kept the range's low end)."""
    from agents.design.space import finger_width_range
    from agents.design.study import StudySpec

    small = {"use_case": None, "object_curvature_per_m": [150.0, 250.0], "object_thickness_mm": [1.0, 3.0],
             "shape": "sphere"}
    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump({"objects": small}))
    with pytest.raises(ValueError, match=r"narrowest object is 8 mm across.*finger_width_mm = 10 mm"):
        finger_width_range({}, load_config(**small))
    with pytest.raises(ValueError, match=r"narrowest object is 8 mm across"):
        StudySpec(out=tmp_path / "study", use_case=None, config=str(path))
    # objects 12 mm across: the range is capped there, and a --bound above them leaves no width
    mid = load_config(**{**small, "object_curvature_per_m": [150.0, 166.0]})
    assert finger_width_range({}, mid) == (10.0, pytest.approx(2e3 / 166.0))
    with pytest.raises(ValueError, match=r"finger_width_mm = 15 mm"):
        finger_width_range({"finger_width_mm": (15.0, 20.0)}, mid)


def test_the_design_checks_refuse_small_objects_before_any_work(monkeypatch):
    """``run_design_checks`` sweeps the finger's width to the narrowest object, refused by name first (no design is
    scored), whatever its ``base``; ``base=None`` is the default task's (it read ``None.objects`` once)."""
    import agents.design.score as score
    from agents.design.checks import run_design_checks

    def no_work(*args, **kwargs):
        raise AssertionError("a design was scored before the width was checked")

    monkeypatch.setattr(score, "reference_regimes", no_work)
    small = load_config(use_case=None, object_curvature_per_m=[150.0, 250.0], object_thickness_mm=[1.0, 3.0],
                        shape="sphere")
    with pytest.raises(ValueError, match=r"narrowest object is 8 mm across"):
        run_design_checks(4, 0, small)
    with pytest.raises(AssertionError, match="scored before"):  # the default task passed the check, then worked
        run_design_checks(4, 0, None)


@pytest.mark.slow
def test_bench_design_prints_figures(tmp_path, capsys):
    from agents.bench.design import main as bench

    assert bench(["--objects", "4", "--repeats", "1", "--no-old", "--json", str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    assert "one design evaluation" in out and "CartPoleVectorEnv" in out
    res = json.loads((tmp_path / "b.json").read_text())
    assert res["evaluation"]["median_s"] > 0 and res["search"]["batched, as the command runs"]["seconds"] > 0


@pytest.mark.slow  # issue 37: every trial a new design, --trials the budget whatever --jobs is, duplicates unrun
def test_trials_is_the_budget_and_every_trial_a_new_design(tmp_path, capsys, four_cores):
    one = tmp_path / "one"
    assert main(["--trials", "1", "--jobs", "3", "--out", str(one), *SMALL]) == 0  # Table 1 only, once
    assert json.loads((one / "design.json").read_text())["trials"] == 1
    out = tmp_path / "budget"
    assert main(["--trials", "3", "--jobs", "2", "--out", str(out), *SMALL]) == 0
    res = json.loads((out / "design.json").read_text())
    assert (res["trials"], res["scored"], res["distinct"], res["duplicates"]) == (3, 3, 3, 0)
    assert "3 designs scored, 3 distinct, in 3 trials" in capsys.readouterr().out
    study = optuna.load_study(study_name="design-kitchen", storage=f"sqlite:///{out / 'study.db'}")
    again = next(t for t in study.trials if not t.user_attrs.get("table1"))
    study.enqueue_trial(dict(again.params))  # a design the study has scored: pruned unrun, and not counted
    # resumed (one process): a sampler seeded afresh, not the first run's sequence again
    assert main(["--trials", "4", "--out", str(out), *SMALL]) == 0
    res = json.loads((out / "design.json").read_text())
    assert (res["trials"], res["scored"], res["distinct"], res["duplicates"]) == (5, 4, 4, 1)
    dup = [t for t in optuna.load_study(study_name="design-kitchen", storage=f"sqlite:///{out / 'study.db'}").trials
           if "duplicate_of" in t.user_attrs]
    assert [(t.state.name, t.user_attrs["duplicate_of"]) for t in dup] == [("PRUNED", again.number)]
    assert "(1 duplicate design pruned unrun)" in capsys.readouterr().out


def test_one_trial_is_one_trial_whatever_the_jobs():
    from agents.design.study import shares

    assert shares(1, 1, 3) == [1, 0, 0]  # --trials 1 --jobs 3: Table 1 only, one worker
    assert shares(6, 1, 2) == [3, 3] and sum(shares(7, 2, 3)) == 7
    assert shares(3, 3, 2) == [3, 0] and shares(5, 3, 3) == [3, 1, 1]  # worker 0 runs what waits


def test_each_worker_and_each_resumption_samples_its_own_designs(tmp_path):
    from agents.design.study import StudySpec, sampler_seed

    spec = StudySpec(out=tmp_path)
    seeds = {sampler_seed(spec, w, n) for w in (0, 1, 2, "host:123") for n in (0, 1, 5)}
    assert len(seeds) == 12
    assert sampler_seed(spec, 1, 5) == sampler_seed(StudySpec(out=tmp_path / "x"), 1, 5)  # reproducible


@pytest.mark.parametrize("cores, memory, jobs, match", [
    (2, None, 3, r"--jobs must be at most 2 on this machine \(2 usable core\(s\)\), got 3"),
    (2, None, 1024, "at most 2 on this machine"),
    (8, 3 << 29, 2, r"--jobs must be at most 1 on this machine \(8 usable core\(s\), 1.5 GiB of memory"),
])
def test_jobs_beyond_the_machine_are_refused_by_name(tmp_path, monkeypatch, cores, memory, jobs, match):
    import os

    import agents.common.workers

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    monkeypatch.setattr(agents.common.workers, "available_memory", lambda: memory, raising=False)
    with pytest.raises(SystemExit, match=match):
        main(["--jobs", str(jobs), "--report", "--out", str(tmp_path / "o"), "--quiet"])
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
