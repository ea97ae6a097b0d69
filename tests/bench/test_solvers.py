"""``pneunet-grasp bench solvers``: the solver study runs, and says what it must."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("mpmath")
pytest.importorskip("scipy")

from pneunet_env import ActuatorParams, solve_equilibrium  # noqa: E402
from pneunet_env.bench import solver_methods, solver_study, solvers  # noqa: E402
from pneunet_env.bench.models import AUTO_TOLERANCE  # noqa: E402
from pneunet_env.cli import main  # noqa: E402
from pneunet_env.physics.solver import ACCEPT_GTOL  # noqa: E402

OUTPUTS = ("solvers.json", "solvers_details.json", "speed_accuracy.png", "stability_map.png", "step_size.png")
FAILURE_TEXTS = set(solver_methods.FAILURE_TEXT.values())


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One ``bench solvers --quick`` run through the console entry point, shared by the tests below."""
    out = tmp_path_factory.mktemp("bench_solvers")
    rc = main(["bench", "solvers", "--quick", "--out", str(out), "--no-progress"])
    records = json.loads((out / "solvers.json").read_text())
    details = json.loads((out / "solvers_details.json").read_text())
    return rc, out, records, details


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_quick_run_writes_its_outputs(quick_run):
    rc, out, records, _ = quick_run
    assert rc == 0
    for name in OUTPUTS:
        assert (out / name).is_file(), name
    for name in OUTPUTS[2:]:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000, name
    assert isinstance(records, list) and records


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_records_have_the_documented_fields(quick_run):
    _, _, records, details = quick_run
    for r in records:
        assert {"method", "scene", "time_s", "error", "failure", "default", "max_gradient_norm",
                "min_hessian_eigenvalue"} <= set(r)
        assert r["time_s"] > 0.0 and math.isfinite(r["time_s"])
        assert r["error"] is None or r["error"] >= 0.0
        assert r["failure"] is None or r["failure"] in FAILURE_TEXTS
        assert isinstance(r["default"], bool)
    methods = {r["method"] for r in records}
    scenes = {r["scene"] for r in records}
    assert len(methods) >= 6 and len(scenes) >= 6
    assert len(records) == len(methods) * len(scenes)  # every method on every scene
    assert {r["method"] for r in records if r["default"]} == {"package"}
    assert {s["name"] for s in details["scenes"]} == scenes


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_default_solver_never_fails_and_is_accurate(quick_run):
    _, _, records, details = quick_run
    default = [r for r in records if r["default"]]
    assert len(default) == len(details["scenes"])
    for r in default:
        assert r["failure"] is None, r
        assert r["error"] is not None and r["error"] <= 1e-9, r
    # ... also on every cell of the stability map, and at every pressure increment of the step-size study.
    cells = [o for row in details["map"]["outcomes"]["package"] for o in row]
    assert not set(cells) & set(solvers.FAILURES)
    for row in details["step_size"]["rows"]:
        if row["method"] == "package":
            assert row["failures"] == 0 and row["error"] <= 1e-9 and row["loop"] == "captured", row


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_hand_scale_scenes_are_solved_like_the_others(quick_run):
    # the catalogue's stiffest (k~ ~ 40 at w kappa_obj = 0.33, firm silicone) and softest corners, through the same
    # paths as every scene: every package answer a converged minimum within 1e-9 of the 30-digit reference
    _, _, records, details = quick_run
    scenes = {s["name"]: s for s in details["scenes"]}
    corners = solvers.catalogue_corners()
    for name, corner in (("hand stiff", corners["stiff"]), ("hand soft", corners["soft"])):
        assert scenes[name]["object_stiffness"] == pytest.approx(corner.object_stiffness)
        assert scenes[name]["object_curvature"] == pytest.approx(corner.object_curvature)
        r = next(r for r in records if r["scene"] == name and r["method"] == "package")
        assert r["failure"] is None and r["outcomes"] == {"correct": r["solves"]}, r
        assert r["error"] <= 1e-9, r
        assert r["max_gradient_norm"] <= ACCEPT_GTOL and r["min_hessian_eigenvalue"] > 0.0, r
    assert scenes["hand stiff"]["object_stiffness"] > 30.0  # far beyond the paper ring's k~ <= 0.1
    # ... and the plain methods still break there (plain Newton leaves the domain once the stiff contact starts)
    newton = next(r for r in records if r["scene"] == "hand stiff" and r["method"] == "plain Newton")
    assert newton["failure"] is not None


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_other_methods_fail_somewhere_and_it_is_recorded(quick_run):
    _, _, records, details = quick_run
    failed = [r for r in records if r["failure"] is not None]
    assert failed and all(not r["default"] for r in failed)
    assert {r["method"] for r in failed} >= {"plain Newton"}
    for r in failed:
        assert r["failed_solves"] >= 1 and r["first_failure_pressure"] is not None
    # Plain Newton has no safeguard: it leaves the domain (contact onset, the balloon, the Gent barrier).
    newton = [r for r in records if r["method"] == "plain Newton"]
    assert any(r["outcomes"].get("left the domain", 0) for r in newton)
    # The map sees failures too, of more than one kind.
    kinds = {o for name, grid in details["map"]["outcomes"].items() if name != "package" for row in grid for o in row}
    assert len(kinds & set(solvers.FAILURES)) >= 2


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_auto_model_records_stay_within_its_bound(quick_run):
    _, _, records, details = quick_run
    auto = [r for r in records if r["method"] == "auto model"]
    assert len(auto) == len(details["scenes"])
    for r in auto:
        assert r["failure"] is None and r["error"] <= AUTO_TOLERANCE, r
    sweep = details["auto"]["sweep"]
    assert [row["tolerance"] for row in sweep] == sorted(row["tolerance"] for row in sweep)
    for row in sweep:
        assert row["max_error"] <= row["tolerance"]
        assert 0.0 <= row["linear_fraction"] <= 1.0
    # At its own tolerance, auto did answer with the linear model somewhere (else nothing was measured).
    assert next(row for row in sweep if row["tolerance"] == AUTO_TOLERANCE)["linear_fraction"] > 0.0
    assert any(r["outcomes"].get("model error", 0) for r in auto)
    # The linear model's error grows like c p^2 (the study fits c; the bound's justification uses it).
    assert 0.05 < details["auto"]["linear_error_coefficient"] < 0.2


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_map_and_step_size_cover_every_method(quick_run):
    _, _, records, details = quick_run
    methods = list(dict.fromkeys(r["method"] for r in records))
    mp = details["map"]
    assert list(mp["outcomes"]) == methods
    for grid in mp["outcomes"].values():
        assert np.shape(grid) == (len(mp["stiffnesses"]), len(mp["pressures"]))
        assert {o for row in grid for o in row} <= set(solvers.OUTCOMES)
    st = details["step_size"]
    p_down, p_up = st["fold_window"]
    assert 0.55 < p_down < p_up < 0.75  # the k~ = 1e-4 hysteresis loop
    assert {(r["method"], r["increment"]) for r in st["rows"]} == {
        (m, dp) for m in methods for dp in {r["increment"] for r in st["rows"]}}
    assert {r["loop"] for r in st["rows"]} <= {"captured", "missed", "unresolved"}
    assert any(r["loop"] == "missed" for r in st["rows"])


# ------------------------------------------------------------------------------- the classifier itself
P = ActuatorParams()
SADDLE = (0.04478907, 0.77937997)  # between the two branches of k~ = 1e-4 at p~ = 0.65 (plain Newton finds it)


def _at(p, k, x0=None):
    return np.array(solve_equilibrium(p, k, 0.02, P, initial=x0).state)


def test_classify_names_each_outcome():
    p, k = 0.65, 1e-4
    low = _at(p, k)
    high = np.array(solve_equilibrium(p, k, 0.02, P, initial=solve_equilibrium(1.0, k, 0.02, P)).state)
    assert solvers.classify(low, low, p, k, 0.02, P)[0] == "correct"
    assert solvers.classify(high, low, p, k, 0.02, P)[0] == "wrong branch"
    assert solvers.classify(np.array(SADDLE), low, p, k, 0.02, P)[0] == "saddle/maximum"
    assert solvers.classify(low + [0.0, 1e-3], low, p, k, 0.02, P)[0] == "no convergence"
    assert solvers.classify([math.nan, 0.1], low, p, k, 0.02, P)[0] == "NaN"
    assert solvers.classify([-0.1, 0.1], low, p, k, 0.02, P)[0] == "left the domain"
    assert solvers.classify(low + [0.0, 1e-3], low, p, k, 0.02, P, kind="model")[0] == "model error"
    out, err = solvers.classify(low + [2e-7, 0.0], low, p, k, 0.02, P)
    assert out == "correct" and err == pytest.approx(2e-7)


def test_a_method_that_raises_is_a_recorded_nan_not_a_crash():
    def broken(energy, x):
        raise FloatingPointError("boom")

    method = solvers.NaiveMethod("broken", "raises", broken)
    run = solvers.solve_path(method, (0.1, 0.2), 0.0, 0.02, P)
    assert np.isnan(run.states).all() and all(m.startswith("raised FloatingPointError") for m in run.messages)


def test_plain_newton_fails_at_contact_onset():
    """The Winkler term's Hessian jumps at contact: an unguarded Newton step from just out of contact overshoots."""
    method = next(m for m in solvers.make_methods() if m.name == "plain Newton")
    ps = solver_methods.ramp(0.5, 0.1)
    ref = solvers.reference_states(ps, 1e-2, 0.02, P)
    run = solvers.solve_path(method, ps, 1e-2, 0.02, P)
    outcomes = [solvers.classify(run.states[i], ref[i], p, 1e-2, 0.02, P)[0] for i, p in enumerate(ps)]
    assert outcomes[:2] == ["correct", "correct"]  # before contact (kappa~ < 0.02 up to p~ ~ 0.27)
    assert set(outcomes[2:]) & set(solvers.FAILURES)


def test_anchored_ramp_always_holds_the_anchor():
    for dp in (0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4):
        ps = solver_study.anchored_ramp(0.639, 1.2, dp)
        assert 0.639 in ps and max(ps) <= 1.2 and min(ps) > 0.0
        n = (len(ps) + 1) // 2
        assert np.all(np.diff(ps[:n]) > 0) and np.all(np.diff(ps[n - 1:]) < 0)


def test_hand_scale_scenes_are_the_catalogues_extreme_corners():
    """The study's hand-scale scenes sit at the largest and the smallest k~ of the catalogue's in-model classes."""
    from pneunet_env.catalogue import load_catalogue, stiffness_range

    inside = [c for c in load_catalogue().values() if c.in_annulus_model]
    k_max = max(stiffness_range(c)[1] for c in inside)
    k_min = min(stiffness_range(c)[0] for c in inside)
    scenes = {s.name: s for s in solvers.make_scenes(quick=True)}
    stiff, soft = scenes["hand stiff"], scenes["hand soft"]
    assert stiff.object_stiffness == pytest.approx(k_max) and soft.object_stiffness == pytest.approx(k_min)
    corners = solvers.catalogue_corners()
    assert stiff.object_curvature == pytest.approx(5.0 / corners["stiff"].radius_mm)
    assert soft.object_curvature == pytest.approx(5.0 / corners["soft"].radius_mm)
    for scene in (stiff, soft):  # the environment's episode: up to p~ = 1.2 (60 kPa) and back
        assert max(scene.pressures) == pytest.approx(1.2) and scene.pressures[-1] < scene.pressures[-2]


def test_package_solver_on_the_stiffest_catalogue_corner_matches_the_reference():
    """k~ ~ 40 at w kappa_obj = 0.33 (firm silicone; contact ratio ~3e3): the path the study runs, every answer a
    converged minimum, all within 1e-9 of the 30-digit reference."""
    scene = next(s for s in solvers.make_scenes(quick=True) if s.name == "hand stiff")
    k, c = scene.object_stiffness, scene.object_curvature
    ref = solvers.reference_states(scene.pressures, k, c, scene.params)
    run = solvers.solve_path(solvers.PackageMethod("package", "package"), scene.pressures, k, c, scene.params)
    outcomes = [solvers.classify(run.states[i], ref[i], p, k, c, scene.params) for i, p in enumerate(scene.pressures)]
    assert {o for o, _ in outcomes} == {"correct"}
    assert max(e for _, e in outcomes) <= 1e-9
    grad, eig = solver_study.stationarity(run.states, scene)
    assert grad <= ACCEPT_GTOL and eig > 0.0
    assert abs(ref[len(ref) // 2, 0] - c) < 0.01 * c  # at p~ = 1.2 the curvature is held within 1 % of the object's
