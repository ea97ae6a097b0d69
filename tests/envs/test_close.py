"""A closed env is closed (issue 37): ``step``, ``reset`` (and the single env's ``render``) after ``close()`` raise
Gymnasium's ``ClosedEnvironmentError``, as Gymnasium's ``AsyncVectorEnv`` does; ``close()`` again does nothing.

Before: ``step()`` after ``close()`` was accepted, and so was ``reset()``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ClosedEnvironmentError

import pneunet_env  # noqa: F401  (registers the ids)
from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv
from pneunet_env.envs.rigid import RigidGraspEnv

MAKERS = {
    "single": lambda: gym.make("PneuNetGrasp-v1"),
    "single, rgb_array": lambda: gym.make("PneuNetGrasp-v1", render_mode="rgb_array"),
    "rigid": lambda: RigidGraspEnv(),
    "vector": lambda: PneuNetGraspVectorEnv(num_envs=2),
    "vector, numpy": lambda: PneuNetGraspVectorEnv(num_envs=2, backend="numpy"),
    "make_vec": lambda: gym.make_vec("PneuNetGrasp-v1", num_envs=2, vectorization_mode="vector_entry_point"),
}


@pytest.mark.parametrize("name", list(MAKERS))
@pytest.mark.parametrize("reset_first", [True, False])
def test_step_and_reset_after_close_are_refused_by_name(name, reset_first):
    env = MAKERS[name]()
    if reset_first:
        env.reset(seed=0)
        env.step(env.action_space.sample())
    env.close()
    env.close()  # again: nothing
    kind = type(env.unwrapped).__name__
    stepped = env if reset_first else env.unwrapped  # (gym.make's OrderEnforcing refuses a step before any reset)
    with pytest.raises(ClosedEnvironmentError, match=rf"^{kind}\.step\(\) after close\(\)"):
        stepped.step(np.zeros(env.action_space.shape, np.float32))
    with pytest.raises(ClosedEnvironmentError, match=rf"^{kind}\.reset\(\) after close\(\): a closed env is not "
                                                       "reopened; make a new one"):
        env.reset(seed=1)
    assert env.unwrapped.closed


def test_render_after_close_is_refused():
    env = gym.make("PneuNetGrasp-v1", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().ndim == 3
    env.close()
    with pytest.raises(ClosedEnvironmentError, match=r"render\(\) after close\(\)"):
        env.render()


def test_a_new_env_is_open():
    first = MAKERS["vector"]()
    first.close()
    second = MAKERS["vector"]()  # the flag is the instance's, not the class's
    second.reset(seed=0)
    second.step(np.zeros((2, 1), np.float32))
    assert not second.closed and first.closed
    second.close()
