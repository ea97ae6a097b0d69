"""``pneunet-grasp bench gpu``: the fused step's CUDA kernel on a GPU, checked and timed in one run (about 5 min).

What it does, on the first CUDA device (``torch.device("cuda")``), with the default config (default solver options,
the free table, the step control, lean info):

* **Agreement.** :data:`AGREEMENT_ENVS` envs from the same start (the CPU env's reset state, copied to the device)
  stepped :data:`AGREEMENT_STEPS` times by the CPU fused step (numba) and by the kernel, with the same actions (half
  the envs random, half the best blind ramp), each free running: the largest relative difference of the states
  (each float field, relative to ``max(|cpu|, 1e-9)``), and the flags and counters that differ, counted (target:
  states within 1e-12 relative; a real GPU fuses multiply-adds and its libdevice differs in the last bits).
* **Speed.** Env-steps/s at N = 2^16, 2^20, 2^22 under random actions and the best blind ramp
  (:func:`pneunet_env.bench.speed.ramp_policy`'s formula, on the device): the kernel alone
  (:class:`~pneunet_env.fused_cuda.DeviceStep` on the state, no env: its launch, outputs and ``_keep_where``), and
  end to end through the VectorEnv API (``gym.make_vec("PneuNetGrasp-v1", num_envs=N, backend="torch",
  device="cuda")``: autoreset, info), each timed after a warm-up over steps that take at least
  :data:`MIN_SECONDS` (``torch.cuda.synchronize`` before reading the clock); the solves that failed, counted.
  Target (issue 35): at least 1 G env-steps/s at N = 2^22 under the ramp, end to end.

Outputs in ``--out`` (default ``bench_out/gpu``): ``gpu.json`` (every figure, the device, versions) and ``gpu.png``.
Without a CUDA device (or numba-cuda: ``pip install pneunet-env[gpu]``) it exits with one line, measuring nothing.
``--dry-run`` runs the same code on the CPU under numba-cuda's simulator (a subprocess with
``NUMBA_ENABLE_CUDASIM=1 PNEUNET_DISABLE_NUMBA=1``), at tiny N: it checks the command, not the GPU (its reference is
then the numpy step without the free table, numba being off).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env import arguments as checks

__all__ = ["add_arguments", "run", "main", "NUM_ENVS", "AGREEMENT_ENVS", "AGREEMENT_STEPS", "torch_ramp"]

NUM_ENVS = (2**16, 2**20, 2**22)
"""The sizes timed."""
AGREEMENT_ENVS = 4096
AGREEMENT_STEPS = 200
MIN_SECONDS = 1.0
"""Each timing runs steps until this much wall time has passed (at least :data:`MIN_STEPS` steps)."""
MIN_STEPS = 5
BUDGET_S = 270.0
"""The run's time budget: the timings not started by then are recorded as skipped (the check must fit 5 min)."""
DRY = {"num_envs": (16, 32), "agreement_envs": 16, "agreement_steps": 10, "min_seconds": 0.0, "min_steps": 2}
"""``--dry-run``'s sizes (the simulator runs each env-step in Python)."""
POLICIES = ("random", "ramp")


def torch_ramp(config=None):
    """:func:`pneunet_env.bench.speed.ramp_policy` on torch tensors of the observations' device (the same formula and
    numbers: no host round trip): observations ``(N, k)`` -> float32 actions ``(N, 1)``."""
    import torch

    from pneunet_env.bench.speed import RAMP_STEPS, RAMP_TARGET_KPA
    from pneunet_env.config import EnvConfig

    task = (EnvConfig() if config is None else config).task
    target = RAMP_TARGET_KPA / task.max_pressure_kpa
    increment = target / RAMP_STEPS
    step_fraction = task.max_pressure_step_kpa / task.max_pressure_kpa

    def act(obs):
        p = obs[..., 0].double()
        change = torch.where(p <= target, torch.clamp(p + increment, max=target), torch.full_like(p, target)) - p
        spacing = torch.nextafter(obs[..., 0], torch.full_like(obs[..., 0], np.inf)).double() - p
        change = torch.where(change.abs() <= spacing, torch.zeros_like(change), change)  # hold: exactly 0
        return torch.clamp(change / step_fraction, -1.0, 1.0)[..., None].float()

    return act


def _sync(device) -> None:
    import torch

    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _to_device(record, device):
    """A (nested) record of numpy arrays (a state, a :class:`GraspObject`) as torch tensors on ``device``."""
    import dataclasses

    import torch

    if isinstance(record, tuple):
        return type(record)(*(_to_device(v, device) for v in record))
    if dataclasses.is_dataclass(record):
        return type(record)(**{f.name: _to_device(getattr(record, f.name), device)
                               for f in dataclasses.fields(record)})
    return torch.from_numpy(np.ascontiguousarray(record).copy()).to(device)


def _flat(record, prefix=""):
    """``(name, array)`` of every field of a nested record (a state, a step)."""
    import dataclasses

    if dataclasses.is_dataclass(record):
        return
    for name, v in zip(record._fields, record, strict=True):
        if isinstance(v, tuple) or dataclasses.is_dataclass(v):
            yield from _flat(v, f"{prefix}{name}.")
        else:
            yield prefix + name, v


def agreement(device, n: int, steps: int, seed: int = 0) -> dict[str, Any]:
    """The kernel against the CPU's step on ``n`` envs over ``steps`` steps from the same start (see the module):
    ``{"max_rel_state": {field: worst}, "flags_differing": {field: count}, "counters_differing": {...}, ...}``."""
    import functools

    import torch

    from pneunet_env import fused, fused_cuda, task
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv
    from pneunet_env.physics.xp import torch_ops

    ref_env = PneuNetGraspVectorEnv(n, backend="numba" if fused.HAVE_FUSED else "numpy")
    obs, _ = ref_env.reset(seed=seed)
    params_h = ref_env._params
    params_d = task.EnvParams.from_config(ref_env.config, torch_ops(device))
    host = ref_env.state
    dev = _to_device(host, device)
    kstep = fused_cuda.DeviceStep(params_d, fused_cuda.new_device_cache(n, device), device)
    if fused.HAVE_FUSED:
        ref = functools.partial(fused.fused_step, params=params_h, cache=fused.new_cache(n))
    else:
        ref = functools.partial(task.step, params=params_h,
                                contact=functools.partial(task.newton_contact_batch, backend="numpy"))
    from pneunet_env.bench.speed import ramp_policy

    ramp, rng = ramp_policy(ref_env.config), np.random.default_rng(seed)
    half = np.arange(n) < n // 2
    worst: dict[str, float] = {}
    differ: dict[str, int] = {}
    failed = 0
    for _ in range(steps):
        a = np.where(half, rng.uniform(-1.0, 1.0, n), ramp(obs)[:, 0].astype(np.float64))
        rh = ref(host, a)
        rd = kstep(dev, torch.from_numpy(a).to(device))
        for (name, x), (_, y) in zip(_flat(rh), _flat(rd), strict=True):
            if name.startswith("state.obj") or name.startswith("state.thresholds"):
                continue
            y = y.cpu().numpy()
            x = np.asarray(x)
            if x.dtype.kind == "f":
                rel = np.abs(y.astype(np.float64) - x) / np.maximum(np.abs(x), 1e-9)
                worst[name] = max(worst.get(name, 0.0), float(np.nanmax(rel, initial=0.0)))
            else:
                differ[name] = differ.get(name, 0) + int(np.sum(x != y))
        failed += int(np.sum(rh.solver_failed))
        host, dev, obs = rh.state, rd.state, rh.obs
    state_fields = {k: v for k, v in worst.items() if k.startswith("state.")}
    return {"num_envs": n, "steps": steps, "reference": "fused (numba)" if fused.HAVE_FUSED else "numpy step",
            "max_rel_state": max(state_fields.values(), default=0.0), "max_rel": worst,
            "differing": {k: v for k, v in differ.items() if v}, "cpu_failed_solves": failed,
            "target_rel_state": 1e-12}


def _timed(step_once, device, min_seconds: float, min_steps: int) -> tuple[float, int]:
    """Wall seconds and count of ``step_once()`` calls: a warm-up call, then calls until ``min_seconds`` passed."""
    step_once()
    _sync(device)
    count, t0 = 0, time.perf_counter()
    while True:
        step_once()
        count += 1
        if count >= min_steps:
            _sync(device)
            if time.perf_counter() - t0 >= min_seconds:
                break
    return time.perf_counter() - t0, count


def _timing(env, device, policy: str, mode: str, pool: list, ramp, min_seconds: float,
            min_steps: int) -> dict[str, Any]:
    """One timing of :func:`speed`, from a reset."""
    import torch

    from pneunet_env import fused_cuda

    core, n = env.unwrapped, env.num_envs
    obs, _ = env.reset(seed=0)
    box = {"obs": obs, "i": 0, "failed": torch.zeros((), dtype=torch.int64, device=device)}

    def action():
        box["i"] += 1
        return pool[box["i"] % len(pool)] if policy == "random" else ramp(box["obs"])

    if mode == "kernel":
        kstep = fused_cuda.DeviceStep(core._params, fused_cuda.new_device_cache(n, device), device)
        box["state"] = core.state

        def once():
            res = kstep(box["state"], action()[:, 0].double())
            box["state"], box["obs"] = res.state, res.obs
            box["failed"] += res.solver_failed.sum()
    else:
        def once():
            box["obs"], _, _, _, info = env.step(action())
            box["failed"] += info["solver_failed"].sum()
    seconds, count = _timed(once, device, min_seconds, min_steps)
    return {"num_envs": n, "policy": policy, "mode": mode, "steps": count, "seconds": seconds,
            "env_steps_per_s": n * count / seconds, "failed_solves": int(box["failed"])}


def speed(device, n: int, min_seconds: float, min_steps: int, deadline: float) -> list[dict[str, Any]]:
    """Env-steps/s at ``n`` envs under each policy (:data:`POLICIES`), from a reset each: the kernel alone (a
    :class:`~pneunet_env.fused_cuda.DeviceStep` of its own, with its own cache, on the env's reset state, no
    autoreset), then end to end (``gym.make_vec``'s ``step``); the failed solves counted on the device. A timing not
    started by ``deadline`` (``time.perf_counter``) is recorded as skipped."""
    import gymnasium as gym
    import torch


    env = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend="torch", device=device, kernel=True)
    core = env.unwrapped
    ramp = torch_ramp(core.config)
    gen = torch.Generator(device=device).manual_seed(0)
    pool = [torch.rand((n, 1), generator=gen, device=device, dtype=torch.float32) * 2.0 - 1.0 for _ in range(8)]
    rows = []
    for policy in POLICIES:
        for mode in ("kernel", "env"):
            if time.perf_counter() > deadline:
                rows.append({"num_envs": n, "policy": policy, "mode": mode, "skipped": "time budget"})
                continue
            rows.append(_timing(env, device, policy, mode, pool, ramp, min_seconds, min_steps))
    env.close()
    return rows


def run_check(device, num_envs=NUM_ENVS, agreement_envs: int = AGREEMENT_ENVS,
              agreement_steps: int = AGREEMENT_STEPS, min_seconds: float = MIN_SECONDS, min_steps: int = MIN_STEPS,
              budget_s: float = BUDGET_S) -> dict[str, Any]:
    """The whole check (see the module) as a JSON-ready record."""
    import torch

    from pneunet_env import __version__, fused_cuda

    t0 = time.perf_counter()
    res: dict[str, Any] = {"pneunet_env": __version__, "torch": torch.__version__,
                           "device": torch.cuda.get_device_name(device) if device.type == "cuda" else "simulator (cpu)",
                           "simulator": fused_cuda.SIMULATOR}
    try:
        import importlib.metadata as md

        res["numba_cuda"] = md.version("numba-cuda")
    except Exception:  # noqa: BLE001 - a version is informative only
        res["numba_cuda"] = None
    t = time.perf_counter()
    res["agreement"] = agreement(device, agreement_envs, agreement_steps)
    res["agreement"]["seconds"] = time.perf_counter() - t
    print(f"agreement: {agreement_envs} envs x {agreement_steps} steps, states within "
          f"{res['agreement']['max_rel_state']:.2e} relative; differing: {res['agreement']['differing'] or 'none'}",
          flush=True)
    res["speed"] = []
    for n in num_envs:
        if time.perf_counter() - t0 > budget_s:
            res["speed"] += [{"num_envs": n, "policy": p, "mode": m, "skipped": "time budget"}
                             for p in POLICIES for m in ("kernel", "env")]
            continue
        for r in speed(device, n, min_seconds, min_steps, t0 + budget_s):
            res["speed"].append(r)
            if "skipped" in r:
                print(f"N = {n:>8}  {r['mode']:<6} {r['policy']:<6} skipped (time budget)", flush=True)
            else:
                print(f"N = {n:>8}  {r['mode']:<6} {r['policy']:<6} {r['env_steps_per_s']:>14,.0f} env-steps/s "
                      f"({r['steps']} steps, {r['failed_solves']} failed solves)", flush=True)
    res["seconds"] = time.perf_counter() - t0
    return res


def plot(res: dict[str, Any], path: Path) -> None:
    """env-steps/s against N, kernel alone and end to end, per policy (log-log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pneunet_env.files import save_figure

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for mode, style in (("kernel", "-"), ("env", "--")):
        for policy, marker in (("random", "o"), ("ramp", "s")):
            rows = [r for r in res["speed"] if r["mode"] == mode and r["policy"] == policy and "skipped" not in r]
            if rows:
                ax.plot([r["num_envs"] for r in rows], [r["env_steps_per_s"] for r in rows], style, marker=marker,
                        label=f"{'kernel alone' if mode == 'kernel' else 'gym.make_vec'}, {policy}")
    ax.axhline(1e9, color="grey", lw=0.8, ls=":", label="target 1 G/s (ramp, 2^22, end to end)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("num_envs N")
    ax.set_ylabel("env-steps/s")
    ax.set_title(f"fused step's CUDA kernel: {res['device']}", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=checks.output_dir, default="bench_out/gpu",
                        help="output folder (gpu.json, gpu.png), checked before the run")
    parser.add_argument("--dry-run", action="store_true",
                        help="no GPU: the same code on the CPU under numba-cuda's simulator, at tiny N (a "
                             "subprocess with NUMBA_ENABLE_CUDASIM=1 PNEUNET_DISABLE_NUMBA=1)")


def run(args: argparse.Namespace) -> int:
    from pneunet_env import fused_cuda
    from pneunet_env.files import atomic_write_json

    out: Path = args.out
    if args.dry_run and not fused_cuda.SIMULATOR:
        env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PNEUNET_DISABLE_NUMBA": "1"}
        return subprocess.run([sys.executable, "-m", "pneunet_env.bench.gpu", "--dry-run", "--out", str(out)],
                              env=env, check=False).returncode
    import torch

    device = torch.device("cpu" if args.dry_run else "cuda")
    if not fused_cuda.kernel_available(device):
        why = "numba-cuda is not installed (pip install pneunet-env[gpu])" if not fused_cuda.HAVE_NUMBA_CUDA \
            else "no CUDA device"
        raise SystemExit(f"bench gpu: {why}: nothing measured (--dry-run checks the command on the CPU)")
    if args.dry_run:
        kw = {"num_envs": DRY["num_envs"], "agreement_envs": DRY["agreement_envs"],
              "agreement_steps": DRY["agreement_steps"], "min_seconds": DRY["min_seconds"],
              "min_steps": DRY["min_steps"]}
    else:
        kw = {}
    res = run_check(device, **kw)
    atomic_write_json(out / "gpu.json", res)
    plot(res, out / "gpu.png")
    print(f"wrote {out}/gpu.json and {out}/gpu.png ({res['seconds']:.0f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pneunet_env.bench.gpu", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
