"""``bench speed``'s single env *with its resets*: a user's loop (steps, and a reset at every episode's end) against
CartPole-v1's, in the same run.

:func:`pneunet_env.bench.speed.bench_single` times ``env.step`` alone, resets outside the timing; a user's loop pays
the resets too. Here each ``env.step`` and each ``env.reset`` of the loop is timed alone (``time.perf_counter``:
the policy's own work, drawing the actions or computing the ramp, stays outside the timing), and the figure is the
env's time per env-step, resets included: ``(sum of step times + sum of reset times) / steps``. Workloads:

* ``random``: actions drawn up front from the action space (PneuNetGrasp-v1 and CartPole-v1 alike);
* ``ramp``: the best blind ramp (the policy :func:`pneunet_env.bench.speed.ramp_policy` gives, on the observation;
  PneuNetGrasp-v1 only: CartPole's figure stays its random one, as in the vector env's table).

Both envs through ``gym.make`` (default wrappers), measured in alternating rounds so that drifts of the machine hit
both. Also the reset alone: the median of the loop's resets (unseeded), and of ``reset(seed=i)`` over fresh seeds
(numpy's seeding, about 15-20 us of it, is the same work for both envs). No threshold is asserted.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["bench_single_with_resets", "format_lines", "ENVS", "TARGETS"]

ENVS = ("PneuNetGrasp-v1", "CartPole-v1")
"""The envs compared."""

TARGETS = {"ratio_random_max": 1.0, "reset_max_us": 50.0}
"""Issue 36's targets, printed next to the figures (never asserted): the time per env-step with resets under random
actions at most CartPole-v1's, and the reset under 50 us."""


def _loop(env, steps: int, actions: list | None, policy: Callable | None = None,
          obs: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """The step and reset times (s) of ``steps`` steps of a user's loop, from the env's current state (its
    observation ``obs``): each action is ``actions[i]``, or ``policy(obs)`` (computed untimed)."""
    clock = time.perf_counter
    step, reset = env.step, env.reset
    step_times = np.empty(steps)
    reset_times: list[float] = []
    for i in range(steps):
        a = actions[i] if policy is None else policy(obs)
        t0 = clock()
        out = step(a)
        t1 = clock()
        step_times[i] = t1 - t0
        obs = out[0]
        if out[2] or out[3]:
            t0 = clock()
            obs, _ = reset()
            reset_times.append(clock() - t0)
    return step_times, np.asarray(reset_times, dtype=float)


def _seeded_resets(env, count: int, first_seed: int) -> np.ndarray:
    """The times (s) of ``reset(seed=s)`` for ``count`` fresh seeds, each timed alone."""
    clock = time.perf_counter
    reset = env.reset
    times = np.empty(count)
    for i in range(count):
        t0 = clock()
        reset(seed=first_seed + i)
        times[i] = clock() - t0
    return times


def bench_single_with_resets(steps: int, rounds: int, resets: int, ramp: Callable, seed: int = 0) -> dict[str, Any]:
    """The single env's time per env-step with its resets (random actions and the ramp ``ramp``: a batch policy,
    ``(N, 1)`` observations to ``(N, 1)`` actions) against CartPole-v1's (random actions), and each env's median
    reset (unseeded: the loop's; seeded: ``resets`` fresh seeds).

    Returns ``{"steps_per_workload", "rounds", "per_step_s", "median_step_s", "median_reset_s",
    "median_seeded_reset_s", "mean_episode_steps", "ratio"}``: ``per_step_s``, ``median_step_s``,
    ``median_reset_s`` and ``mean_episode_steps`` keyed ``"<env> <workload>"``; ``median_seeded_reset_s`` by env;
    ``ratio`` by PneuNetGrasp-v1's workload, over CartPole-v1's random figure.
    """
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers the environment)

    envs = {name: gym.make(name) for name in ENVS}

    def act_ramp(obs):
        return ramp(np.asarray(obs)[None])[0]

    runs = [("PneuNetGrasp-v1 random", "PneuNetGrasp-v1", None), ("PneuNetGrasp-v1 ramp", "PneuNetGrasp-v1", act_ramp),
            ("CartPole-v1 random", "CartPole-v1", None)]
    steps_t: dict[str, list[np.ndarray]] = {k: [] for k, _, _ in runs}
    resets_t: dict[str, list[np.ndarray]] = {k: [] for k, _, _ in runs}
    seeded: dict[str, list[np.ndarray]] = {name: [] for name in envs}
    for env in envs.values():  # warm up (the first numba call compiles; caches)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        _loop(env, 200, [env.action_space.sample() for _ in range(200)])
        _seeded_resets(env, 20, seed)
    per_round = max(1, steps // rounds)
    per_round_resets = max(1, resets // rounds)
    for r in range(rounds):
        for key, name, policy in runs:
            env = envs[name]
            obs, _ = env.reset(seed=seed + r)
            actions = [env.action_space.sample() for _ in range(per_round)] if policy is None else None
            s, t = _loop(env, per_round, actions, policy, obs)
            steps_t[key].append(s)
            resets_t[key].append(t)
        for name, env in envs.items():
            seeded[name].append(_seeded_resets(env, per_round_resets, seed + 1000 * (r + 1)))
    for env in envs.values():
        env.close()
    per_step = {}
    for key in steps_t:
        s, t = np.concatenate(steps_t[key]), np.concatenate(resets_t[key])
        per_step[key] = float((s.sum() + t.sum()) / s.size)
    n_resets = {k: sum(a.size for a in v) for k, v in resets_t.items()}
    cart = per_step["CartPole-v1 random"]
    return {
        "steps_per_workload": per_round * rounds,
        "rounds": rounds,
        "per_step_s": per_step,
        "median_step_s": {k: float(np.median(np.concatenate(v))) for k, v in steps_t.items()},
        "median_reset_s": {k: float(np.median(np.concatenate(v))) if n_resets[k] else float("nan")
                           for k, v in resets_t.items()},
        "median_seeded_reset_s": {k: float(np.median(np.concatenate(v))) for k, v in seeded.items()},
        "mean_episode_steps": {k: per_round * rounds / n_resets[k] if n_resets[k] else float("inf")
                               for k in resets_t},
        "ratio": {"random": per_step["PneuNetGrasp-v1 random"] / cart, "ramp": per_step["PneuNetGrasp-v1 ramp"] / cart},
    }


def format_lines(res: dict[str, Any]) -> list[str]:
    """The table's lines for :func:`bench_single_with_resets`'s result."""
    lines = [
        "single env with its resets: env time per env-step, resets included (gym.make; each step and reset timed "
        "alone, the policy untimed)",
        f"  {'':<24}{'per step':>10}  {'step':>9}  {'reset':>9}  {'seeded reset':>12}  {'episode':>8}  {'ratio':>7}",
    ]
    for key, per_step in res["per_step_s"].items():
        name, workload = key.rsplit(" ", 1)
        ratio = res["ratio"].get(workload) if name == "PneuNetGrasp-v1" else 1.0
        lines.append(f"  {key:<24}{per_step * 1e6:>7.2f} us  {res['median_step_s'][key] * 1e6:>6.2f} us  "
                     f"{res['median_reset_s'][key] * 1e6:>6.2f} us  {res['median_seeded_reset_s'][name] * 1e6:>9.2f} us"
                     f"  {res['mean_episode_steps'][key]:>8.1f}  {ratio:>6.2f}x")
    lines.append("  (step, reset: medians; episode: mean steps per episode; ratio: per step over CartPole-v1's, random "
                 f"actions; targets: random <= {TARGETS['ratio_random_max']:g}x, the reset under "
                 f"{TARGETS['reset_max_us']:g} us)")
    return lines
