"""The fused step as one CUDA kernel (numba-cuda): :func:`pneunet_env.fused.fused_step` on a GPU's threads.

The kernel is the fused loop itself (:func:`pneunet_env.fused._make_loop`), generated from its source: the one
line ``for i in numba.prange(action.shape[0]):`` becomes ``i = cuda.grid(1)`` and ``if i < action.shape[0]:``,
and the per-env body, at the same indentation, is the CPU loop's, line for line (:func:`kernel_source`; the
tests check that the transform touches the header only, so the two cannot drift). It calls the same ``@njit``
functions (the solve, the free table, eq. 3.1's contact, the rules), which numba-cuda compiles for the device.

Around the body, two edits: the task's params carry numbers where the CPU loop's carry ``None`` (a kernel takes
no ``None``: :func:`kernel_params`), and the free table is built on the CPU and copied to the device once
(:class:`DeviceStep`).

:class:`DeviceStep` runs the kernel on torch tensors of a CUDA device, read in place through
``__cuda_array_interface__`` (no copy), on torch's current stream; the record it returns is a
:class:`~pneunet_env.task.Step` of tensors there, so the torch backend's autoreset, ``_keep_where`` and info run
on the device as they do for the round-by-round masked solver. The vector env uses it for ``backend="torch"`` on
a CUDA device where numba-cuda is installed (``pip install pneunet-env[gpu]``); ``kernel=False`` selects the
masked solver instead.

Without a GPU, numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``, set before numba is imported) runs the same
kernel in Python, thread by thread, on CPU tensors (their numpy views): that is how the tests run it (with
``PNEUNET_DISABLE_NUMBA=1``: under the simulator the ``@njit`` functions must be plain Python).
"""

from __future__ import annotations

import importlib.util
import inspect
import os
from typing import Any, NamedTuple

import numpy as np

from pneunet_env import fused, task
from pneunet_env.physics import _jit, contact, xp
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.task import TaskState

__all__ = ["HAVE_NUMBA_CUDA", "SIMULATOR", "LOOP_HEADER", "KERNEL_HEADER", "kernel_source", "kernel_params",
           "kernel_available", "new_device_cache", "DeviceStep", "THREADS_PER_BLOCK"]

SIMULATOR = bool(os.environ.get("NUMBA_ENABLE_CUDASIM")) and os.environ.get("NUMBA_ENABLE_CUDASIM") != "0"
"""Whether numba-cuda's simulator is on (the kernel then runs in Python on CPU arrays)."""

HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
"""Whether numba-cuda is installed (the gpu extra; imported when first used: it takes about 0.4 s)."""


def _cuda():
    """numba-cuda's ``numba.cuda`` (imported here, on first use)."""
    from numba import cuda

    return cuda

LOOP_HEADER = "for i in numba.prange(action.shape[0]):"
"""The fused loop's header (:func:`pneunet_env.fused._make_loop`), the only line the kernel replaces."""
KERNEL_HEADER = ("i = cuda.grid(1)", "if i < action.shape[0]:")
"""The kernel's header: one env per thread, the grid's spare threads doing nothing."""
THREADS_PER_BLOCK = 128
"""Threads per block of the launch (the kernel uses about 255 registers a thread: 2 blocks fit an SM's 65,536)."""


def loop_source() -> str:
    """The source of :func:`pneunet_env.fused._make_loop` (the CPU loop's factory)."""
    return inspect.getsource(fused._make_loop)


def kernel_source(source: str | None = None) -> str:
    """The kernel's factory source: ``source`` (default :func:`loop_source`) with :data:`LOOP_HEADER`'s line replaced
    by :data:`KERNEL_HEADER`'s two lines at its indentation; every other line unchanged. ``ValueError`` unless the
    header is found exactly once."""
    source = loop_source() if source is None else source
    lines = source.splitlines(keepends=True)
    where = [j for j, line in enumerate(lines) if line.strip() == LOOP_HEADER]
    if len(where) != 1:
        raise ValueError(f"the fused loop's source must hold the line {LOOP_HEADER!r} once, found it {len(where)} "
                         f"times")
    j = where[0]
    indent = lines[j][:len(lines[j]) - len(lines[j].lstrip())]
    lines[j:j + 1] = [f"{indent}{KERNEL_HEADER[0]}\n", f"{indent}{KERNEL_HEADER[1]}\n"]
    return "".join(lines)


def _globals() -> dict[str, Any]:
    """The names the kernel's body reads: the fused module's, with ``cuda`` and, where numba is off (the simulator's
    tests), the contact and the rules as plain Python (the fused module builds them with numba only)."""
    names = dict(vars(fused))
    names["cuda"] = _cuda()
    if "_contact" not in names:
        names["_contact"] = contact.make_contact(_jit.njit(xp.scalar_max), _jit.njit(xp.scalar_where),
                                                 jit=_jit.njit)[1]
        names["_rules"] = task.make_rules(_jit.njit(fused._flag_value), _jit.njit(xp.scalar_max), jit=_jit.njit)
    return names


_KERNEL = None


def kernel_function():
    """The kernel as a Python function (:func:`kernel_source`'s loop, built in the fused module's names)."""
    if not HAVE_NUMBA_CUDA:
        raise RuntimeError("the CUDA kernel needs numba-cuda (pip install pneunet-env[gpu])")
    names = _globals()
    exec(compile(kernel_source(), "<pneunet_env.fused_cuda kernel>", "exec"), names)
    return names["_make_loop"](0, 3)


def _kernel():
    """The compiled kernel (``cuda.jit`` of :func:`kernel_function`; compiled for the device at first launch)."""
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _cuda().jit(kernel_function())
    return _KERNEL


class KernelParams(NamedTuple):
    """The numbers the kernel takes besides the arrays (see :func:`kernel_params`)."""

    task: Any  # the task's params, numbers only
    actuator: Any
    solver: tuple
    volume_scale: float
    spacing: float


def kernel_params(params: task.EnvParams) -> KernelParams:
    """The params as the kernel takes them: the fused loop's (:func:`pneunet_env.fused._loop_params`), with ``0`` for
    each ``None`` (the namespace and the strings, which the loop does not read: a kernel takes no ``None``), the
    volume scale ``0.0`` where there is none, and the free table's spacing."""
    tp = fused._loop_params(params.task)
    tp = tp._replace(**{f: 0 for f, v in zip(tp._fields, tp, strict=True) if v is None})
    for record in (tp, params.actuator, params.solver):
        bad = [v for v in record if not isinstance(v, (bool, int, float, np.number))]
        if bad:
            raise TypeError(f"the kernel's params must be numbers, got {bad!r} in {record!r}")
    vs = params.volume_scale
    return KernelParams(tp, params.actuator, tuple(params.solver), 0.0 if vs is None else float(vs),
                        fused._table(params)[1])


def kernel_available(device) -> bool:
    """Whether the kernel can run on ``device`` (a ``torch.device``): numba-cuda installed and a CUDA device it
    sees, or, under the simulator, the CPU."""
    if not HAVE_NUMBA_CUDA:
        return False
    if SIMULATOR:
        return device.type == "cpu"
    return device.type == "cuda" and _cuda().is_available()


def new_device_cache(n: int, device) -> tuple[Any, Any]:
    """:func:`pneunet_env.fused.new_cache` as torch tensors on ``device``: ``(values (n, 10) float64, valid (n,))``."""
    import torch

    return (torch.zeros((n, fused.EV_FIELDS), dtype=torch.float64, device=device),
            torch.zeros(n, dtype=torch.bool, device=device))


def _view(a):
    """A tensor as the kernel reads it: its CUDA array (through ``__cuda_array_interface__``, no copy; no stream sync:
    the kernel runs on torch's current stream, after what torch queued there), or, on the CPU under the simulator,
    its numpy view (no copy either)."""
    if a.is_cuda:
        return _cuda().as_cuda_array(a, sync=False)
    return a.numpy()


def _views(record):
    """:func:`_view` of every tensor of a (nested) record."""
    if isinstance(record, tuple):
        return type(record)(*(_views(v) for v in record)) if hasattr(record, "_fields") \
            else tuple(_views(v) for v in record)
    return _view(record)


_TORCH_DTYPES = {bool: "bool", np.int64: "int64", np.float64: "float64"}


class DeviceStep:
    """:func:`pneunet_env.fused.fused_step` on tensors of one device, as one kernel launch: ``step(state, action)``
    returns the :class:`~pneunet_env.task.Step`, of tensors on the device (the same record as the fused step's; the
    previous equilibrium kept where a solve failed by :func:`pneunet_env.task._keep_where`, with no host sync).

    Args:
        params: the env's :class:`~pneunet_env.task.EnvParams` on the device's namespace (``params.ops``).
        cache: ``(values, valid)`` from :func:`new_device_cache`, kept between steps and updated in place (the
            caller marks the envs it resets invalid), as :func:`~pneunet_env.fused.fused_step`'s.
        device: the ``torch.device`` (a CUDA one; the CPU under the simulator).
    """

    def __init__(self, params: task.EnvParams, cache: tuple[Any, Any], device) -> None:
        import torch

        if not kernel_available(device):
            raise ValueError(f"the CUDA kernel cannot run on device {str(device)!r} (it needs numba-cuda and a CUDA "
                             f"device: pip install pneunet-env[gpu])")
        self._torch, self._device, self._params, self._cache = torch, device, params, cache
        self._kp = kernel_params(params)
        # the free table, built on the CPU (EnvParams), copied to the device once
        self._table = torch.tensor(np.array(fused._table(params)[0]), device=device)
        self._kernel = _kernel()
        self._streams: dict[int, Any] = {}  # torch's streams as numba-cuda's, by handle

    def _empty(self, record_type, n: int, dtypes: dict[str, Any]):
        torch = self._torch
        return record_type(*(torch.empty(n, dtype=getattr(torch, _TORCH_DTYPES[dtypes.get(f, np.float64)]),
                                         device=self._device) for f in record_type._fields))

    def __call__(self, state: task.EnvState, action) -> task.Step:
        """One step of every env (``action``: float64 ``(N,)`` on the device, finite)."""
        torch, n = self._torch, action.shape[0]
        obj, kp = state.obj, self._kp
        solve = self._empty(Equilibrium, n, fused._SOLVE_DTYPES)._replace(object_stiffness=obj.stiffness.clone(),
                                                                          object_curvature=obj.curvature.clone())
        outcome = self._empty(task.Outcome, n, fused._OUTCOME_DTYPES)._replace(
            state=self._empty(TaskState, n, fused._STATE_DTYPES))
        obs = torch.empty((n, 1 if self._params.volume_scale is None else 2), dtype=torch.float32,
                          device=self._device)
        out = fused.Outputs(torch.empty(n, dtype=torch.float64, device=self._device), solve,
                            torch.empty(n, dtype=torch.bool, device=self._device),
                            torch.empty(n, dtype=torch.bool, device=self._device), outcome, obs)
        ev_cache, ev_valid = self._cache
        args = (_view(action.contiguous()), _view(state.command), _views(state.eq), _view(obj.stiffness),
                _view(obj.curvature), _views(state.thresholds), _views(state.task), kp.task, kp.volume_scale,
                kp.actuator, kp.solver, _view(self._table), kp.spacing, _view(ev_cache), _view(ev_valid), _views(out))
        self.launch(args, n)
        new_eq = task._keep_where(out.failed, state.eq, solve, self._params.ops)
        new = task.EnvState(out.command, new_eq, obj, state.thresholds, outcome.state)
        return task.Step(new, out.obs, outcome.reward, outcome.terminated, outcome.truncated, solve, outcome,
                         out.clipped, out.failed)

    def launch(self, args: tuple, n: int) -> None:
        """The kernel over ``n`` envs on ``args`` (the fused loop's, as views), on torch's current stream."""
        if n == 0:
            return
        tpb = min(THREADS_PER_BLOCK, n)
        blocks = (n + tpb - 1) // tpb
        if self._device.type == "cuda":
            handle = self._torch.cuda.current_stream(self._device).cuda_stream
            stream = self._streams.get(handle)
            if stream is None:
                stream = self._streams[handle] = _cuda().external_stream(handle)
            self._kernel[blocks, tpb, stream](*args)
        else:  # the simulator
            self._kernel[blocks, tpb](*args)


def example_args(params: task.EnvParams, n: int = 4) -> tuple:
    """The kernel's arguments for ``n`` envs as host numpy arrays (zeros: their types are what counts), e.g. to type
    it for :func:`compile_report`. Arrays on a device have the same numba types (C-contiguous, mutable)."""
    kp = kernel_params(params)
    f = np.zeros(n)
    solve = fused._empty(Equilibrium, n, fused._SOLVE_DTYPES)
    eq = Equilibrium(*(np.zeros(n, a.dtype) for a in solve))
    outcome = fused._empty(task.Outcome, n, fused._OUTCOME_DTYPES)._replace(
        state=fused._empty(TaskState, n, fused._STATE_DTYPES))
    out = fused.Outputs(np.empty(n), solve, np.empty(n, bool), np.empty(n, bool), outcome,
                        np.empty((n, 1 if params.volume_scale is None else 2), np.float32))
    cache, valid = fused.new_cache(n)
    state = TaskState(np.zeros(n, np.int64), np.zeros(n, bool), np.zeros(n, bool), f.copy())
    return (f.copy(), f.copy(), eq, f.copy(), f.copy(), task.Thresholds(f.copy(), f.copy(), f.copy()), state, kp.task,
            kp.volume_scale, kp.actuator, kp.solver, np.array(fused._table(params)[0]), kp.spacing, cache, valid, out)


def compile_report(params: task.EnvParams, cc: tuple[int, int]) -> dict[str, Any]:
    """The kernel compiled offline for compute capability ``cc`` (e.g. ``(9, 0)``: H100/H200), with no device: PTX by
    ``numba.cuda.compile_ptx`` (NVVM), then a cubin by nvJitLink (ptxas), whose log gives the kernel's resources.

    Returns ``{"cc", "ptx_lines", "registers", "spill_stores_bytes", "spill_loads_bytes", "stack_bytes",
    "cubin_bytes", "compile_s"}`` (registers per thread; spills and stack per thread, bytes). Needs numba-cuda's
    NVVM and nvJitLink wheels (``pip install numba-cuda[cu13]``). The device functions the kernel calls ask numba-cuda
    for the current device's capability: with none, ``cc`` is given in its place while compiling."""
    import re
    import time
    import types as _types

    import numba
    from numba.cuda import dispatcher as _dispatcher

    cuda = _cuda()

    if SIMULATOR or not HAVE_NUMBA_CUDA:
        raise RuntimeError("compile_report needs numba-cuda without its simulator")
    sig = tuple(numba.typeof(a) for a in example_args(params))
    fake = _types.SimpleNamespace(compute_capability=tuple(cc))
    original = _dispatcher.get_current_device
    _dispatcher.get_current_device = lambda: fake
    t0 = time.perf_counter()
    try:
        ptx, _ = cuda.compile_ptx(kernel_function(), sig, cc=tuple(cc))
    finally:
        _dispatcher.get_current_device = original
    compile_s = time.perf_counter() - t0
    from cuda.bindings import nvjitlink

    data = ptx.encode()
    handle = nvjitlink.create(2, [f"-arch=sm_{cc[0]}{cc[1]}", "-verbose"])
    try:
        nvjitlink.add_data(handle, nvjitlink.InputType.PTX, data, len(data), "kernel")
        nvjitlink.complete(handle)
        log = bytearray(nvjitlink.get_info_log_size(handle))
        nvjitlink.get_info_log(handle, log)
        cubin = nvjitlink.get_linked_cubin_size(handle)
    finally:
        nvjitlink.destroy(handle)
    text = log.decode(errors="replace")
    # ptxas's lines for the entry (the kernel): the last "stack frame" line before its "Used N registers"
    used = list(re.finditer(r"Used (\d+) registers", text))
    frames = list(re.finditer(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads",
                              text[:used[-1].start()]))
    stack, stores, loads = (int(g) for g in frames[-1].groups())
    return {"cc": f"sm_{cc[0]}{cc[1]}", "ptx_lines": len(ptx.splitlines()), "registers": int(used[-1].group(1)),
            "spill_stores_bytes": stores, "spill_loads_bytes": loads, "stack_bytes": stack, "cubin_bytes": int(cubin),
            "compile_s": round(compile_s, 2)}
