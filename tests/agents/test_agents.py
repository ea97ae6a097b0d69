"""Scripted policies, the best-ramp file, the policy registry, the oracle, the rigid gripper, the search."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v1)
from agents.evaluation.episodes import run_episode
from agents.policies.oracle import Oracle, feasible_stiffness, plan_target
from agents.policies.registry import BEST_RAMP_PAPER_PATH, BEST_RIGID_PAPER_PATH, make_policy, parse_spec
from agents.policies.scripted import LinearRamp, StepPolicy, load_ramp, save_ramp
from agents.search.ramp import Candidate, best_candidate, search_ramp
from agents.search.sensitivity import strain_crush_fraction
from pneunet_env import PAPER_TASK, load_config
from pneunet_env.envs.rigid import RigidGraspEnv, default_jaw_travel_mm, jaw_indentation
from pneunet_env.objects import GraspObject
from pneunet_env.task import TaskParams, object_thresholds

CFG = load_config(**PAPER_TASK)  # these baselines' unit tests are on the paper's task (its 250 mm ring)
SPACE = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)


def _thresholds(k, config=CFG):
    obj = GraspObject.from_stiffness(k, thickness_mm=config.objects.object_thickness_mm[0],
                                     curvature_per_m=config.objects.object_curvature_per_m[0],
                                     density_kg_m3=config.objects.object_density_kg_m3[0],
                                     failure_strain=config.objects.object_failure_strain[0], scales=config.scales)
    return obj, object_thresholds(obj, TaskParams.from_config(config))


# ---- scripted policies: deterministic, in the action space --------------------------------------------------


@pytest.mark.parametrize("spec", ["ramp", "step", "best-ramp", "ramp:target_kpa=30,steps=7", "step:target=0.25",
                                  "rigid", "rigid:target_mm=4,steps=3"])
def test_scripted_policies_are_deterministic_and_in_the_action_space(spec):
    entry = make_policy(spec)
    rng = np.random.default_rng(1)
    obs = rng.random((200, 1)).astype(np.float32)
    a1 = entry.policy(obs)
    a2 = entry.policy(obs.copy())
    assert a1.dtype == np.float32 and a1.shape == (200, 1)
    np.testing.assert_array_equal(a1, a2)
    assert all(SPACE.contains(a) for a in a1)
    single = entry.policy(obs[3])
    assert single.shape == (1,) and SPACE.contains(single)
    np.testing.assert_array_equal(single, a1[3])
    pred, state = entry.policy.predict(obs[3])
    np.testing.assert_array_equal(pred, single)
    assert state is None


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
@pytest.mark.parametrize("spec", ["best-ramp", "step:target_kpa=20"])
def test_scripted_episodes_repeat_exactly(spec):
    entry = make_policy(spec)
    env = entry.make_env(CFG)
    r1 = run_episode(env, entry.policy, seed=5, record=True)
    r2 = run_episode(env, entry.policy, seed=5, record=True)
    assert r1 == r2
    env.close()


def test_linear_ramp_reaches_its_target_and_holds():
    env = gym.make("PneuNetGrasp-Paper-v0")
    pol = LinearRamp.from_kpa(50.0, 20)
    r = run_episode(env, pol, seed=0, options={"object_stiffness": 0.05}, record=True)
    p = np.array(r["commands"])
    np.testing.assert_allclose(p[1:21], 2.5 * np.arange(1, 21), rtol=1e-6)  # the ramp, 2.5 kPa per step
    np.testing.assert_allclose(p[20:], 50.0, rtol=1e-6)
    assert r["success"] and r["steps"] == 100  # a stiff object at 50 kPa: held (the grip needs about 42 kPa)
    env.close()


def test_step_policy_is_rate_limited_by_the_action():
    pol = StepPolicy(1.0)
    a = pol(np.array([0.0], np.float32))
    assert a[0] == 1.0  # one full step; the env turns it into 3 kPa


def test_best_ramp_loads_its_saved_parameters():
    data = json.loads(BEST_RAMP_PAPER_PATH.read_text())
    entry = make_policy("best-ramp", CFG)
    assert isinstance(entry.policy, LinearRamp)
    assert entry.policy.target == data["target"] and entry.policy.n_steps == data["n_steps"]
    assert data["target_kpa"] == pytest.approx(data["target"] * CFG.task.max_pressure_kpa)
    assert data["score"]["success_rate"] >= 0.0 and data["search"]["objects"] >= 1
    rigid_data = json.loads(BEST_RIGID_PAPER_PATH.read_text())
    r = make_policy("rigid", CFG)
    assert r.env_id == "RigidGrasp-v1" and r.command == "jaw"
    assert r.policy.target * default_jaw_travel_mm(CFG) == pytest.approx(rigid_data["target_mm"])


def test_save_and_load_ramp_round_trip(tmp_path):
    path = save_ramp(LinearRamp(0.42, 17), tmp_path / "r.json", note="x")
    pol = load_ramp(path)
    assert isinstance(pol, LinearRamp) and pol.target == 0.42 and pol.n_steps == 17
    pol = load_ramp(save_ramp(StepPolicy(0.3), tmp_path / "s.json"))
    assert isinstance(pol, StepPolicy) and pol.target == 0.3


@pytest.mark.parametrize("content, match", [(None, "cannot read"), ("{", "not JSON"), ("[1]", "JSON object"),
                                            ('{"kind": "spline"}', "unknown kind"),
                                            ('{"kind": "linear_ramp", "target": 0.5}', "n_steps"),
                                            ('{"kind": "step", "target": 1.5}', "target")])
def test_load_ramp_rejects_bad_files(tmp_path, content, match):
    path = tmp_path / "bad.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ValueError, match=match):
        load_ramp(path)


@pytest.mark.parametrize("spec, match", [("nope", "unknown policy"), ("ramp:target", "key=value"),
                                         ("ramp:speed=3", "unknown parameter"), ("ramp:steps=x", "not a number"),
                                         ("ramp:steps=2.5", "not an integer"),
                                         ("ramp:target=0.5,target_kpa=3", "not both"), ("missing.zip", "no such"),
                                         ("", "non-empty"), ("ramp:target=2", "target")])
def test_policy_specs_are_validated(spec, match):
    with pytest.raises(ValueError, match=match):
        make_policy(spec)


def test_parse_spec():
    assert parse_spec("ramp:target_kpa=30, steps=20") == ("ramp", {"target_kpa": "30", "steps": "20"})
    assert parse_spec("oracle") == ("oracle", {})


# ---- the oracle -----------------------------------------------------------------------------------------------


def test_feasible_stiffness_is_the_grip_over_the_crush_depth():
    # F_grip = rho g H / (2 mu_f) = 98.1 Pa -> F~ = 1.962e-3; crush depth H/w = 2: k~ = 9.81e-4 (docs/env.md)
    assert feasible_stiffness(CFG) == pytest.approx(1000 * 9.81 * 0.010 / (2 * 0.5) / 50e3 / 2.0, rel=1e-12)
    foam = CFG.replace(object_density_kg_m3=30.0)
    assert feasible_stiffness(foam) == pytest.approx(0.03 * feasible_stiffness(CFG), rel=1e-12)
    for config in (CFG, foam, CFG.replace(crush_fraction=7.5, friction_coefficient=1.0)):  # the env's own thresholds
        _, thr = _thresholds(1e-3, config)
        assert feasible_stiffness(config) == pytest.approx(thr.grip_traction / thr.crush_indentation, rel=1e-12)
    # a density range: the lightest objects set the bound
    assert feasible_stiffness(CFG.replace(object_density_kg_m3=[30.0, 1000.0])) == pytest.approx(
        feasible_stiffness(foam), rel=1e-12)
    # the weight rule on the ring: rho g pi (2 R H - H^2) b / (2 mu_f L_c b), L_c = 90 mm, over crush depth H/w = 2
    ring = 1000 * 9.81 * math.pi * (2 * 0.25 * 0.010 - 0.010 ** 2) / (2 * 0.5 * 0.090) / 50e3 / 2.0
    assert feasible_stiffness(CFG.replace(hold_rule="weight")) == pytest.approx(ring, rel=1e-12)  # 0.0168


@pytest.mark.parametrize("k, feasible", [(1e-5, False), (3e-4, False), (2e-3, True), (5e-2, True)])
def test_oracle_plan_matches_the_window(k, feasible):
    obj, thr = _thresholds(k)
    plan = plan_target(k, obj.curvature, thr.failure_traction, thr.crush_indentation, thr.grip_traction, CFG)
    assert plan["feasible"] is feasible
    assert 0.0 <= plan["target"] <= 1.0
    if feasible:
        assert plan["grip_ratio"] >= 1.0 and plan["damage_ratio"] <= 1.0


@pytest.mark.parametrize("k, success", [(2e-3, True), (5e-2, True), (3e-4, False)])
def test_oracle_episode_outcome_follows_its_plan(k, success):
    env = gym.make("PneuNetGrasp-Paper-v0")
    oracle = Oracle(CFG)
    r = run_episode(env, oracle, seed=0, options={"object_stiffness": k}, record=True)
    assert r["success"] is success
    assert r["commands"][-1] == pytest.approx(oracle.plan["pressure_kpa"], rel=1e-6) or not success
    a = oracle(np.array([[0.1], [0.9]], np.float32))
    assert all(SPACE.contains(x) for x in a)
    env.close()


def test_oracle_needs_the_reset_info():
    with pytest.raises(ValueError, match="reset"):
        Oracle().begin_episode({})
    with pytest.raises(RuntimeError, match="begin_episode"):
        Oracle()(np.zeros(1, np.float32))


# ---- the rigid gripper --------------------------------------------------------------------------------------


def test_rigid_env_passes_the_gymnasium_checker():
    check_env(RigidGraspEnv(), skip_render_check=True)


def test_rigid_traction_is_k_delta_and_the_same_objects():
    env = gym.make("RigidGrasp-v1", **PAPER_TASK)
    penv = gym.make("PneuNetGrasp-Paper-v0")
    for seed in range(5):
        _, info = env.reset(seed=seed)
        _, pinfo = penv.reset(seed=seed)
        k_kpa_per_mm = info["object_stiffness_kpa_per_mm"]  # the object's constants are in the reset info
        assert info["object_stiffness"] == pinfo["object_stiffness"]  # the same object for the same seed
        assert info["grip_traction_kpa"] == pinfo["grip_traction_kpa"]
        for _ in range(4):
            obs, _, _, _, info = env.step(np.array([0.5], np.float32))
        closure = 4 * 0.5 * env.unwrapped.jaw_step_mm
        assert info["jaw_closure_mm"] == pytest.approx(closure)
        assert obs[0] == pytest.approx(closure / env.unwrapped.jaw_travel_mm, rel=1e-6)
        assert info["indentation_mm"] == pytest.approx(closure)  # one object size: delta = closure
        assert info["contact_force_kpa"] == pytest.approx(k_kpa_per_mm * closure, rel=1e-12)
    env.close()
    penv.close()


def test_rigid_crushes_past_the_thickness_and_slips_below_the_grip():
    env = gym.make("RigidGrasp-v1", **PAPER_TASK)
    too_deep = LinearRamp.from_kpa(CFG.task.max_pressure_kpa, 20)  # the full 20 mm travel: past H = 10 mm
    r = run_episode(env, too_deep, seed=0, options={"object_stiffness": 1e-2})
    assert r["damaged"] and not r["success"]
    shallow = LinearRamp(0.05, 5)  # 1 mm: k~ = 1e-4 gives F = 1 Pa << 98 Pa
    r = run_episode(env, shallow, seed=0, options={"object_stiffness": 1e-4})
    assert r["dropped"] and r["steps"] == CFG.task.squeeze_steps + 1
    env.close()


def test_rigid_size_offset():
    assert jaw_indentation(5.0, 4.0, 4.0) == pytest.approx(5.0)
    # a larger object (smaller curvature) is met earlier: 1/3.6 - 1/4 m = 27.8 mm more indentation
    assert jaw_indentation(5.0, 3.6, 4.0) == pytest.approx(5.0 + 1e3 / 3.6 - 250.0)
    env = RigidGraspEnv(object_curvature_per_m=[3.6, 4.4], **PAPER_TASK)
    _, info = env.reset(seed=3)
    assert env.unwrapped.nominal_curvature_per_m == pytest.approx(4.0)
    assert np.isfinite(info["indentation_mm"])


@pytest.mark.parametrize("kwargs, match", [({"jaw_travel_mm": -1}, "jaw_travel_mm"),
                                           ({"jaw_travel_mm": 300.0}, "centre"),
                                           ({"jaw_step_mm": 50.0}, "exceeds"), ({"render_mode": "human"}, "render"),
                                           ({"bogus_key": 1}, "unknown config key")])
def test_rigid_env_validates(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RigidGraspEnv(**kwargs)


def test_rigid_env_rejects_nan_actions():
    env = RigidGraspEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan], np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2))


# ---- the search ---------------------------------------------------------------------------------------------


@pytest.mark.slow  # 11 s: a ramp search end to end; the README's test command runs it
def test_search_finds_the_best_of_a_small_grid():
    best, cands = search_ramp(CFG, "pneunet", n_objects=8, seed=0, targets=[0.3, 0.75, 1.0], durations=[20],
                              refine=0.0, progress=False)
    assert len(cands) == 3
    assert best.success_rate == max(c.success_rate for c in cands)
    assert best.target == 0.75  # 0.3 never holds the stiff objects; 1.0 also crushes some of the intermediate ones
    by_target = {c.target: c for c in cands}
    assert by_target[0.3].success_rate == 0.0
    assert by_target[0.75].success_rate >= by_target[1.0].success_rate


def test_best_candidate_breaks_ties_by_return_then_the_middle():
    z = np.zeros(1)
    mk = lambda t, s, r: Candidate(t, 20, s, 0, 0, r, z, z, z)  # noqa: E731
    cands = [mk(0.1, 0.5, 0.0), mk(0.2, 0.6, 0.1), mk(0.3, 0.6, 0.2), mk(0.4, 0.6, 0.2), mk(0.5, 0.6, 0.2),
             mk(0.6, 0.2, 1.0)]
    assert best_candidate(cands).target == 0.4


def test_search_summary_splits_by_the_mechanics_regime():
    # on hand-scale objects the paper ring's k~ thresholds would call everything stiff; the search's score is split
    # by the regime read off the mechanics (a 4.3 kPa gel of R = 40 mm yields, an apple of R = 17.6 mm blocks)
    cfg = load_config()
    k = np.array([1.56e-3, 55.0, 55.0])
    c = np.array([5.0 / 40.0, 5.0 / 17.6, 5.0 / 17.6])
    cand = Candidate(0.5, 20, 2 / 3, 0.0, 1 / 3, 0.0, np.array([False, True, True]), k, c)
    s = cand.summary(cfg)
    assert (s["objects_force"], s["objects_position"]) == (1, 2)
    assert s["success_rate_force"] == 0.0 and s["success_rate_position"] == 1.0


def test_strain_crush_fraction():
    assert strain_crush_fraction() == pytest.approx(0.3 / (0.010 * 4.0))
    assert math.isclose(strain_crush_fraction(CFG.replace(object_failure_strain=0.6)), 15.0)


def test_a_ramp_holds_the_pressure_exactly_once_at_its_target():
    """The observation is float32: the ramp sees its target only to within float32 rounding. Holding is an exact 0
    action, so the command stays put (it used to creep by ~5e-8 of full scale a step, re-solving every step)."""
    import gymnasium as gym

    from agents.policies.scripted import LinearRamp

    ramp = LinearRamp(0.565, 20)
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=4, info_level="full", backend="numpy")
    obs, _ = env.reset(seed=3)
    pressures, ended = [], np.zeros(4, bool)
    for _ in range(30):
        obs, _, term, trunc, info = env.step(ramp(obs))
        pressures.append(info["pressure"].copy())
        ended |= term | trunc
    env.close()
    held = np.array(pressures[21:])[:, ~ended]  # the episodes still running: at their target since step 20
    assert held.shape[1] >= 2 and np.all(held == held[0]) and np.all(ramp(obs)[~ended] == 0.0)
