"""PPO from skrl, trained where the env lives: on the torch backend, tensors in and out, on a CPU or a GPU.

``pneunet-grasp train-skrl --device cuda --num-envs 65536 --minutes 10`` (needs the ``skrl`` extra, and a CUDA torch
for a GPU). The env is ``gym.make_vec("PneuNetGrasp-v1", num_envs=N, backend="torch", device=...)``; skrl drives it
through :class:`TorchVecEnvWrapper`, an implementation of skrl's own environment-wrapper interface
(``skrl.envs.wrappers.torch.base.Wrapper``) that passes the env's tensors straight through: observations, actions,
rewards and flags never leave the device (skrl's generic Gymnasium wrapper would convert them to numpy and back).

By default the agent's action is the env's own pressure increment, with an initial exploration of one full step
(log std 0): skrl's PPO draws Gaussian noise afresh every step, and on increments that noise adds up to a random walk
of the pressure, which explores hold pressures. ``action="setpoint"`` gives the SB3 agent's action instead (``(u +
1)/2`` of ``p_max``, through :func:`pneunet_env.wrappers.setpoint_to_rate`); behind its rate-limited regulator
per-step noise averages out, and skrl's PPO did not learn with it (docs/performance.md). Either way the agent sees
the pressure alone: as blind as best-ramp.

Progress is measured the way the baselines are compared: every ``eval_every_s`` seconds the deterministic policy
(skrl's mean action) grasps a fixed, seeded set of objects (one episode each, on the same backend), beside
best-ramp's success on the same objects. :func:`train` returns the curve (wall-clock seconds, env-steps, success)
and the time at which the policy first reached best-ramp's success rate, if it did.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

from pneunet_env.arguments import count, integer, output_dir, real
from pneunet_env.arguments import seed as seed_type

__all__ = ["TorchVecEnvWrapper", "evaluate_success", "train", "add_arguments", "run"]


def _wrapper_base():
    from skrl.envs.wrappers.torch.base import Wrapper

    return Wrapper


def TorchVecEnvWrapper(env, setpoint: bool = True):  # noqa: N802 - a class factory (skrl is imported lazily)
    """skrl's env-wrapper interface around the torch-backend vector env (see the module docstring)."""
    import torch

    from pneunet_env.wrappers import setpoint_step_fraction, setpoint_to_rate

    class _Wrapper(_wrapper_base()):
        def __init__(self, env):
            super().__init__(env)
            self._obs = None
            self._info: dict[str, Any] = {}
            self._fraction = setpoint_step_fraction(env.unwrapped.config)

        @property
        def observation_space(self):
            return self._unwrapped.single_observation_space

        @property
        def action_space(self):
            return self._unwrapped.single_action_space

        def reset(self):
            if self._obs is None:  # a vector env resets its sub-envs itself (SAME_STEP): reset only once
                self._obs, self._info = self._env.reset()
            return self._obs, self._info

        def step(self, actions: torch.Tensor):
            a = actions.reshape(-1)
            if setpoint:
                a = setpoint_to_rate(a, self._obs[:, 0], self._fraction)
            obs, reward, terminated, truncated, info = self._env.step(a)
            self._obs = obs
            n = self.num_envs
            return obs, reward.to(torch.float32).view(n, 1), terminated.view(n, 1), truncated.view(n, 1), info

        def state(self):
            return None

        def render(self, *args, **kwargs):
            return None

        def close(self):
            self._env.close()

    return _Wrapper(env)


def _first_episode_success(env, act, seed: int) -> float:
    """Success rate of the first episode of every sub-env of ``env`` (reset with ``seed``) under ``act(obs)``."""
    import torch

    obs, _ = env.reset(seed=seed)
    n = env.num_envs
    done = torch.zeros(n, dtype=torch.bool, device=env.unwrapped.device)
    success = torch.zeros(n, dtype=torch.bool, device=env.unwrapped.device)
    for _ in range(env.unwrapped.config.episode_steps + 1):
        obs, _, term, trunc, info = env.step(act(obs))
        ended = (term | trunc) & ~done
        if bool(ended.any()):
            success |= ended & info["final_info"]["is_success"]
            done |= ended
        if bool(done.all()):
            break
    return float(success.double().mean())


def evaluate_success(env, policy_fn, seed: int) -> float:
    """Success of ``policy_fn`` (setpoint ``u`` from the observation tensor) on ``env``'s seeded objects."""
    from pneunet_env.wrappers import setpoint_step_fraction, setpoint_to_rate

    frac = setpoint_step_fraction(env.unwrapped.config)
    return _first_episode_success(env, lambda obs: setpoint_to_rate(policy_fn(obs), obs[:, 0], frac), seed)


def best_ramp_success(env, seed: int) -> float:
    """best-ramp (the tuned blind ramp of the env's task) on the same objects: the target."""
    import torch

    from agents.policies.registry import make_policy

    ramp = make_policy("best-ramp", env.unwrapped.config).policy
    device = env.unwrapped.device
    return _first_episode_success(
        env, lambda obs: torch.as_tensor(ramp(obs.cpu().numpy()), device=device).reshape(-1), seed)


def train(num_envs: int = 256, device: str = "cpu", minutes: float = 5.0, eval_objects: int = 200,
          eval_every_s: float = 30.0, seed: int = 0, compile: bool = False, rollouts: int = 32,
          action: str = "increment", initial_log_std: float = 0.0, log=print) -> dict[str, Any]:
    """Train skrl's PPO on the torch backend for ``minutes`` of wall-clock; see the module docstring.

    ``action``: ``"setpoint"`` (the regulator, as the SB3 agent) or ``"increment"`` (the env's own action, whose
    per-step noise adds up to a random walk of the pressure). ``initial_log_std``: the policy's initial exploration.
    """
    if action not in ("setpoint", "increment"):
        raise ValueError(f"action must be 'setpoint' or 'increment', got {action!r}")
    import gymnasium as gym
    import torch
    from skrl.agents.torch.ppo import PPO, PPO_CFG
    from skrl.memories.torch import RandomMemory
    from skrl.trainers.torch import StepTrainer
    from skrl.utils import set_seed
    from skrl.utils.model_instantiators.torch import deterministic_model, gaussian_model

    import pneunet_env  # noqa: F401

    set_seed(seed)
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=num_envs, backend="torch", device=device, compile=compile)
    eval_env = gym.make_vec("PneuNetGrasp-v1", num_envs=eval_objects, backend="torch", device=device,
                            compile=compile)
    eval_seed = 10_000 + seed
    target = best_ramp_success(eval_env, eval_seed)
    log(f"best-ramp on the {eval_objects} evaluation objects: {target:.1%}")
    setpoint = action == "setpoint"
    wrapped = TorchVecEnvWrapper(env, setpoint=setpoint)
    dev = wrapped.device
    net = [{"name": "net", "input": "OBSERVATIONS", "layers": [64, 64], "activations": "tanh"}]
    models = {
        "policy": gaussian_model(observation_space=wrapped.observation_space, action_space=wrapped.action_space,
                                 device=dev, clip_actions=True, initial_log_std=initial_log_std, network=net,
                                 output="ACTIONS"),
        "value": deterministic_model(observation_space=wrapped.observation_space, action_space=wrapped.action_space,
                                     device=dev, network=net, output="ONE"),
    }
    cfg = PPO_CFG(rollouts=rollouts, learning_epochs=5, mini_batches=4, discount_factor=0.999, gae_lambda=0.98,
                  learning_rate=3e-4, entropy_loss_scale=0.0, value_loss_scale=0.5, time_limit_bootstrap=True)
    memory = RandomMemory(memory_size=rollouts, num_envs=num_envs, device=dev)
    agent = PPO(models=models, memory=memory, observation_space=wrapped.observation_space,
                action_space=wrapped.action_space, device=dev, cfg=cfg)
    trainer = StepTrainer(env=wrapped, agents=agent, cfg={"timesteps": 10**9, "headless": True,
                                                          "disable_progressbar": True,
                                                          "close_environment_at_exit": False})

    def mean_action(obs):
        # fork_rng: the evaluation's draws (the model samples even when only its mean is used) leave the training's
        # random stream as it was, so the training does not depend on when the evaluations happen
        with torch.no_grad(), torch.random.fork_rng(devices=[dev] if dev.type == "cuda" else []):
            return agent.act(obs, None, timestep=0, timesteps=1)[1]["mean_actions"].reshape(-1)

    curve = []
    budget = 60.0 * minutes
    train_s, next_eval, steps, reached = 0.0, 0.0, 0, None
    while True:
        if train_s >= next_eval or train_s >= budget:  # evaluation time is not training time
            success = (evaluate_success(eval_env, mean_action, eval_seed) if setpoint
                       else _first_episode_success(eval_env, mean_action, eval_seed))
            curve.append({"wall_s": train_s, "env_steps": steps, "success": success})
            log(f"{train_s:7.1f} s  {steps:>10,} env-steps  success {success:.1%}")
            if reached is None and success >= target:
                reached = curve[-1]
            next_eval = train_s + eval_every_s
            if train_s >= budget:
                break
        t = time.perf_counter()
        with torch.enable_grad():  # whatever the caller's mode (see agents.training.train: a Ctrl-C can leave it off)
            trainer.train()
        train_s += time.perf_counter() - t
        steps += num_envs
    wrapped.close()
    eval_env.close()
    return {"library": f"skrl {__import__('skrl').__version__}", "torch": torch.__version__, "device": str(dev),
            "num_envs": num_envs, "compile": compile, "action": action, "initial_log_std": initial_log_std,
            "minutes": minutes, "eval_objects": eval_objects,
            "best_ramp_success": target, "curve": curve, "reached_best_ramp": reached,
            "final_success": curve[-1]["success"]}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", default="cpu", help="torch device of the env and the agent (cpu, cuda, ...)")
    parser.add_argument("--num-envs", type=integer(1, 1 << 26, "--num-envs"), default=256,
                        help="parallel envs (default 256; on a GPU: 65536)")
    parser.add_argument("--minutes", type=real(0, 1e7, above=True), default=5.0,
                        help="training wall-clock budget (evaluations excluded)")
    parser.add_argument("--eval-objects", type=count, default=200, help="objects of the seeded evaluation set")
    parser.add_argument("--eval-every", type=real(0, 1e9, above=True), default=30.0,
                        help="seconds of training between evaluations")
    parser.add_argument("--seed", type=seed_type, default=0)
    parser.add_argument("--compile", action="store_true", help="the env's solver round through torch.compile")
    parser.add_argument("--action", choices=("setpoint", "increment"), default="increment",
                        help="the agent's action: the env's pressure increment (default) or a pressure setpoint")
    parser.add_argument("--initial-log-std", type=real(-20, 5), default=0.0, help="the policy's initial log std")
    parser.add_argument("--out", type=output_dir, default=Path("runs/skrl"), help="output folder (curve.json)")


def run(args: argparse.Namespace) -> int:
    for name in ("num_envs", "eval_objects"):
        if getattr(args, name) < 1:
            raise SystemExit(f"--{name.replace('_', '-')} must be a positive integer, got {getattr(args, name)}")
    if not args.minutes > 0 or not args.eval_every > 0:
        raise SystemExit(f"--minutes and --eval-every must be > 0, got {args.minutes}, {args.eval_every}")
    if not math.isfinite(args.initial_log_std):
        raise SystemExit(f"--initial-log-std must be finite, got {args.initial_log_std}")
    try:
        import skrl  # noqa: F401
    except ImportError:
        raise SystemExit("train-skrl needs skrl: pip install 'pneunet-env[skrl]' (after torch==2.13.0)") from None
    res = train(num_envs=args.num_envs, device=args.device, minutes=args.minutes, eval_objects=args.eval_objects,
                eval_every_s=args.eval_every, seed=args.seed, compile=args.compile, action=args.action,
                initial_log_std=args.initial_log_std)
    from pneunet_env.files import atomic_write_json, deferred_interrupt

    with deferred_interrupt():  # whole or not at all (a Ctrl-C before it writes nothing)
        atomic_write_json(args.out / "curve.json", res)
    r = res["reached_best_ramp"]
    print(f"best-ramp {res['best_ramp_success']:.1%}; final {res['final_success']:.1%}; "
          + (f"reached best-ramp after {r['wall_s']:.0f} s ({r['env_steps']:,} env-steps)" if r
             else "did not reach best-ramp in the budget"))
    print(f"wrote {args.out}/curve.json")
    return 0
