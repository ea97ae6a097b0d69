"""The fused step's CUDA kernel (pneunet_env.fused_cuda), without a GPU: its source is the fused loop's with the
header replaced (the drift test), it runs under numba-cuda's simulator with the CPU fused step's results, the
vector env selects it or the masked solver by name, and it compiles offline for sm_80 and sm_90."""

from __future__ import annotations

import copy
import difflib
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneunet_env import fused, fused_cuda, task
from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

pytestmark = pytest.mark.skipif(not fused_cuda.HAVE_NUMBA_CUDA, reason="needs numba-cuda (the gpu extra)")

RUNNER = Path(__file__).with_name("cuda_simulator_run.py")

TOLERANCES = {"gradient_norm": 1e-12, "min_eigenvalue": 1e-12}
"""Relative tolerances of the kernel's fields under the simulator against the CPU fused step's (every other field:
equal). The two differ by round-off only: the simulator runs the formulas in Python, whose ``math.hypot`` and
eigenvalues differ from numba's compiled ones in the last bits (the feasibility study: 1e-28 and 3.6e-15)."""


def test_the_kernel_is_the_fused_loop_with_only_its_header_replaced():
    loop, kernel = fused_cuda.loop_source(), fused_cuda.kernel_source()
    diff = [d for d in difflib.ndiff(loop.splitlines(), kernel.splitlines()) if d[:1] in "+-"]
    assert [d[0] + d[2:].strip() for d in diff] == ["-" + fused_cuda.LOOP_HEADER] + \
        ["+" + h for h in fused_cuda.KERNEL_HEADER]
    # the per-env body is the loop's own, line for line, at its indentation
    body = loop.split(fused_cuda.LOOP_HEADER)[1]
    assert kernel.endswith(body) and len(body.splitlines()) > 80


def test_an_edit_of_the_loop_is_in_the_kernel():
    loop = fused_cuda.loop_source()
    line = "o_clipped[i] = a < -1.0 or a > 1.0"
    assert loop.count(line) == 1
    edited = loop.replace(line, "o_clipped[i] = a < -2.0 or a > 2.0")
    assert "a < -2.0" in fused_cuda.kernel_source(edited) and line not in fused_cuda.kernel_source(edited)
    # the kernel is built from the live loop's source, not from a copy
    assert fused_cuda.kernel_function().__code__.co_filename == "<pneunet_env.fused_cuda kernel>"
    assert fused_cuda.kernel_function().__code__.co_code != fused._make_loop(0, 0).__code__.co_code  # the header
    with pytest.raises(ValueError, match="once, found it 0 times"):
        fused_cuda.kernel_source(loop.replace(fused_cuda.LOOP_HEADER, "for i in range(action.shape[0]):"))
    with pytest.raises(ValueError, match="once, found it 2 times"):
        fused_cuda.kernel_source(loop + "\n    " + fused_cuda.LOOP_HEADER + "\n")


def test_the_kernels_params_carry_numbers_not_none():
    params = task.EnvParams.from_config(PneuNetGraspVectorEnv(1, backend="numpy").config)
    assert None in fused._loop_params(params.task)  # the CPU loop's carry None (the namespace, the damage rule)
    kp = fused_cuda.kernel_params(params)
    for record in (kp.task, kp.actuator, kp.solver):
        assert all(isinstance(v, (bool, int, float)) for v in record), record
    assert kp.task.ops == 0 and kp.task.pressure_max == params.task.pressure_max
    with pytest.raises(TypeError, match="must be numbers.*'x'"):
        fused_cuda.kernel_params(params._replace(solver=params.solver + ("x",)))


def test_the_vector_env_selects_the_kernel_or_the_masked_solver_by_name():
    pytest.importorskip("torch")
    env = PneuNetGraspVectorEnv(2, backend="torch")  # the CPU, no simulator: the masked solver
    assert env.kernel is False and env.fused is False
    assert PneuNetGraspVectorEnv(2, backend="torch", kernel=False).kernel is False
    with pytest.raises(ValueError, match="kernel=True needs numba-cuda .* device='cpu'"):
        PneuNetGraspVectorEnv(2, backend="torch", kernel=True)
    with pytest.raises(ValueError, match="backend='torch' only.*backend='numpy'"):
        PneuNetGraspVectorEnv(2, backend="numpy", kernel=False)
    with pytest.raises(ValueError, match="kernel must be True, False or None.*'yes'"):
        PneuNetGraspVectorEnv(2, backend="torch", kernel="yes")


def _policy(rng: np.random.Generator, n: int, t: int) -> np.ndarray:
    """Actions that load, unload, hold and clip: a quarter of the envs each random (beyond [-1, 1]), ramping up,
    up then down, up then holding."""
    a = rng.uniform(-1.5, 1.5, n)
    kind = np.arange(n) % 4
    a[kind == 1] = 1.0 if t % 20 < 16 else 0.0
    a[kind == 2] = 1.0 if t % 20 < 12 else -1.0
    a[kind == 3] = 1.0 if t % 20 < 11 else 0.0
    return a


def _record(overrides: dict, n: int, steps: int, seed: int) -> dict:
    """The CPU fused env's trajectory: before each step, its state, cache and action (copies)."""
    env = PneuNetGraspVectorEnv(n, backend="numba", squeeze_steps=14, hold_steps=6, **overrides)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    rows = []
    for t in range(steps):
        a = _policy(rng, n, t)
        rows.append((copy.deepcopy(env.state), copy.deepcopy(env._ev_cache), a.copy()))
        env.step(a.astype(np.float32)[:, None])
    return {"overrides": {"squeeze_steps": 14, "hold_steps": 6, **overrides}, "table": env._params.free_table,
            "steps": rows, "params": env._params}


def _fields(record, prefix=""):
    for name, v in zip(record._fields, record, strict=True):
        if isinstance(v, tuple):
            yield from _fields(v, f"{prefix}{name}.")
        else:
            yield prefix + name, v


@pytest.mark.slow
def test_the_kernel_under_the_simulator_is_the_cpu_fused_step():
    """The kernel (numba-cuda's simulator, plain-Python physics, in a subprocess) on each state of the CPU fused env's
    trajectories (loading, unloading, contact, holding, slips, autoresets, and failed solves under a small sub-step
    budget) gives the CPU fused step's results (:data:`TOLERANCES`); and the vector env through the kernel gives the
    masked solver's (torch), both autoreset modes."""
    pytest.importorskip("torch")
    cases = [_record({}, 24, 28, 1), _record({"max_substeps": 3, "max_pressure_step_kpa": 20.0}, 12, 14, 2)]
    refs = []
    for case in cases:
        ref = []
        for state, cache, a in case["steps"]:
            cache = copy.deepcopy(cache)
            ref.append((fused.fused_step(copy.deepcopy(state), a, case["params"], parallel=False, cache=cache), cache))
        refs.append(ref)
    # what the trajectories cover (so that the comparison below keeps covering it)
    steps = [r for ref in refs for r, _ in ref]
    assert any(s.solve.in_contact.any() for s in steps) and any(s.outcome.held.any() for s in steps)
    assert any(s.outcome.in_hold.any() for s in steps) and any(s.action_clipped.any() for s in steps)
    assert any((s.terminated | s.truncated).any() for s in steps)
    assert any(s.solver_failed.any() for s, _ in refs[1]) and not any(s.solver_failed.any() for s, _ in refs[0])
    assert any(not c[1].all() for case in cases for _, c, _ in case["steps"][1:])  # reset envs, cache invalid
    assert any((s.solve.evaluations > 4).any() for s in steps) and any((s.solve.evaluations == 0).any() for s in steps)

    spec = {"cases": [{k: c[k] for k in ("overrides", "table", "steps")} for c in cases], "env_steps": 14}
    path_in, path_out = Path(os.environ.get("TMPDIR", "/tmp")) / f"cuda_sim_{os.getpid()}.in", None
    path_out = path_in.with_suffix(".out")
    path_in.write_bytes(pickle.dumps(spec))
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PNEUNET_DISABLE_NUMBA": "1"}
    try:
        run = subprocess.run([sys.executable, str(RUNNER), str(path_in), str(path_out)], env=env, capture_output=True,
                             text=True, timeout=300)
        assert run.returncode == 0, run.stderr[-3000:]
        got = pickle.loads(path_out.read_bytes())
    finally:
        path_in.unlink(missing_ok=True)
        if path_out.exists():
            path_out.unlink()

    for ref, kernel in zip(refs, got["steps"], strict=True):
        for t, ((r, rc), (k, kc)) in enumerate(zip(ref, kernel, strict=True)):
            for (name, a), (name_k, b) in zip(_fields(r), _fields(k), strict=True):
                assert name == name_k
                if name.startswith("state.obj"):
                    continue  # the object (the state's own, passed on)
                tol = TOLERANCES.get(name.rsplit(".", 1)[-1])
                if tol is None:
                    np.testing.assert_array_equal(np.asarray(b), np.asarray(a), err_msg=f"step {t}: {name}")
                else:
                    np.testing.assert_allclose(b, a, rtol=tol, atol=0, err_msg=f"step {t}: {name}")
            np.testing.assert_array_equal(kc[1], rc[1])  # the evaluation cache: the same envs valid
            np.testing.assert_array_equal(kc[0][rc[1]], rc[0][rc[1]])

    worst = got["env"]
    assert worst["episode_ends.SameStep"] > 0 and worst["episode_ends.NextStep"] > 0
    assert worst["cache_valid_false.SameStep"] > 0 or worst["cache_valid_false.NextStep"] > 0
    flags = {k: v for k, v in worst.items() if k in ("terminated", "truncated") or k.startswith("info._")}
    assert not any(flags.values()), flags
    # without the free table (numba off) the kernel's solve is the scalar continuation, the masked solver's the
    # same formulas round by round: equal to round-off; only the work differs (the kernel's evaluation cache)
    work = ("episode_ends", "cache_valid", "info.solver_evaluations")
    beyond = {k: v for k, v in worst.items() if v > 1e-9 and not k.startswith(work)}
    assert not beyond, beyond


_NVVM = fused_cuda.HAVE_NUMBA_CUDA and not fused_cuda.SIMULATOR
if _NVVM:
    try:
        from numba.cuda.cudadrv.nvvm import NVVM

        NVVM()
    except Exception:  # noqa: BLE001 - NVVM's wheel absent: the offline compile cannot run
        _NVVM = False


@pytest.mark.slow
@pytest.mark.skipif(not _NVVM, reason="needs NVVM and nvJitLink (pip install numba-cuda[cu13])")
@pytest.mark.parametrize("cc", [(8, 0), (9, 0)])
def test_the_kernel_compiles_offline(cc):
    """The kernel compiles to PTX (NVVM) and a cubin (nvJitLink) for A100s (sm_80) and H100/H200s (sm_90) with no
    device, in one function: every call inlined, within the register file (255 a thread at most), little spilled."""
    params = task.EnvParams.from_config(PneuNetGraspVectorEnv(1, backend="numpy").config)
    report = fused_cuda.compile_report(params, cc)
    print(report)
    assert report["cc"] == f"sm_{cc[0]}{cc[1]}" and report["ptx_lines"] > 5000 and report["cubin_bytes"] > 0
    assert 64 <= report["registers"] <= 255
    assert report["spill_stores_bytes"] <= 256 and report["stack_bytes"] <= 512


_GPU = fused_cuda.HAVE_NUMBA_CUDA and not fused_cuda.SIMULATOR and _NVVM
if _GPU:
    import torch

    _GPU = fused_cuda.kernel_available(torch.device("cuda"))


@pytest.mark.skipif(not _GPU, reason="needs a CUDA device and numba-cuda")
def test_on_a_gpu_the_kernel_env_is_the_numba_env():
    """On a real GPU (FMA, libdevice): ``gym.make_vec(..., backend="torch", device="cuda")`` picks the kernel and gives
    the numba fused env's results through autoresets: the flags the same, the numbers to 1e-9 (the observations,
    float32, to 1e-6)."""
    import gymnasium as gym

    n, steps = 256, 60
    ref = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend="numba")
    gpu = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend="torch", device="cuda")
    assert gpu.unwrapped.kernel
    o1, _ = ref.reset(seed=3)
    o2, _ = gpu.reset(seed=3)
    np.testing.assert_allclose(o2.cpu().numpy(), o1, rtol=0, atol=1e-9)
    rng = np.random.default_rng(4)
    ended = 0
    for _ in range(steps):
        a = rng.uniform(-1.0, 2.0, (n, 1)).astype(np.float32)
        r1, r2 = ref.step(a), gpu.step(torch.from_numpy(a).cuda())
        for j in (2, 3):
            np.testing.assert_array_equal(r2[j].cpu().numpy(), r1[j])
        np.testing.assert_allclose(r2[0].cpu().numpy(), r1[0], rtol=0, atol=1e-6)  # float32 observations
        np.testing.assert_allclose(r2[1].cpu().numpy(), r1[1], rtol=1e-9, atol=1e-9)
        for key in ("curvature_per_m", "contact_force_kpa", "indentation_mm", "pressure_kpa"):
            np.testing.assert_allclose(r2[4][key].cpu().numpy(), r1[4][key], rtol=1e-9, atol=1e-9, err_msg=key)
        ended += int(np.sum(r1[2] | r1[3]))
    assert ended > 0
