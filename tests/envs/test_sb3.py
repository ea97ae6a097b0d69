"""SB3VecEnv: Stable-Baselines3's VecEnv contract over the batched env, its wrappers, and PPO/SAC training on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from stable_baselines3.common.vec_env import (  # noqa: E402
    DummyVecEnv,
    VecCheckNan,
    VecEnv,
    VecMonitor,
    VecNormalize,
)
from stable_baselines3.common.vec_env.util import dict_to_obs, obs_space_info  # noqa: E402

import pneunet_env  # noqa: E402, F401
from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv  # noqa: E402
from pneunet_env.envs.sb3 import SB3VecEnv  # noqa: E402

SHORT = dict(squeeze_steps=8, hold_steps=8, max_episode_steps=16)


def _same(a, b, where):
    if isinstance(a, (np.ndarray, float, np.floating)) and not isinstance(a, bool):
        np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-12, err_msg=where)
    else:
        assert a == b, (where, a, b)


@pytest.mark.parametrize("info_keys", ["all", ()])
def test_same_as_dummy_vec_env_of_single_envs(info_keys):
    """Obs, rewards, dones, terminal_observation, TimeLimit.truncated, is_success, reset_infos: DummyVecEnv's."""
    n = 5
    ref = DummyVecEnv([lambda: gym.make("PneuNetGrasp-v1", **SHORT) for _ in range(n)])
    ours = SB3VecEnv(num_envs=n, info_keys=info_keys, **SHORT)
    assert isinstance(ours, VecEnv) and ours.num_envs == n
    assert ours.observation_space == ref.observation_space and ours.action_space == ref.action_space
    assert ref.seed(11) == ours.seed(11) == list(range(11, 11 + n))
    np.testing.assert_allclose(ours.reset(), ref.reset(), rtol=1e-10)
    if info_keys == "all":
        for a, b in zip(ref.reset_infos, ours.reset_infos, strict=True):
            assert set(a) == set(b)
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(100):
        act = rng.uniform(-1.3, 1.3, (n, 1)).astype(np.float32)
        o1, r1, d1, i1 = ref.step(act)
        o2, r2, d2, i2 = ours.step(act)
        np.testing.assert_allclose(o2, o1, rtol=1e-10, atol=1e-12)
        assert r2.dtype == r1.dtype and d2.dtype == d1.dtype
        np.testing.assert_allclose(r2, r1, rtol=1e-6)
        np.testing.assert_array_equal(d2, d1)
        for i, (a, b) in enumerate(zip(i1, i2, strict=True)):
            keys = set(a) if info_keys == "all" else set(a) & {"TimeLimit.truncated", "terminal_observation",
                                                                 "is_success"}
            assert set(b) == keys, (t, i, set(b) ^ keys)
            for k in keys:
                _same(a[k], b[k], f"t={t} env {i} {k}")
        ends += int(d1.sum())
        if info_keys == "all":
            for a, b in zip(ref.reset_infos, ours.reset_infos, strict=True):
                assert set(a) == set(b)
                for k in a:
                    _same(a[k], b[k], f"t={t} reset_info {k}")
    assert ends >= 2 * n


def test_vec_env_api():
    n = 3
    venv = SB3VecEnv(num_envs=n, render_mode="rgb_array")
    keys, shapes, dtypes = obs_space_info(venv.observation_space)
    assert keys == [None] and shapes == {None: (1,)} and dtypes == {None: np.float32}
    obs = venv.reset()
    assert obs.shape == (n, 1) and obs.dtype == np.float32
    assert np.array_equal(dict_to_obs(venv.observation_space, {None: obs}), obs)
    assert venv.get_attr("render_mode") == ["rgb_array"] * n and venv.render_mode == "rgb_array"
    assert venv.get_attr("num_envs", indices=[0, 2]) == [n, n]
    assert venv.has_attr("config") and not venv.has_attr("no_such_attribute")
    assert venv.env_method("state_nbytes", indices=1) == [venv.vector_env.state_nbytes()]
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * n
    venv.set_attr("backend", "numpy")
    assert venv.vector_env.backend == "numpy"
    with pytest.raises(ValueError, match="share one batched env"):
        venv.set_attr("backend", "numba", indices=[0])
    with pytest.raises(IndexError):
        venv.get_attr("num_envs", indices=[n])
    image = venv.render("rgb_array")
    assert image.ndim == 3 and image.shape[2] == 3 and image.shape[0] >= 360
    venv.set_options({"object_stiffness": 1e-3})
    venv.reset()
    assert np.all(venv.vector_env.objects.stiffness == 1e-3)
    venv.set_options([{"object_stiffness": k} for k in (1e-5, 1e-4, 1e-3)])
    venv.reset()
    np.testing.assert_array_equal(venv.vector_env.objects.stiffness, [1e-5, 1e-4, 1e-3])
    venv.close()


def test_rejects_a_next_step_vector_env_and_bad_arguments():
    sync = gym.make_vec("PneuNetGrasp-v1", num_envs=2, vectorization_mode="sync")  # NEXT_STEP
    with pytest.raises(ValueError, match="SAME_STEP"):
        SB3VecEnv(sync)
    with pytest.raises(ValueError, match="num_envs"):
        SB3VecEnv(PneuNetGraspVectorEnv(2), num_envs=3)
    with pytest.raises(ValueError, match="info_keys"):
        SB3VecEnv(num_envs=2, info_keys="contact_force")
    venv = SB3VecEnv(num_envs=2, info_keys=("no_such_key",))
    with pytest.raises(KeyError, match="no_such_key"):
        venv.reset()


def test_sb3_wrappers_on_it():
    n = 4
    venv = VecNormalize(VecMonitor(VecCheckNan(SB3VecEnv(num_envs=n, **SHORT), raise_exception=True)))
    venv.seed(0)
    venv.reset()
    episodes = []
    rewards = np.zeros(n)
    for _ in range(50):
        _, _, dones, infos = venv.step(np.random.default_rng(1).uniform(-1, 1, (n, 1)).astype(np.float32))
        rewards += venv.get_original_reward()
        for i in np.flatnonzero(dones):
            ep = infos[i]["episode"]
            assert ep["r"] == pytest.approx(rewards[i], abs=1e-5) and ep["l"] <= 16
            assert "terminal_observation" in infos[i] and "is_success" in infos[i]
            episodes.append(ep)
            rewards[i] = 0.0
    assert len(episodes) >= n
    with pytest.raises(ValueError, match="nan"):
        venv.step(np.full((n, 1), np.nan, np.float32))  # VecCheckNan catches a NaN action first ...
    bare = SB3VecEnv(num_envs=n)
    bare.reset()
    with pytest.raises(ValueError, match=r"actions\[0\] must be finite"):
        bare.step(np.full((n, 1), np.nan, np.float32))  # ... and the env itself names it


def test_ppo_trains_a_few_thousand_steps_and_eval_callback_reads_success(tmp_path):
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import EvalCallback

    from agents.training.train import no_folder_logger

    venv = VecMonitor(SB3VecEnv(num_envs=16))
    eval_env = VecMonitor(SB3VecEnv(num_envs=4))
    model = PPO("MlpPolicy", venv, n_steps=128, batch_size=512, n_epochs=2, seed=0, device="cpu", verbose=0)
    model.set_logger(no_folder_logger())  # else learn() leaves an empty $TMPDIR/SB3-<date> folder
    before = model.policy.state_dict()["action_net.weight"].clone()
    callback = EvalCallback(eval_env, n_eval_episodes=4, eval_freq=128, log_path=str(tmp_path), verbose=0)
    model.learn(4096, callback=callback)
    assert model.num_timesteps >= 4096
    assert len(model.ep_info_buffer) > 0  # episodes (100 steps) were completed and recorded by VecMonitor
    assert not np.array_equal(before.numpy(), model.policy.state_dict()["action_net.weight"].numpy())
    assert len(callback.evaluations_successes) >= 1 and len(callback.evaluations_successes[0]) == 4
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (16, 1) and np.all(np.isfinite(action))


def test_sac_runs_on_it():
    from stable_baselines3 import SAC

    from agents.training.train import no_folder_logger

    venv = SB3VecEnv(num_envs=4)
    model = SAC("MlpPolicy", venv, learning_starts=64, batch_size=64, train_freq=8, gradient_steps=1, seed=0,
                device="cpu", verbose=0, policy_kwargs={"net_arch": [32, 32]})
    model.set_logger(no_folder_logger())
    model.learn(400)
    assert model.num_timesteps >= 400 and model.replay_buffer.size() > 0
