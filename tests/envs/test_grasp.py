"""PneuNetGrasp-v1 through the Gymnasium API: checkers, determinism, actions, physics, reward."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env

import pneunet_env  # noqa: F401  (registers the environment)
from agents.policies.scripted import LinearRamp, StepPolicy
from pneunet_env import task
from pneunet_env.envs.grasp import PneuNetGraspEnv


@pytest.fixture(autouse=True)
def _headless_matplotlib(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


def _episode(env, policy, seed=0, options=None, max_steps=10_000):
    obs, info = env.reset(seed=seed, options=options)
    traj = [(obs, 0.0, False, False, info)]
    for _ in range(max_steps):
        out = env.step(policy(obs))
        traj.append(out)
        obs = out[0]
        if out[2] or out[3]:
            break
    return traj


# ---- the checkers -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("render_mode", [None, "rgb_array", "human"])
def test_gymnasium_check_env(render_mode):
    if render_mode == "human":
        pytest.importorskip("matplotlib")
    env = gym.make("PneuNetGrasp-v1", render_mode=render_mode)
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


@pytest.mark.filterwarnings("ignore:.*Box observation space (minimum|maximum) value is:UserWarning")
def test_gymnasium_check_env_sighted_variant():
    env = gym.make("PneuNetGrasp-v1", observe_volume=True)
    check_env(env.unwrapped)
    env.close()


def test_sb3_check_env():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_checker.check_env(PneuNetGraspEnv(), warn=True)
    sb3_checker.check_env(PneuNetGraspEnv(observe_volume=True), warn=True)


def test_make_registers_spaces_and_time_limit():
    env = gym.make("PneuNetGrasp-v1")
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    assert env.observation_space == gym.spaces.Box(0.0, 1.0, (1,), np.float32)
    traj = _episode(env, StepPolicy(1.0), options={"object_stiffness": 0.05})
    assert len(traj) - 1 == env.unwrapped.config.episode_steps
    assert traj[-1][3] and not traj[-1][2]  # truncated, never terminated, at the time limit
    assert "is_success" in traj[-1][4] and all("is_success" not in t[4] for t in traj[:-1])
    env.close()


# ---- determinism and fresh arrays ----------------------------------------------------------------------------


def test_same_seed_same_episode():
    env = gym.make("PneuNetGrasp-v1")
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (100, 1)).astype(np.float32)

    def run(seed):
        obs, info = env.reset(seed=seed)
        out = [(obs, info)]
        for a in actions:
            o, r, te, tr, inf = env.step(a)
            out.append((o, r, te, tr, inf))
            if te or tr:
                break
        return out

    a, b, c = run(11), run(11), run(12)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            if isinstance(u, dict):
                assert u.keys() == v.keys()
                for k in u:
                    assert np.array_equal(u[k], v[k]), k
            else:
                assert np.array_equal(u, v)
    assert a[0][1]["object_stiffness"] != c[0][1]["object_stiffness"]
    env.close()


def test_returned_arrays_are_not_reused():
    env = gym.make("PneuNetGrasp-v1", observe_volume=True)
    obs0, info0 = env.reset(seed=0)
    keep = obs0.copy()
    obs1, *_ , info1 = env.step(np.array([1.0], np.float32))
    obs2, *_ , info2 = env.step(np.array([1.0], np.float32))
    assert obs1 is not obs2 and not np.shares_memory(obs1, obs2)
    assert not np.shares_memory(obs0, obs1)
    assert np.array_equal(obs0, keep)  # the reset observation was not overwritten
    obs1[:] = 123.0  # a caller mutating an observation does not touch the env
    obs3, *_ = env.step(np.array([0.0], np.float32))
    assert np.all(obs3 < 100.0)
    assert info1 is not info2
    for k, v in info1.items():
        if isinstance(v, np.ndarray):
            assert not np.shares_memory(v, info2[k]), k
    env.close()


# ---- actions ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_raise(bad):
    env = gym.make("PneuNetGrasp-v1")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([bad], np.float32))
    env.close()


def test_out_of_range_actions_are_clipped_and_reported():
    env = PneuNetGraspEnv()
    env.reset(seed=0)
    step = env.config.task.max_pressure_step_kpa
    _, _, _, _, info = env.step(np.array([5.0]))
    assert info["action_clipped"] and info["pressure_kpa"] == pytest.approx(step)
    _, _, _, _, info = env.step(np.array([0.5]))
    assert not info["action_clipped"] and info["pressure_kpa"] == pytest.approx(1.5 * step)
    _, _, _, _, info = env.step(np.array([-7.0]))
    assert info["action_clipped"] and info["pressure_kpa"] == pytest.approx(0.5 * step)
    _, _, _, _, info = env.step(np.array([-1.0]))
    assert not info["action_clipped"] and info["pressure_kpa"] == 0.0  # the pressure is kept >= 0
    with pytest.raises(ValueError, match="shape"):
        env.step(np.array([0.1, 0.2]))


def test_step_before_reset_raises():
    with pytest.raises(ResetNeeded, match="reset"):
        PneuNetGraspEnv().step(np.array([0.0]))


@pytest.mark.parametrize("env_id", ["PneuNetGrasp-v1", "RigidGrasp-v1"])
def test_step_after_the_episode_ended_asks_for_reset(env_id):
    env = gym.make(env_id).unwrapped  # unwrapped: no TimeLimit or order checks in front of it
    env.reset(seed=0, options={"object_stiffness": 1e-2})
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.array([1.0], np.float32))
        done = terminated or truncated
    with pytest.raises(ResetNeeded, match="call reset"):
        env.step(np.array([0.0], np.float32))  # no more success reward after the end
    env.reset(seed=1)
    env.step(np.array([0.0], np.float32))


@pytest.mark.parametrize(("action", "error", "match"), [
    ("1", TypeError, "str"),
    (np.array(["1"]), TypeError, "dtype <U1"),
    (np.array([1 + 1j]), TypeError, "complex"),
    (None, TypeError, "None"),
    (True, TypeError, "bool"),
    (10**400, ValueError, "too large"),
    ([0.1, 0.2], ValueError, "shape"),
    (np.array([[0.5]]), ValueError, "shape"),
    ({"a": 1}, TypeError, "dtype object"),
])
def test_bad_actions_are_named(action, error, match):
    env = PneuNetGraspEnv()
    env.reset(seed=0)
    with pytest.raises(error, match=match):
        env.step(action)
    for ok in (0.5, 1, np.float32(0.3), [0.2], np.array(0.1), np.array([0.4], np.float64)):
        env.step(ok)


# ---- many random steps --------------------------------------------------------------------------------------


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_20000_random_steps_converge_without_nan():
    env = gym.make("PneuNetGrasp-Paper-v0", info_level="full", observe_volume=True)
    env.action_space.seed(0)
    obs, info = env.reset(seed=0)
    episodes, snaps, contacts = 1, 0, 0
    for _ in range(20_000):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert info["solver_converged"] and not info["solver_failed"], info["solver_status"]
        assert info["gradient_norm"] <= 1e-10 and info["min_eigenvalue"] > 0.0
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        assert obs in env.observation_space
        snaps += info["snapped"]
        contacts += info["in_contact"]
        if terminated or truncated:
            obs, info = env.reset()
            episodes += 1
    numeric = [v for v in info.values() if isinstance(v, (float, np.floating))]
    assert all(np.isfinite(numeric))
    assert episodes > 100 and contacts > 1000  # the random walk did grasp things
    env.close()


# ---- the paper's regime switch, seen through the env ---------------------------------------------------------


def test_soft_object_traction_saturates_stiff_object_curvature_pinned():
    env = gym.make("PneuNetGrasp-Paper-v0", info_level="full", terminate_on_damage=False, terminate_on_slip=False)
    ramp = LinearRamp(1.0, 40)

    def path(k):
        traj = _episode(env, ramp, options={"object_stiffness": k})[1:41]
        info = [t[4] for t in traj]
        return (np.array([i["pressure"] for i in info]), np.array([i["curvature"] for i in info]),
                np.array([i["contact_force"] for i in info]))

    kc = 0.02
    p, kap, F = path(1e-5)  # soft: the actuator curls as if free, the traction saturates
    assert kap[-1] > 0.5
    late = p >= 0.6 * p[-1]
    assert F[late].max() - F[late].min() < 0.05 * F[-1]
    assert F.max() == pytest.approx(4.8e-4, rel=0.05)
    p, kap, F = path(1e-1)  # stiff: the curvature stays at the object's, the traction keeps rising
    contact = kap > kc
    assert contact.sum() > 25
    assert np.all(kap[contact] < 1.01 * kc)
    assert np.all(np.diff(F[contact]) > 0.0)
    assert F[-1] > 10 * F[contact][0]
    env.close()


# ---- reward bookkeeping ---------------------------------------------------------------------------------------


def test_crushing_schedule_gets_the_damage_penalty_and_terminates():
    env = gym.make("PneuNetGrasp-Paper-v0", info_level="full")
    cfg = env.unwrapped.config
    traj = _episode(env, StepPolicy(1.0), options={"object_stiffness": 1e-4})
    _, reward, terminated, truncated, info = traj[-1]
    assert terminated and not truncated
    assert info["damaged"] and info["crushed"] and info["indentation_mm"] > info["crush_indentation_mm"]
    assert reward == -cfg.task.penalty_damage
    assert info["is_success"] is False
    assert len(traj) - 1 < cfg.task.squeeze_steps  # crushed while squeezing
    env.close()


def test_too_gentle_schedule_gets_the_slip_penalty():
    env = gym.make("PneuNetGrasp-v1", info_level="full")
    cfg = env.unwrapped.config
    traj = _episode(env, LinearRamp(0.2, 20), options={"object_stiffness": 1e-1})
    _, reward, terminated, truncated, info = traj[-1]
    assert terminated and not truncated
    assert info["slipping"] and info["dropped"] and not info["damaged"]
    assert info["contact_force_kpa"] < info["grip_traction_kpa"]
    assert reward == -cfg.task.penalty_slip
    assert len(traj) - 1 == cfg.task.squeeze_steps + 1  # dropped on the first lifted step
    assert sum(t[1] for t in traj) == -cfg.task.penalty_slip
    env.close()


def test_firm_schedule_on_a_stiff_object_is_held():
    env = gym.make("PneuNetGrasp-v1", info_level="full")
    cfg = env.unwrapped.config
    traj = _episode(env, StepPolicy(1.0), options={"object_stiffness": 1e-1})
    _, _, terminated, truncated, info = traj[-1]
    assert truncated and not terminated and info["is_success"] is True
    assert info["contact_force_kpa"] >= info["grip_traction_kpa"] and not info["damaged"]
    total = sum(t[1] for t in traj)
    assert total == pytest.approx(cfg.task.hold_steps * cfg.task.reward_hold + cfg.task.reward_success)
    env.close()


# ---- reset options and info --------------------------------------------------------------------------------------


def test_reset_pins_and_info_units():
    env = gym.make("PneuNetGrasp-v1", info_level="full", terminate_on_damage=False, terminate_on_slip=False)
    _, info = env.reset(seed=0, options={"object_shear_modulus_kpa": 15.0, "object_thickness_mm": 8.0})
    assert info["object_shear_modulus_kpa"] == 15.0 and info["object_thickness_mm"] == 8.0
    assert info["pressure"] == 0.0 and info["curvature"] == 0.0 and not info["in_contact"]
    for _ in range(30):
        _, _, _, _, info = env.step(np.array([1.0]))
    cfg = env.unwrapped.config
    assert info["pressure_kpa"] == pytest.approx(info["pressure"] * cfg.actuator.shear_modulus_kpa)
    assert info["contact_force_kpa"] == pytest.approx(info["contact_force"] * cfg.actuator.shear_modulus_kpa)
    assert info["indentation_mm"] == pytest.approx(info["indentation"] * cfg.actuator.width_mm)
    assert info["curvature_per_m"] == pytest.approx(info["curvature"] / (cfg.actuator.width_mm * 1e-3))
    assert info["contact_force"] == pytest.approx(info["object_stiffness"] * info["indentation"])
    for key in ("pressure", "curvature", "side_strain", "contact_force", "indentation", "object_stiffness",
                "in_contact", "damaged", "slipping", "snapped", "solver_iterations", "solver_converged",
                "gradient_norm", "action_clipped"):
        assert key in info
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"stiffness": 1.0})
    env.close()


def test_free_actuator_episode():
    env = gym.make("PneuNetGrasp-v1", info_level="full")
    traj = _episode(env, StepPolicy(1.0), options={"object_stiffness": 0.0})
    info = traj[-1][4]
    assert info["dropped"] and not info["damaged"] and info["contact_force"] == 0.0 and info["indentation"] == 0.0
    env.close()


# ---- the scripted policies ----------------------------------------------------------------------------------------


def test_linear_ramp_reaches_its_target_in_n_steps_and_holds():
    env = PneuNetGraspEnv()
    ramp = LinearRamp.from_kpa(30.0, 20, env.config)
    obs, _ = env.reset(seed=0, options={"object_stiffness": 0.05})
    pressures = []
    for _ in range(30):
        a = ramp(obs)
        assert a.shape == (1,) and a.dtype == np.float32 and env.action_space.contains(a)
        obs, _, _, _, info = env.step(a)
        pressures.append(info["pressure_kpa"])
    np.testing.assert_allclose(pressures[:20], 1.5 * np.arange(1, 21), rtol=1e-5)
    np.testing.assert_allclose(pressures[20:], 30.0, rtol=1e-5)
    # a ramp steeper than the largest step is limited by it
    fast = LinearRamp(1.0, 5, env.config)
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(fast(obs))
    assert obs[0] == pytest.approx(env.config.task.max_pressure_step_kpa / env.config.task.max_pressure_kpa)


def test_step_policy_and_batched_predict():
    cfg = PneuNetGraspEnv().config
    pol = StepPolicy(0.5, cfg)
    obs = np.array([[0.0], [0.45], [0.5], [0.9]], np.float32)
    actions, state = pol.predict(obs)
    assert state is None and actions.shape == (4, 1) and actions.dtype == np.float32
    np.testing.assert_allclose(actions[:, 0], [1.0, 0.05 / 0.05, 0.0, -1.0], atol=1e-5)
    np.testing.assert_allclose(LinearRamp(0.5, 10, cfg)(obs)[:, 0], [1.0, 1.0, 0.0, -1.0], atol=1e-5)
    with pytest.raises(ValueError, match="target"):
        StepPolicy(1.5)
    with pytest.raises(ValueError, match="n_steps"):
        LinearRamp(0.5, 0)


def test_lean_info_keys_and_the_objects_constants_at_reset():
    env = gym.make("PneuNetGrasp-v1")
    _, info = env.reset(seed=3)
    assert set(info) == set(task.LEAN_KEYS) | set(task.OBJECT_KEYS)
    _, _, _, _, info = env.step(np.array([1.0], np.float32))
    assert set(info) == set(task.LEAN_KEYS)
    full = gym.make("PneuNetGrasp-v1", info_level="full")
    _, info_r = full.reset(seed=3)
    _, _, _, _, info_f = full.step(np.array([1.0], np.float32))
    assert set(info_f) == set(task.FULL_KEYS) and set(task.LEAN_KEYS) | set(task.OBJECT_KEYS) <= set(info_f)
    assert all(info_f[k] == info[k] for k in task.LEAN_KEYS)  # the lean keys are the full info's, unchanged
    with pytest.raises(ValueError, match="info_level"):
        gym.make("PneuNetGrasp-v1", info_level="everything")


# ---- one shell for the single envs ---------------------------------------------------------------------------


def test_single_envs_share_one_base_and_write_only_their_own_private_fields():
    """``PneuNetGraspEnv`` and ``RigidGraspEnv`` derive from one base (:mod:`pneunet_env.envs.base`), and no module of
    ``pneunet_env/envs`` assigns another object's private attribute (``env._state = ...``; the old
    ``grasp.single_env_step`` wrote the rigid env's)."""
    import ast
    from pathlib import Path

    from pneunet_env.envs.base import SingleGraspEnv
    from pneunet_env.envs.rigid import RigidGraspEnv

    assert issubclass(PneuNetGraspEnv, SingleGraspEnv) and issubclass(RigidGraspEnv, SingleGraspEnv)
    for cls in (PneuNetGraspEnv, RigidGraspEnv):  # the shared glue is written once, in the base
        assert "reset" not in vars(cls) and "step" not in vars(cls), cls.__name__
    bad = []
    for path in sorted(Path(pneunet_env.__file__).parent.joinpath("envs").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            targets = node.targets if isinstance(node, ast.Assign) else (
                [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else [])
            for t in targets:
                if (isinstance(t, ast.Attribute) and t.attr.startswith("_") and not t.attr.startswith("__")
                        and not (isinstance(t.value, ast.Name) and t.value.id in ("self", "cls"))):
                    bad.append(f"{path.name}:{node.lineno} {ast.unparse(t)}")
    assert not bad, f"private fields of other objects written: {bad}"


def test_rigid_env_is_stepped_by_the_shared_shell():
    """The rigid env through the base's reset and step: ResetNeeded before reset and past an episode's end, the jaw
    closure as the command (the task's command ceiling holds the travel in mm), and its render refusal named."""
    from pneunet_env.envs.rigid import RigidGraspEnv, jaw_task_params

    env = gym.make("RigidGrasp-v1").unwrapped
    with pytest.raises(ResetNeeded, match="call reset"):
        env.step(np.ones(1, np.float32))
    env.reset(seed=0)
    assert env.equilibrium is env.state.eq
    obs, *_ = env.step(np.ones(1, np.float32))
    assert env.state.command == pytest.approx(env.jaw_step_mm)
    assert obs[0] == pytest.approx(env.jaw_step_mm / env.jaw_travel_mm)
    tp = jaw_task_params(task.EnvParams.from_config(env.config), 12.0, 0.5).task
    assert (tp.pressure_max, tp.pressure_step) == (12.0, 0.5)
    for _ in range(200):
        *_, terminated, truncated, info = env.step(np.ones(1, np.float32))
        if terminated or truncated:
            break
    assert "is_success" in info
    with pytest.raises(ResetNeeded, match="ended"):
        env.step(np.ones(1, np.float32))
    with pytest.raises(ValueError, match="RigidGrasp-v1 does not render"):
        RigidGraspEnv(render_mode="rgb_array")
