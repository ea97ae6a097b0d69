"""``bench speed``'s single env with its resets (:mod:`pneunet_env.bench.episodes`): its figures and rows (no timing
thresholds: the ratio to CartPole-v1 is reported, never asserted)."""

from __future__ import annotations

import math

import pytest

from pneunet_env.bench import episodes, speed

KEYS = ("PneuNetGrasp-v1 random", "PneuNetGrasp-v1 ramp", "CartPole-v1 random")


@pytest.fixture(scope="module")
def small_run():
    return episodes.bench_single_with_resets(steps=600, rounds=2, resets=20, ramp=speed.ramp_policy())


def test_the_figures_count_steps_and_resets(small_run):
    res = small_run
    assert res["steps_per_workload"] == 600 and res["rounds"] == 2
    for key in KEYS:
        # the time per env-step with resets is at least the steps' own share; every workload ends episodes in 600
        # steps (CartPole's random ones after about 20, the ramp's grasps after at most 100)
        assert 0.0 < res["median_step_s"][key] < 1.0 and res["per_step_s"][key] > 0.0
        assert 0.0 < res["median_reset_s"][key] < 1.0 and 1.0 < res["mean_episode_steps"][key] <= 101.0
    assert res["mean_episode_steps"]["CartPole-v1 random"] < res["mean_episode_steps"]["PneuNetGrasp-v1 ramp"]
    for name in episodes.ENVS:
        assert 0.0 < res["median_seeded_reset_s"][name] < 1.0
    cart = res["per_step_s"]["CartPole-v1 random"]
    for workload in ("random", "ramp"):
        assert res["ratio"][workload] == pytest.approx(res["per_step_s"][f"PneuNetGrasp-v1 {workload}"] / cart)


def test_its_rows_are_printed_in_the_speed_table(small_run):
    lines = episodes.format_lines(small_run)
    assert lines[0].startswith("single env with its resets")
    for key in KEYS:
        row = next(line for line in lines if line.strip().startswith(key))
        assert row.rstrip().endswith("x") and "us" in row
    assert f"under {episodes.TARGETS['reset_max_us']:g} us" in lines[-1]
    assert speed.TARGETS["single_with_resets"] == episodes.TARGETS and math.isfinite(episodes.TARGETS["reset_max_us"])
