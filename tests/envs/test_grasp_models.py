"""The env's ``model`` option: ``full`` (default), ``linear``, ``auto`` (pneunet_env.physics.models)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401
from pneunet_env.physics.models import AUTO_TOLERANCE


def _episode(model: str, stiffness: float, actions):
    env = gym.make("PneuNetGrasp-v0", model=model, terminate_on_damage=False, terminate_on_slip=False)
    env.reset(seed=3, options={"object_stiffness": stiffness})
    rows = []
    for a in actions:
        _, _, term, trunc, info = env.step(np.array([a], np.float32))
        rows.append((info["curvature"], info["side_strain"], info["solver_converged"]))
        if term or trunc:
            break
    return np.array(rows)


@pytest.mark.parametrize("stiffness", [1e-5, 1e-4, 1e-2])
def test_auto_agrees_with_full_to_its_bound(stiffness):
    actions = [0.3] * 40 + [-0.5] * 20  # up through contact (and the fold at 1e-4), then partly down
    full = _episode("full", stiffness, actions)
    auto = _episode("auto", stiffness, actions)
    assert full[:, 2].all() and auto[:, 2].all()
    assert np.abs(full[:, :2] - auto[:, :2]).max() <= AUTO_TOLERANCE


def test_linear_model_runs_and_differs_past_the_balloon():
    actions = [1.0] * 20
    full = _episode("full", 1e-5, actions)
    lin = _episode("linear", 1e-5, actions)
    assert np.isfinite(lin).all()
    assert np.abs(full[:, 0] - lin[:, 0]).max() > 0.05  # the linear law misses the balloon


def test_unknown_model_raises_naming_it():
    with pytest.raises(ValueError, match="model"):
        gym.make("PneuNetGrasp-v0", model="quadratic")


def test_vector_env_refuses_non_full_models():
    with pytest.raises(ValueError, match="model"):
        gym.make_vec("PneuNetGrasp-v0", num_envs=2, model="auto")
