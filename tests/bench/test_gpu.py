"""``pneunet-grasp bench gpu`` (pneunet_env.bench.gpu) without a GPU: its ramp is bench speed's, it says in one line
that there is no device, and its dry run (the simulator) writes the JSON and the PNG."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pneunet_env import fused_cuda
from pneunet_env.bench import gpu
from pneunet_env.bench.speed import ramp_policy

torch = pytest.importorskip("torch")


def test_the_device_ramp_is_bench_speeds_ramp():
    obs = np.concatenate([np.linspace(0.0, 1.0, 401), [0.0, 33.9 / 70.0, np.nextafter(np.float32(0.3), 1.0)],
                          np.random.default_rng(0).uniform(0, 1, 200)]).astype(np.float32)[:, None]
    want = ramp_policy()(obs)
    got = gpu.torch_ramp()(torch.from_numpy(obs)).numpy()
    assert got.dtype == want.dtype == np.float32 and got.shape == want.shape
    np.testing.assert_array_equal(got, want)
    assert (want == 0.0).any() and (want > 0.0).any()  # both the climb and the hold


@pytest.mark.skipif(fused_cuda.HAVE_NUMBA_CUDA and fused_cuda.kernel_available(torch.device("cuda")),
                    reason="a CUDA device is here: the check would run")
def test_without_a_gpu_it_says_so_in_one_line(tmp_path):
    with pytest.raises(SystemExit) as exc:
        gpu.main(["--out", str(tmp_path / "out")])
    message = str(exc.value.code)
    assert message.startswith("bench gpu: ") and "nothing measured" in message and "\n" not in message
    assert not (tmp_path / "out" / "gpu.json").exists()


@pytest.mark.slow
@pytest.mark.skipif(not fused_cuda.HAVE_NUMBA_CUDA, reason="needs numba-cuda (the gpu extra)")
def test_the_dry_run_checks_and_times_under_the_simulator(tmp_path):
    """About 10 s: the whole check at tiny N on the CPU (a subprocess under the simulator)."""
    out = tmp_path / "gpu"
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_ENABLE_CUDASIM", "PNEUNET_DISABLE_NUMBA")}
    run = subprocess.run([sys.executable, "-m", "pneunet_env.bench.gpu", "--dry-run", "--out", str(out)], env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    res = json.loads((out / "gpu.json").read_text())
    assert res["simulator"] is True and res["device"] == "simulator (cpu)"
    assert (out / "gpu.png").stat().st_size > 1000
    ag = res["agreement"]
    assert ag["num_envs"] == gpu.DRY["agreement_envs"] and ag["steps"] == gpu.DRY["agreement_steps"]
    assert ag["max_rel_state"] <= 1e-9 and ag["cpu_failed_solves"] == 0
    # the reference is numpy's step, without the evaluation cache: only the work counts may differ
    assert set(ag["differing"]) <= {"state.eq.evaluations", "solve.evaluations"}, ag["differing"]
    rows = {(r["num_envs"], r["mode"], r["policy"]): r for r in res["speed"]}
    assert set(rows) == {(n, m, p) for n in gpu.DRY["num_envs"] for m in ("kernel", "env") for p in gpu.POLICIES}
    assert all(r["env_steps_per_s"] > 0 and r["failed_solves"] == 0 for r in rows.values())
    assert "agreement:" in run.stdout and "wrote" in run.stdout
