"""The CUDA kernel under numba-cuda's simulator, run by tests/test_cuda_kernel.py in a subprocess.

Run as ``NUMBA_ENABLE_CUDASIM=1 PNEUNET_DISABLE_NUMBA=1 python tests/cuda_simulator_run.py IN OUT`` (the variables
must be set before numba is imported). ``IN``: a pickle of the cases the parent recorded with the CPU fused step
(``{"cases": [{"overrides", "table", "steps": [(state, cache, action), ...]}, ...], "env_steps": int}``). ``OUT``: a
pickle of the kernel's :class:`~pneunet_env.task.Step` for each recorded step (as numpy records), and the largest
differences between the vector env through the kernel (``kernel=True``) and through the masked solver
(``kernel=False``), both modes of autoreset.
"""

from __future__ import annotations

import os
import pickle
import sys

import numpy as np
import torch


def _to_torch(record):
    if isinstance(record, tuple):
        return type(record)(*(_to_torch(v) for v in record)) if hasattr(record, "_fields") \
            else tuple(_to_torch(v) for v in record)
    if isinstance(record, np.ndarray):
        return torch.from_numpy(record.copy())
    if hasattr(record, "__dataclass_fields__"):  # a GraspObject
        return type(record)(**{f: _to_torch(getattr(record, f)) for f in record.__dataclass_fields__})
    return record


def _to_numpy(record):
    if isinstance(record, tuple):
        return type(record)(*(_to_numpy(v) for v in record)) if hasattr(record, "_fields") \
            else tuple(_to_numpy(v) for v in record)
    if torch.is_tensor(record):
        return record.numpy().copy()
    return record


def _steps(cases):
    """The kernel's step on each recorded state (from the CPU fused step's trajectory), as numpy records."""
    from pneunet_env import fused_cuda, task
    from pneunet_env.config import load_config
    from pneunet_env.physics.xp import torch_ops

    cpu = torch.device("cpu")
    results = []
    for case in cases:
        params = task.EnvParams.from_config(load_config(None, **case["overrides"]), torch_ops(cpu))
        params = params._replace(free_table=case["table"])  # the parent's (numba is off here: none is built)
        got = []
        for state, cache, action in case["steps"]:
            cache = _to_torch(cache)
            step = fused_cuda.DeviceStep(params, cache, cpu)(_to_torch(state), torch.from_numpy(action.copy()))
            got.append((_to_numpy(step), _to_numpy(cache)))
        results.append(got)
    return results


def _env_differences(n_steps: int) -> dict[str, float]:
    """The vector env through the kernel against the masked solver's (torch, CPU), the same seeds and actions: the
    largest difference of each returned value (flags: the count that differ), both autoreset modes."""
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

    worst: dict[str, float] = {}

    def note(key, a, b):
        if torch.is_tensor(a):
            d = float((a.double() - b.double()).abs().max()) if a.dtype != torch.bool else float((a != b).sum())
            worst[key] = max(worst.get(key, 0.0), d)

    n = 16
    for mode in ("SameStep", "NextStep"):
        kw = dict(backend="torch", device="cpu", squeeze_steps=5, hold_steps=5, autoreset_mode=mode, info_level="full")
        envs = [PneuNetGraspVectorEnv(n, kernel=k, **kw) for k in (True, False)]
        assert envs[0].kernel and not envs[1].kernel
        first = [e.reset(seed=7) for e in envs]
        note("reset_obs", first[0][0], first[1][0])
        rng = np.random.default_rng(11)
        ends = 0
        for _ in range(n_steps):
            action = torch.from_numpy(rng.uniform(-0.6, 1.4, (n, 1)))
            a, b = (e.step(action) for e in envs)
            for name, x, y in zip(("obs", "reward", "terminated", "truncated"), a[:4], b[:4], strict=True):
                note(name, x, y)
            assert a[4].keys() == b[4].keys()
            for key, x in a[4].items():
                if key.startswith("final"):
                    continue
                note("info." + key, x, b[4][key])
            ends += int((a[2] | a[3]).sum())
            if "final_obs" in a[4]:
                note("final_obs", a[4]["final_obs"], b[4]["final_obs"])
        worst["episode_ends." + mode] = float(ends)
        worst["cache_valid_false." + mode] = float((~envs[0]._ev_cache[1]).sum())
    return worst


def main(path_in: str, path_out: str) -> None:
    if not (os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" and os.environ.get("PNEUNET_DISABLE_NUMBA")):
        raise SystemExit("run with NUMBA_ENABLE_CUDASIM=1 PNEUNET_DISABLE_NUMBA=1")
    with open(path_in, "rb") as f:
        spec = pickle.load(f)
    out = {"steps": _steps(spec["cases"]), "env": _env_differences(spec["env_steps"])}
    with open(path_out, "wb") as f:
        pickle.dump(out, f)


if __name__ == "__main__":
    main(*sys.argv[1:])
