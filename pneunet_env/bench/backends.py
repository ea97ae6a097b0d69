"""The vector env's throughput by backend and device, swept over N, against CartPoleVectorEnv in the same run.

``pneunet-grasp bench speed --backend numba numpy torch --device cpu cuda`` (what :func:`run_sweep` measures): for
every backend (and, for torch, every device) and every N, the env-steps per second of
``gym.make_vec("PneuNetGrasp-v1", num_envs=N, backend=..., device=...)`` stepped with the same seeded random actions
(through its autoresets), beside Gymnasium's ``CartPoleVectorEnv`` at the same N, and:

* the speedup over the numba backend at the same N (when numba was measured);
* the unconverged fraction: steps whose solve did not converge (``info["solver_converged"]`` false), which the env
  flags and truncates; a backend's throughput only counts where this is no more than numba's;
* the memory per env: the state kept between steps (host, or device tensors) and, on a GPU, the peak of
  ``torch.cuda.max_memory_allocated`` over the run divided by N.

It writes ``backends.json`` and ``backends.png`` (env-steps/s against N, one line per backend and device, CartPole's
dashed). Timings are wall-clock: on a GPU every step ends with a host sync (its observations are read back for the
autoreset test), so they are what a training loop sees.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.bench import machine as bench_machine
from pneunet_env.files import atomic_write_json, save_figure

__all__ = ["run_sweep", "format_sweep", "plot_sweep"]


def _sync(device) -> None:
    if device is not None and str(device).startswith("cuda"):
        import torch

        torch.cuda.synchronize()


def _measure(backend: str, device, n: int, steps: int, seed: int, compile: bool) -> dict[str, Any]:
    import gymnasium as gym

    import pneunet_env  # noqa: F401

    kw: dict[str, Any] = {"backend": backend}
    if backend == "torch":
        kw.update(device=device, compile=compile)
    cuda = backend == "torch" and str(device).startswith("cuda")
    if cuda:
        import torch

        torch.cuda.reset_peak_memory_stats()
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=n, **kw)
    rng = np.random.default_rng(seed + n)
    acts = rng.uniform(-1.0, 1.0, (steps + 1, n, 1)).astype(np.float32)
    if backend == "torch":
        import torch

        acts = torch.from_numpy(acts).to(device)
    env.reset(seed=seed)
    env.step(acts[0])  # warm-up (numba's threads, torch.compile's first compilation)
    _sync(device)
    unconverged = 0
    t0 = time.perf_counter()
    for a in acts[1:]:
        info = env.step(a)[4]
        unconverged += int((~info["solver_converged"]).sum())
    _sync(device)
    dt = time.perf_counter() - t0
    row = {
        "backend": backend,
        "device": str(device) if backend == "torch" else "cpu",
        "compile": bool(compile and backend == "torch"),
        "num_envs": n,
        "steps": steps,
        "steps_per_s": n * steps / dt,
        "unconverged_fraction": unconverged / (n * steps),
        "state_bytes_per_env": env.unwrapped.state_nbytes() / n,
    }
    if cuda:
        import torch

        row["gpu_peak_bytes_per_env"] = torch.cuda.max_memory_allocated() / n
    env.close()
    return row


def _cartpole(n: int, steps: int, seed: int) -> float:
    import gymnasium as gym

    env = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
    acts = np.random.default_rng(seed).integers(0, 2, (steps + 1, n))
    env.reset(seed=seed)
    env.step(acts[0])
    t0 = time.perf_counter()
    for a in acts[1:]:
        env.step(a)
    dt = time.perf_counter() - t0
    env.close()
    return n * steps / dt


def run_sweep(backends: list[str], devices: list[str], num_envs: list[int], env_steps: int = 400_000,
              min_steps: int = 5, max_steps: int = 200, seed: int = 0, compile: bool = False) -> dict[str, Any]:
    """Measure every backend (torch: on every device, eager and, with ``compile``, compiled) at every N; see the
    module docstring.

    ``env_steps``: about this many env-steps per point (``steps = env_steps // N`` within ``[min_steps,
    max_steps]``).
    """
    from pneunet_env.physics._jit import HAVE_NUMBA

    if "numba" in backends and not HAVE_NUMBA:
        raise ValueError("backend 'numba' needs numba (pip install pneunet-env[fast])")
    # torch: eager on every device, and compiled too with ``compile``
    combos = [(b, d, c) for b in backends for d in (devices if b == "torch" else [None])
              for c in ((False, True) if b == "torch" and compile else (False,))]
    rows, cartpole = [], {}
    t_start = time.perf_counter()
    for n in num_envs:
        steps = int(min(max_steps, max(min_steps, env_steps // n)))
        cartpole[n] = _cartpole(n, steps, seed)
        for b, d, c in combos:
            row = _measure(b, d, n, steps, seed, c)
            row["cartpole_steps_per_s"] = cartpole[n]
            row["ratio_to_cartpole"] = row["steps_per_s"] / cartpole[n]
            rows.append(row)
    numba = {r["num_envs"]: r for r in rows if r["backend"] == "numba"}
    for r in rows:
        ref = numba.get(r["num_envs"])
        r["speedup_over_numba"] = None if ref is None else r["steps_per_s"] / ref["steps_per_s"]
    machine = bench_machine.machine()  # after the runs: numba's threading layer is chosen at the first parallel one
    machine["load_average"] = bench_machine.load_average()
    if "torch" in backends:
        import torch

        machine["torch"] = torch.__version__
        if any(str(d).startswith("cuda") for d in devices) and torch.cuda.is_available():
            machine["gpu"] = torch.cuda.get_device_name(0)
            machine["cuda"] = torch.version.cuda
    return {"rows": rows, "machine": machine, "compile": compile, "wall_s": time.perf_counter() - t_start}


def _label(r: dict[str, Any]) -> str:
    if r["backend"] != "torch":
        return r["backend"]
    return f"torch ({r['device']}{', compiled' if r['compile'] else ''})"


def format_sweep(res: dict[str, Any]) -> str:
    """The printed table."""
    m = res["machine"]
    layer = f", numba {m['numba_threads']} threads, layer {m['threading_layer']}" if m.get("numba") else ""
    head = (f"PneuNetGrasp-v1 vector env by backend ({m['cpus']} CPUs{layer}"
            + (f", GPU {m['gpu']}" if "gpu" in m else "") + ")")
    lines = [head, "",
             f"{'backend':<26}{'N':>9}{'env-steps/s':>14}{'CartPoleVec':>14}{'ratio':>8}{'vs numba':>10}"
             f"{'unconverged':>13}{'host B/env':>12}{'GPU B/env':>11}"]
    for r in res["rows"]:
        vs = "-" if r["speedup_over_numba"] is None else f"{r['speedup_over_numba']:.2f}x"
        gpu = f"{r['gpu_peak_bytes_per_env']:.0f}" if "gpu_peak_bytes_per_env" in r else "-"
        lines.append(f"{_label(r):<26}{r['num_envs']:>9,}{r['steps_per_s']:>14,.0f}{r['cartpole_steps_per_s']:>14,.0f}"
                     f"{r['ratio_to_cartpole']:>8.3f}{vs:>10}{r['unconverged_fraction']:>13.2e}"
                     f"{r['state_bytes_per_env']:>12.0f}{gpu:>11}")
    return "\n".join(lines)


def plot_sweep(res: dict[str, Any], path: Path) -> None:
    """Env-steps/s against N (log-log): one line per backend and device, CartPoleVectorEnv dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.6))
    labels = sorted({_label(r) for r in res["rows"]})
    for lab in labels:
        rows = sorted((r for r in res["rows"] if _label(r) == lab), key=lambda r: r["num_envs"])
        ax.loglog([r["num_envs"] for r in rows], [r["steps_per_s"] for r in rows], "o-", label=lab)
    cp = sorted({(r["num_envs"], r["cartpole_steps_per_s"]) for r in res["rows"]})
    ax.loglog([c[0] for c in cp], [c[1] for c in cp], "k--", lw=1, label="CartPoleVectorEnv (same run)")
    m = res["machine"]
    ax.set_xlabel("number of envs N")
    ax.set_ylabel("env-steps per second")
    ax.set_title(f"PneuNetGrasp-v1 by backend: {m['cpus']} CPUs" + (f", {m['gpu']}" if "gpu" in m else ""),
                 fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def write(res: dict[str, Any], out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "backends.json", res, indent=1)
    plot_sweep(res, out / "backends.png")
