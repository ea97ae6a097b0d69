"""The batched evaluation (agents.evaluation.batch) against the single env, episode by episode."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v1)
from agents.evaluation.batch import duration_invariance, episode_seeds, ramp_actions, ramp_grid
from agents.evaluation.episodes import run_episode
from agents.policies.scripted import LinearRamp
from agents.search.ramp import search_ramp
from pneunet_env import load_config

CFG = load_config()


def test_ramp_grid_is_the_single_env_object_for_object():
    seeds = episode_seeds(6)
    targets = [0.3, 0.565]
    g = ramp_grid(CFG, seeds, targets, 20)
    env = gym.make("PneuNetGrasp-v1", config=CFG)
    for i, t in enumerate(targets):
        for m, s in enumerate(seeds):
            r = run_episode(env, LinearRamp(t, 20, CFG), int(s))
            assert (g.outcome.success[i, m], g.outcome.damaged[i, m], g.outcome.dropped[i, m]) == \
                (r["success"], r["damaged"], r["dropped"]), (t, s)
            assert g.outcome.returns[i, m] == pytest.approx(r["return"], abs=1e-12)
            assert g.outcome.steps[i, m] == r["steps"]
            assert g.outcome.stiffness[m] == pytest.approx(r["stiffness"], rel=1e-12)
    env.close()
    assert g.outcome.classes[:1][0] in g.outcome.class_names


def test_ramp_actions_are_linear_ramps_bit_for_bit():
    obs = np.random.default_rng(0).uniform(0, 1, (50, 1)).astype(np.float32)
    t = np.linspace(0.05, 1.0, 50)
    act = ramp_actions(t, 7, CFG)(obs)
    ref = np.concatenate([LinearRamp(tt, 7, CFG)(o) for tt, o in zip(t, obs, strict=True)])
    assert np.array_equal(act[:, 0], ref)


def test_grid_oracle_and_window():
    g = ramp_grid(CFG, episode_seeds(30), np.arange(1, 21) / 20, 20)
    assert (g.oracle() >= g.outcome.success.max(axis=0)).all()
    b = g.best()
    lo, hi = g.window(b)
    assert lo <= g.pressure_kpa[b] <= hi
    rates = g.rates()
    inside = (g.pressure_kpa >= lo) & (g.pressure_kpa <= hi)
    assert (rates[inside] >= rates[b] - 0.05 - 1e-12).all()


def test_durations_within_the_squeeze_phase_give_identical_outcomes():
    r = duration_invariance(CFG, episode_seeds(20), [0.4, 0.6, 0.8], (20, 1, 35, 50, 80))
    assert r["identical"][:4] == [True, True, True, True]
    assert r["identical"][4] is False  # 80 steps reach the target in the hold phase


def test_batched_search_equals_the_episode_loop():
    kw = dict(n_objects=10, seed=3, targets=[0.45, 0.6, 0.75], durations=[20], refine=0.0, progress=False)
    b1, c1 = search_ramp(CFG, "pneunet", **kw)
    b2, c2 = search_ramp(CFG, "pneunet", batched=False, **kw)
    assert (b1.target, b1.n_steps, b1.success_rate, b1.mean_return) == (b2.target, b2.n_steps, b2.success_rate,
                                                                         b2.mean_return)
    for x, y in zip(sorted(c1, key=lambda c: c.target), sorted(c2, key=lambda c: c.target), strict=True):
        assert np.array_equal(x.success, y.success)


@pytest.mark.parametrize("bad", [[], [0.0], [1.5], [float("nan")]])
def test_ramp_grid_refuses_bad_targets(bad):
    with pytest.raises(ValueError, match="targets"):
        ramp_grid(CFG, episode_seeds(2), bad)


@pytest.mark.parametrize("n, seed", [(0, 0), (1.5, 0), (3, -1)])
def test_episode_seeds_refuses_bad_values(n, seed):
    with pytest.raises(ValueError):
        episode_seeds(n, seed)


@pytest.mark.parametrize("spec", ["best-ramp", "oracle", "step:target_kpa=20",
                                  pytest.param("agents/models/ppo_kitchen.zip", marks=pytest.mark.slow)])
def test_batched_policies_are_the_episode_loop(spec):
    from agents.evaluation.batch import batchable, run_policy
    from agents.policies.registry import make_policy

    if spec.endswith(".zip"):
        pytest.importorskip("stable_baselines3")
    entry = make_policy(spec, CFG)
    assert batchable(entry)
    seeds = [int(s) for s in episode_seeds(10, held_out=True)]
    batched = run_policy(entry, CFG, seeds).episodes()
    env = entry.make_env(CFG)
    for s, b in zip(seeds, batched, strict=True):
        r = run_episode(env, entry.policy, s)
        assert {k: r[k] for k in b if k != "return"} == {k: b[k] for k in b if k != "return"}, (spec, s)
        assert b["return"] == pytest.approx(r["return"], abs=1e-12)
    env.close()
    assert not batchable(make_policy("rigid", CFG))


def test_evaluate_on_a_stiffness_grid_runs_batched_with_the_same_episodes():
    from agents.evaluation.episodes import episode_seed
    from agents.evaluation.evaluate import evaluate_policies
    from agents.policies.registry import make_policy
    from pneunet_env import PAPER_TASK

    cfg = load_config(**PAPER_TASK)
    entry = make_policy("best-ramp", cfg)
    grid = [3e-5, 1e-3]
    rows = evaluate_policies([entry], cfg, grid, episodes=2, progress=False)
    env = entry.make_env(cfg)
    for i, (k, row) in enumerate(zip(grid, rows, strict=True)):
        res = [run_episode(env, entry.policy, episode_seed(0, i, e), {"object_stiffness": k}) for e in range(2)]
        assert row["success_rate"] == np.mean([r["success"] for r in res])
        assert row["mean_return"] == pytest.approx(np.mean([r["return"] for r in res]), abs=1e-12)
        assert row["mean_peak_traction_kpa"] == pytest.approx(np.mean([r["peak_traction_kpa"] for r in res]),
                                                              rel=1e-12)
    env.close()
