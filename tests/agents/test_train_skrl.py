"""skrl's PPO on the torch backend (``pneunet-grasp train-skrl``): the wrapper keeps tensors on the env's device,
and the setpoint regulator is the same formula on tensors. skrl is an optional extra, outside the default CI: the
skrl tests skip without it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pneunet_env.wrappers import setpoint_to_rate

torch = pytest.importorskip("torch")


def test_setpoint_regulator_is_the_same_on_tensors_and_arrays():
    rng = np.random.default_rng(0)
    u, p = rng.uniform(-1.5, 1.5, 64), rng.uniform(0.0, 1.0, 64)
    ref = setpoint_to_rate(u, p, 0.05)
    got = setpoint_to_rate(torch.from_numpy(u), torch.from_numpy(p), 0.05)
    assert isinstance(got, torch.Tensor) and got.dtype == torch.float32
    assert np.array_equal(ref, got.numpy())


def test_wrapper_passes_tensors_through():
    pytest.importorskip("skrl")
    import gymnasium as gym

    import pneunet_env  # noqa: F401
    from agents.training.skrl_ppo import TorchVecEnvWrapper

    env = TorchVecEnvWrapper(gym.make_vec("PneuNetGrasp-v1", num_envs=8, backend="torch"))
    obs, _ = env.reset()
    assert obs.shape == (8, 1) and env.num_envs == 8 and env.action_space.shape == (1,)
    obs2, rew, term, trunc, _ = env.step(torch.ones(8, 1))
    assert isinstance(obs2, torch.Tensor) and rew.shape == (8, 1) and rew.dtype == torch.float32
    assert term.shape == (8, 1) and trunc.dtype == torch.bool
    assert env.reset()[0] is obs2  # a vector env is reset once; afterwards reset returns the last observation


@pytest.mark.slow
def test_train_skrl_command_runs_and_writes_the_curve(tmp_path):
    pytest.importorskip("skrl")
    from pneunet_env.cli import main

    rc = main(["train-skrl", "--num-envs", "16", "--minutes", "0.05", "--eval-objects", "8", "--eval-every", "1",
               "--out", str(tmp_path)])
    assert rc == 0
    res = json.loads((tmp_path / "curve.json").read_text())
    assert res["curve"][0]["env_steps"] == 0 and res["curve"][-1]["env_steps"] > 0
    assert 0.0 <= res["best_ramp_success"] <= 1.0 and "skrl" in res["library"]


@pytest.mark.parametrize("args,match", [
    (["--num-envs", "0"], "num-envs"), (["--eval-objects", "-1"], "eval-objects"), (["--minutes", "nan"], "minutes"),
    (["--eval-every", "0"], "eval-every"), (["--initial-log-std", "inf"], "initial-log-std"),
])
def test_train_skrl_names_a_bad_argument_before_anything_runs(args, match, tmp_path):
    from pneunet_env.cli import main

    with pytest.raises(SystemExit, match=match):
        main(["train-skrl", *args, "--out", str(tmp_path)])
