"""The fused numba step is :func:`pneunet_env.task.step`, bit for bit (every field of the returned Step)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401
from pneunet_env import task
from pneunet_env.fused import HAVE_FUSED, fused_step

pytestmark = pytest.mark.skipif(not HAVE_FUSED, reason="the fused step needs numba")


def _fields(record, prefix=""):
    items = (record._asdict().items() if hasattr(record, "_asdict")
             else ((f.name, getattr(record, f.name)) for f in dataclasses.fields(record)))
    out = {}
    for name, v in items:
        if hasattr(v, "_asdict") or dataclasses.is_dataclass(v):
            out.update(_fields(v, f"{prefix}{name}."))
        else:
            out[prefix + name] = np.asarray(v)
    return out


@pytest.mark.parametrize("env_id,overrides", [
    ("PneuNetGrasp-v0", {}),
    pytest.param("PneuNetGrasp-Paper-v0", {"observe_volume": True}, marks=pytest.mark.slow),
])
def test_fused_step_equals_the_array_step(env_id, overrides):
    n = 256
    env = gym.make_vec(env_id, num_envs=n, backend="numba", fused=False, **overrides).unwrapped
    env.reset(seed=4)
    state, params = env.state, env._params
    rng = np.random.default_rng(0)
    failed_or_ended = 0
    for t in range(30):
        a = rng.uniform(-1.5, 2.5, n)  # clipped actions, loading and unloading
        ref = task.step(state, a, params, env._contact)
        got = fused_step(state, a, params, parallel=bool(t % 2))
        f_ref, f_got = _fields(ref), _fields(got)
        assert f_ref.keys() == f_got.keys()
        for key, v in f_ref.items():
            w = f_got[key]
            assert v.dtype == w.dtype and v.shape == w.shape, key
            assert np.array_equal(v, w, equal_nan=v.dtype.kind == "f"), key
        failed_or_ended += int(np.sum(ref.terminated | ref.truncated))
        state = ref.state
    assert failed_or_ended > 0


def test_fused_is_the_numba_default_and_checked():
    assert gym.make_vec("PneuNetGrasp-v0", num_envs=2, backend="numba").unwrapped.fused
    assert not gym.make_vec("PneuNetGrasp-v0", num_envs=2, backend="numpy").unwrapped.fused
    with pytest.raises(ValueError, match="fused"):
        gym.make_vec("PneuNetGrasp-v0", num_envs=2, backend="numpy", fused=True)
    with pytest.raises(ValueError, match="fused"):
        gym.make_vec("PneuNetGrasp-v0", num_envs=2, backend="numba", fused="yes")
