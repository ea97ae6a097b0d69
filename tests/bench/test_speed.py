"""``pneunet-grasp bench speed --quick``: runs, prints its table, writes JSON and a PNG (no timing thresholds)."""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from pneunet_env.bench import speed  # noqa: E402
from pneunet_env.cli import main  # noqa: E402


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One ``bench speed --quick`` run through the console entry point, shared by the tests below."""
    out = tmp_path_factory.mktemp("bench_speed")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["bench", "speed", "--quick", "--out", str(out), "--no-progress"])
    return rc, out, buf.getvalue(), json.loads((out / "speed.json").read_text())


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_quick_run_prints_its_table_and_writes_json_and_png(quick_run):
    rc, out, text, _ = quick_run
    assert rc == 0
    for row in ("single env", "PneuNetGrasp-v1", "CartPole-v1", "ratio", "vector env", "CartPoleVectorEnv",
                "solve_equilibrium", "memory at N = 16,384", "accuracy over", "single env with its resets",
                "PneuNetGrasp-v1 random", "PneuNetGrasp-v1 ramp", "CartPole-v1 random"):
        assert row in text, row
    for n in speed.NUM_ENVS:
        assert any(line.split()[:1] == [str(n)] for line in text.splitlines()), n
    png = (out / "speed.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_json_holds_every_figure(quick_run):
    _, _, _, res = quick_run
    single = res["single_env"]
    for name in ("PneuNetGrasp-v1", "CartPole-v1"):
        assert 0.0 < single["median_step_s"][name] < 1.0
    assert single["ratio"] == pytest.approx(single["median_step_s"]["PneuNetGrasp-v1"]
                                            / single["median_step_s"]["CartPole-v1"])
    loop = res["single_env_with_resets"]  # the single env with its resets (issue 36): reported, never asserted
    cart = loop["per_step_s"]["CartPole-v1 random"]
    for workload in ("random", "ramp"):
        assert loop["ratio"][workload] == pytest.approx(loop["per_step_s"][f"PneuNetGrasp-v1 {workload}"] / cart)
    assert all(0.0 < t < 1.0 for t in loop["median_seeded_reset_s"].values())
    assert [r["num_envs"] for r in res["vector_env"]] == list(speed.NUM_ENVS)
    for r in res["vector_env"]:
        cp = r["steps_per_s"]["CartPole-v1"]
        for p in speed.POLICIES:
            pn = r["steps_per_s"][f"PneuNetGrasp-v1 {p}"]
            assert pn > 0 and cp > 0 and r["ratio"][p] == pytest.approx(pn / cp)
    s = res["solves"]
    assert s["solve_equilibrium_calls_per_s"] > 0 and s["step_state_calls_per_s"] > 0
    assert s["solve_batch_num_envs"] == 16384 and s["solve_batch_solves_per_s"] > 0
    mem = res["memory"]
    assert mem["num_envs"] == 16384 and 0 < mem["state_bytes_per_env"] <= mem["peak_bytes_per_env"]
    acc = res["accuracy"]
    # correctness, not speed: every solve of the run converged to the solver's tolerance
    assert acc["solves"] > 10_000 and acc["converged_fraction"] == 1.0 and acc["nan_gradient_norms"] == 0
    assert 0.0 <= acc["worst_gradient_norm"] <= 1e-10
    assert res["targets"] == speed.TARGETS and math.isfinite(res["wall_s"])
    for r in res["vector_env"]:  # the work per env-step, over at least one whole episode even in a quick run
        for w in r["workload"].values():
            assert w["env_steps"] >= speed.WORKLOAD_MIN_STEPS * r["num_envs"] and w["energy_evaluations"] > 0
    last = res["vector_env"][-1]  # the free table's comparison (numba), at the largest N only, in the same rounds
    if res["backend"] == "numba":
        assert all("ratio_continuation" not in r for r in res["vector_env"][:-1])
        for p in speed.POLICIES:
            without = last["steps_per_s"][f"PneuNetGrasp-v1 {p}, {speed.CONTINUATION}"]
            assert last["ratio_continuation"][p] == pytest.approx(without / last["steps_per_s"]["CartPole-v1"])
            # the same steps, the table's work against the continuation's (counts, not times)
            w, wc = last["workload"][p], last["workload_continuation"][p]
            assert w["contact_share"] == wc["contact_share"] and w["energy_evaluations"] < wc["energy_evaluations"]
            # the step control "jump", likewise (the same steps: the same contact; its work measured, not asserted)
            jump = last["steps_per_s"][f"PneuNetGrasp-v1 {p}, {speed.JUMP}"]
            assert last[f"ratio_{speed.JUMP}"][p] == pytest.approx(jump / last["steps_per_s"]["CartPole-v1"])
            wj = last[f"workload_{speed.JUMP}"][p]
            assert wj["contact_share"] == pytest.approx(w["contact_share"], abs=1e-4) and wj["energy_evaluations"] > 0
        assert "the free actuator's table" in quick_run[2] and "the solver's step control" in quick_run[2]


@pytest.mark.slow  # the benchmark's end-to-end quick run (its fixture takes 5-11 s)
def test_table_and_plot_from_a_result(tmp_path, quick_run):
    _, _, text, res = quick_run
    assert speed.format_table(res) in text
    speed.plot(res, tmp_path / "again.png")
    assert (tmp_path / "again.png").stat().st_size > 20_000


def test_the_ramp_workload_is_the_shipped_best_ramp():
    """The benchmark's ramp is ``best-ramp`` (``agents/best_ramp.json``) written without ``agents``: same actions."""
    from agents.policies.registry import make_policy

    best = json.loads((Path(speed.__file__).resolve().parents[2] / "agents" / "best_ramp.json").read_text())
    assert (speed.RAMP_TARGET_KPA, speed.RAMP_STEPS) == (best["target_kpa"], best["n_steps"])
    shipped = make_policy("best-ramp").policy
    ours = speed.ramp_policy()
    obs = np.random.default_rng(0).uniform(0.0, 1.0, (512, 1)).astype(np.float32)
    obs[:8, 0] = [0.0, shipped.target, np.float32(shipped.target), 1.0, 0.5, 0.6, 0.1, 0.565]
    assert np.array_equal(ours(obs), shipped(obs))


def test_workload_counts_per_env_step():
    """The untimed pass's counts: contact and unchanged pressure under the ramp, episode ends, solver work."""
    import gymnasium as gym

    env = gym.make_vec("PneuNetGrasp-v1", num_envs=8, info_level="full", backend="numpy")
    obs, _ = env.reset(seed=0)
    infos: list = []
    speed._vector_run(env, [None] * 60, infos, speed.ramp_policy(), obs)
    env.close()
    w = speed._workload(infos, None)
    assert w["env_steps"] == 8 * 60
    assert 0.0 < w["contact_share"] <= 1.0 and 0.0 < w["unchanged_pressure_share"] < 1.0
    assert 0.0 < w["episode_end_share"] < 0.5  # 60 steps cover at least one episode end per env
    assert w["newton_iterations"] > 0 and w["substeps"] > 0.0  # (held steps take none)
    # the solver's own work counters (issue 23): every step evaluates the energy at least once per Newton iteration
    assert w["energy_evaluations"] >= w["newton_iterations"] and w["backtracks"] >= 0.0
    streamed = speed._Work(None)
    for info in infos:
        streamed.append(info)
    assert streamed.result() == w
