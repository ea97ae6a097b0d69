"""``pneunet-grasp bench train``: how fast PPO trains on the env, against the same PPO on CartPole, in one run.

The shipped PPO config (``configs/train/ppo.yaml``: 16 envs, 128 steps per rollout, gSDE, the setpoint action)
trains ``--steps`` timesteps on the batched env, once per ``--threads`` value (torch threads; the numba threads of
the env run beside them), without evaluations or checkpoints: the figure is env-steps of training per second, the
env's step and PPO's update together. The reference is SB3's PPO with the same hyperparameters on
``CartPole-v1`` (16 envs in a ``DummyVecEnv``; gSDE needs a continuous action, so plain PPO there), trained in the
same run with one torch thread. Figures, never a pass/fail: machines are noisy. ``--json PATH`` keeps them.

This is where the training time of the full-training test went: the test judges what 300,000 steps reach, this
command says how long steps take.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from typing import Any

from pneunet_env import arguments as checks
from pneunet_env.files import atomic_write_json


def _rate(model, steps: int) -> tuple[float, float]:
    from agents.training.train import no_folder_logger

    model.set_logger(no_folder_logger())  # no empty SB3-<date> folder per learn()
    model.learn(total_timesteps=model.n_steps * model.n_envs)  # warm-up: the first rollout compiles and allocates
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    wall = time.perf_counter() - t0
    return steps / wall, wall


def bench_train(steps: int = 20_000, threads: tuple[int, ...] = (1, 2), seed: int = 0) -> dict[str, Any]:
    """Timesteps per second of PPO on ``PneuNetGrasp-v1`` (the shipped config) per torch thread count, and of the
    same PPO on CartPole-v1 (one thread)."""
    import stable_baselines3 as sb3
    import torch
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env

    from agents.common.resources import resolve_config
    from agents.training.config import _algo_kwargs, _resolve_policy_kwargs, load_train_config
    from agents.training.envs import make_vec_env

    hp = load_train_config(resolve_config("ppo", "train"))
    kwargs = _algo_kwargs(hp)
    out: dict[str, Any] = {"steps": steps, "n_envs": hp["n_envs"], "n_steps": hp["n_steps"], "pneunet": {}}
    previous = torch.get_num_threads()
    try:
        for n in threads:
            torch.set_num_threads(n)
            venv = make_vec_env(hp, hp["n_envs"], seed, None)
            model = sb3.PPO(hp["policy"], venv, seed=seed, device="cpu", verbose=0,
                            policy_kwargs=_resolve_policy_kwargs(hp["policy_kwargs"]), **kwargs)
            rate, wall = _rate(model, steps)
            venv.close()
            out["pneunet"][str(n)] = {"steps_per_s": rate, "wall_s": wall}
        torch.set_num_threads(1)
        cp = sb3_make_vec_env("CartPole-v1", n_envs=hp["n_envs"], seed=seed)
        plain = {k: v for k, v in kwargs.items() if k not in ("use_sde", "sde_sample_freq")}
        model = sb3.PPO("MlpPolicy", cp, seed=seed, device="cpu", verbose=0, policy_kwargs={"net_arch": [64, 64]},
                        **plain)
        rate, wall = _rate(model, steps)
        cp.close()
        out["cartpole"] = {"steps_per_s": rate, "wall_s": wall}
    finally:
        torch.set_num_threads(previous)
    for r in out["pneunet"].values():
        r["ratio_to_cartpole"] = r["steps_per_s"] / out["cartpole"]["steps_per_s"]
    out["machine"] = {"cpus": os.cpu_count(), "python": platform.python_version(), "torch": torch.__version__,
                      "stable_baselines3": sb3.__version__}
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--steps", type=checks.integer(1, 10**9), default=20_000,
                        help="timesteps timed per run (default 20000)")
    parser.add_argument("--threads", type=checks.integer(1, 1024), nargs="+", default=[1, 2],
                        help="torch thread counts to time (default 1 2)")
    parser.add_argument("--json", type=checks.output_file, default=None,
                        help="also write the figures to this JSON file (checked before the benchmark; replaced "
                             "whole)")


def run(args: argparse.Namespace) -> int:
    from pneunet_env.extras import require_extra

    require_extra("bench train", "stable_baselines3", "rl", "PPO")
    if args.steps < 1 or any(n < 1 for n in args.threads):
        raise SystemExit(f"pneunet-grasp bench train: --steps and --threads must be >= 1, got {args.steps} and "
                         f"{args.threads}")
    res = bench_train(args.steps, tuple(dict.fromkeys(args.threads)))
    print(f"PPO training speed, {res['steps']} timesteps each ({res['n_envs']} envs x {res['n_steps']} steps a "
          "rollout), after one warm-up rollout:")
    for n, r in res["pneunet"].items():
        print(f"  PneuNetGrasp-v1, shipped ppo config, {n} torch thread(s): {r['steps_per_s']:8.0f} steps/s "
              f"({r['wall_s']:.1f} s), {r['ratio_to_cartpole']:.2f}x CartPole's")
    cp = res["cartpole"]
    print(f"  CartPole-v1, the same PPO (no gSDE), 1 torch thread:       {cp['steps_per_s']:8.0f} steps/s "
          f"({cp['wall_s']:.1f} s)")
    if args.json is not None:
        atomic_write_json(args.json, res)
        print(f"wrote {args.json}")
    return 0
