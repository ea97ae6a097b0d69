"""Rendering speed: ``env.step`` + ``env.render()`` frames per second, PneuNetGrasp-v1 against CartPole-v1.

What it measures (one process, one after the other, in alternating rounds so that drifts of the machine hit
both): the wall time of ``env.step(action); env.render()`` pairs of ``gym.make(ENV, render_mode="rgb_array")``
(default wrappers, the default frame size: 480 x 360 for PneuNetGrasp-v1, 600 x 400 for CartPole-v1), each pair
timed alone (``time.perf_counter``), resets outside the timing. Frames per second are ``frames`` over the summed
time of a round; the best round of ``repeats`` is kept (other processes on the machine only ever slow a round).

Actions are drawn up front: PneuNetGrasp-v1 squeezes (``+1``, the largest pressure increase) for the first 20
steps of each episode, so that frames show the actuator curling, contact and damage, then draws uniformly from
its action space; CartPole-v1 draws from its action space.

CartPole-v1 draws with pygame (``pip install "gymnasium[classic-control]"``), which this package does not need:
without it, its figures are ``None`` and ``cartpole_error`` says why. ``python -m pneunet_env.bench.render_speed``
prints the figures; :func:`bench_render` returns them.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

__all__ = ["bench_render", "main", "TARGET_FRAMES_PER_S"]

TARGET_FRAMES_PER_S = 300.0
"""The target: PneuNetGrasp-v1's step + render frames per second at the default 480 x 360."""

_SQUEEZE_STEPS = 20


def _make(env_id: str):
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v1)

    return gym.make(env_id, render_mode="rgb_array")


def _actions(env, n: int, seed: int) -> list:
    env.action_space.seed(seed)
    return [env.action_space.sample() for _ in range(n)]


def _round(env, actions: list, seed: int, squeeze: bool) -> tuple[float, tuple[int, ...]]:
    """Seconds of ``len(actions)`` step + render pairs (resets excluded); the frame's shape.

    ``squeeze``: the first steps of each episode take the largest action (``+1``) instead.
    """
    clock = time.perf_counter
    push = np.ones(env.action_space.shape, env.action_space.dtype) if squeeze else None
    env.reset(seed=seed)
    total, t_in_episode, shape = 0.0, 0, ()
    for i, a in enumerate(actions):
        if squeeze and t_in_episode < _SQUEEZE_STEPS:
            a = push
        t0 = clock()
        _, _, terminated, truncated, _ = env.step(a)
        frame = env.render()
        total += clock() - t0
        shape = frame.shape
        t_in_episode += 1
        if terminated or truncated:
            env.reset(seed=seed + i + 1)
            t_in_episode = 0
    return total, shape


def bench_render(frames: int = 300, repeats: int = 3, seed: int = 0) -> dict[str, Any]:
    """Step + render frames per second of PneuNetGrasp-v1 and of CartPole-v1, measured in the same run.

    Returns ``pneunet_frames_per_s``, ``cartpole_frames_per_s`` (``None`` without pygame, with
    ``cartpole_error``), ``ratio`` (PneuNetGrasp-v1 over CartPole-v1), the frame shapes, ``frames``, ``repeats``
    and ``target_frames_per_s``.
    """
    frames, repeats = int(frames), int(repeats)
    if frames < 1 or repeats < 1:
        raise ValueError(f"frames and repeats must be >= 1, got {frames} and {repeats}")
    envs: dict[str, Any] = {"PneuNetGrasp-v1": _make("PneuNetGrasp-v1")}
    error = None
    try:
        cartpole = _make("CartPole-v1")
        cartpole.reset(seed=seed)
        cartpole.render()  # pygame is imported here
        envs["CartPole-v1"] = cartpole
    except Exception as exc:  # gymnasium.error.DependencyNotInstalled without pygame; a display error
        error = f"{type(exc).__name__}: {exc}"
    actions = {name: _actions(env, frames, seed) for name, env in envs.items()}
    best: dict[str, float] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    for name, env in envs.items():  # a round of warm-up each (first frames build caches)
        _round(env, actions[name][: min(frames, 20)], seed, squeeze=name == "PneuNetGrasp-v1")
    for _ in range(repeats):
        for name, env in envs.items():
            seconds, shapes[name] = _round(env, actions[name], seed, squeeze=name == "PneuNetGrasp-v1")
            best[name] = max(best.get(name, 0.0), frames / seconds)
    for env in envs.values():
        env.close()
    pn = best["PneuNetGrasp-v1"]
    cp = best.get("CartPole-v1")
    return {
        "frames": frames,
        "repeats": repeats,
        "pneunet_frames_per_s": pn,
        "pneunet_frame_shape": list(shapes["PneuNetGrasp-v1"]),
        "cartpole_frames_per_s": cp,
        "cartpole_frame_shape": list(shapes["CartPole-v1"]) if cp is not None else None,
        "cartpole_error": error,
        "ratio": pn / cp if cp else None,
        "target_frames_per_s": TARGET_FRAMES_PER_S,
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=300, help="step + render pairs per round (default 300)")
    parser.add_argument("--repeats", type=int, default=3, help="rounds; the best is kept (default 3)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m pneunet_env.bench.render_speed", description=__doc__.split("\n")[0]
    )
    add_arguments(parser)
    return run(parser.parse_args(argv))


def run(args: argparse.Namespace) -> int:
    """``pneunet-grasp bench render``: frames/s of step + render, against CartPole measured in the same run."""
    r = bench_render(args.frames, args.repeats)
    h, w, _ = r["pneunet_frame_shape"]
    print(f"PneuNetGrasp-v1 step + render ({w} x {h}): {r['pneunet_frames_per_s']:8.1f} frames/s "
          f"(target >= {r['target_frames_per_s']:.0f})")
    if r["cartpole_frames_per_s"] is None:
        print(f"CartPole-v1 step + render: not measured ({r['cartpole_error']})")
    else:
        h, w, _ = r["cartpole_frame_shape"]
        print(f"CartPole-v1     step + render ({w} x {h}): {r['cartpole_frames_per_s']:8.1f} frames/s")
        print(f"ratio PneuNetGrasp-v1 / CartPole-v1: {r['ratio']:.2f}")
    print(f"(best of {r['repeats']} rounds of {r['frames']} frames)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
