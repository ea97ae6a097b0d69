"""``python ramp.py LABEL``: the vector env at N = 16,384 under the best blind ramp: energy evaluations per env-step
(an untimed full-info pass of 200 steps) and env-steps per second (best of 3 × 100 steps) against
CartPoleVectorEnv in the same process. ``STEP_CONTROL`` (environment): the solver's ``step_control``."""

import os
import sys
import time

import gymnasium as gym
import numpy as np

import pneunet_env  # noqa: F401
from pneunet_env.bench.speed import ramp_policy

N = 16384
CONTROL = {"step_control": os.environ.get("STEP_CONTROL", "jump")}
pol = ramp_policy()
env = gym.make_vec("PneuNetGrasp-v1", num_envs=N, info_level="full", **CONTROL)
obs, _ = env.reset(seed=5)
ev = n = 0
for _ in range(200):
    obs, _, _, _, info = env.step(pol(obs))
    e = info["solver_evaluations"]
    if "final_info" in info:
        e = np.where(info["final_info"]["_pressure"], info["final_info"]["solver_evaluations"], e)
    ev, n = ev + e.sum(), n + e.size
env = gym.make_vec("PneuNetGrasp-v1", num_envs=N, **CONTROL)
obs, _ = env.reset(seed=5)
for _ in range(30):
    obs, *_ = env.step(pol(obs))
best = 1e9
for _ in range(3):
    t = time.perf_counter()
    for _ in range(100):
        obs, *_ = env.step(pol(obs))
    best = min(best, time.perf_counter() - t)
cp = gym.make_vec("CartPole-v1", num_envs=N)
cp.reset(seed=0)
acts = np.random.default_rng(0).integers(0, 2, (100, N))
cbest = 1e9
for _ in range(3):
    t = time.perf_counter()
    for a in acts:
        cp.step(a)
    cbest = min(cbest, time.perf_counter() - t)
print(sys.argv[1], f"evaluations per env-step {ev / n:.3f}; {100 * N / best / 1e6:.2f} M env-steps/s; "
      f"CartPoleVectorEnv {100 * N / cbest / 1e6:.2f} M; ratio {cbest / best:.3f}")
