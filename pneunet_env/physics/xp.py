"""The array operations the physics and the task are written against: one namespace each for Python scalars (one
env), numpy and torch.

The energy (:func:`pneunet_env.physics.mechanics.make_terms`), the 2x2 eigen helpers
(:func:`pneunet_env.physics.solver.make_sym2`), the contact (:func:`pneunet_env.physics.contact.make_contact`), the
masked solver (:mod:`pneunet_env.physics.masked`) and the task's rules (:mod:`pneunet_env.task`) are written once
against the handful of operations of :class:`Ops`, the way SciPy's array-API code is written against an
``array_namespace``. The namespace is chosen once, where an env or a batch is built (:data:`SCALAR` for one env,
:data:`NUMPY`, :func:`torch_ops` for a device), and carried in its params
(:attr:`pneunet_env.task.TaskParams.ops`), so that no function of the step tests the type of its input.
:func:`ops_for` picks the namespace of an array, for code at the edges. torch is imported only when its namespace
is asked for, so the core imports without it.

A namespace pickles by name (:meth:`Ops.__reduce__`): an unpickled one is the same object as this process's.

The scalar kernels (:mod:`pneunet_env.physics.mechanics`, :mod:`~pneunet_env.physics.contact`, the solver) are
compiled by numba from :func:`scalar_where` and :func:`scalar_max` (``a if a > b else b``); :data:`SCALAR`'s
``maximum`` and ``minimum`` are Python's ``max`` and ``min`` (what one env has always computed with: the first
argument at a tie, so ``max(-0.0, 0.0)`` is ``-0.0``, where numpy's gives ``0.0``).

Why not ``array_api_compat`` alone: the kernels mix arrays with Python floats (``where(c, 1.0, x)``,
``maximum(x, 0.0)``), which the array API only allows from its 2024 revision on; the torch namespace here makes
those calls keep float64 (torch's ``where`` of two Python floats gives float32) and keeps every result on the
tensors' device.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

__all__ = ["Ops", "SCALAR", "NUMPY", "ops_for", "ops_named", "torch_ops", "is_torch", "copy", "to_host", "identity",
           "scalar_where", "scalar_max"]


class Ops(NamedTuple):
    """An array namespace: elementwise operations that accept Python scalars beside arrays, and constructors."""

    name: str
    where: Callable
    maximum: Callable
    minimum: Callable
    abs: Callable
    hypot: Callable
    atan2: Callable
    sin: Callable
    cos: Callable
    tan: Callable
    log: Callable
    isfinite: Callable
    full: Callable  # full(n, value, kind) with kind in {"float", "int", "bool"}
    full_like: Callable  # full_like(x, value, kind): x's shape (and device); a Python number for the scalars
    any: Callable  # any(mask) -> Python bool (a host sync on a GPU)
    nonzero: Callable  # nonzero(mask) -> int index array
    to_float32: Callable
    stack: Callable  # stack(list of arrays of one shape) -> shape + (k,)
    copy: Callable  # a fresh copy (a Python number is itself)
    to_host: Callable  # as numpy (a copy from the device for torch); numpy arrays and numbers as they are
    device: Any = None

    def __reduce__(self):
        return ops_named, (self.name, None if self.device is None else str(self.device))


_DTYPES = {"float": np.float64, "int": np.int64, "bool": np.bool_}
_PY_TYPES = {"float": float, "int": int, "bool": bool}


def identity(x):
    """``x`` itself (also the ``jit`` that compiles nothing)."""
    return x


def scalar_where(c, a, b):
    """``where`` on Python scalars."""
    return a if c else b


def scalar_max(a, b):
    """The scalar kernels' ``maximum``: ``b`` at a tie (and where either is NaN)."""
    return a if a > b else b


# ---- Python scalars: one env -------------------------------------------------------------------------------------


def _scalar_full(n, value, kind):
    return _PY_TYPES[kind](value)


def _scalar_full_like(x, value, kind):
    return _PY_TYPES[kind](value)


def _scalar_nonzero(mask):
    return np.flatnonzero(mask)


def _scalar_float32(a):
    return np.asarray(a, dtype=np.float32)


def _scalar_stack(xs):
    return np.array(xs, dtype=np.float64)


SCALAR = Ops(
    name="scalar", where=scalar_where, maximum=max, minimum=min, abs=abs, hypot=math.hypot, atan2=math.atan2,
    sin=math.sin, cos=math.cos, tan=math.tan, log=math.log, isfinite=math.isfinite, full=_scalar_full,
    full_like=_scalar_full_like, any=bool, nonzero=_scalar_nonzero, to_float32=_scalar_float32, stack=_scalar_stack,
    copy=identity, to_host=identity,
)
"""Python scalars (floats, ints, bools): one env. ``stack`` gives a float64 numpy vector."""


# ---- numpy -------------------------------------------------------------------------------------------------------


def _np_full(n, value, kind):
    return np.full(n, value, dtype=_DTYPES[kind])


def _np_full_like(x, value, kind):
    return np.full(np.shape(x), value, dtype=_DTYPES[kind])


def _np_any(mask):
    return bool(mask.any())


def _np_float32(a):
    return np.asarray(a, dtype=np.float32)


def _np_stack(xs):
    return np.stack(np.broadcast_arrays(*xs), axis=-1)


def _np_copy(a):
    return np.array(a, copy=True)


NUMPY = Ops(
    name="numpy", where=np.where, maximum=np.maximum, minimum=np.minimum, abs=np.abs, hypot=np.hypot,
    atan2=np.arctan2, sin=np.sin, cos=np.cos, tan=np.tan, log=np.log, isfinite=np.isfinite, full=_np_full,
    full_like=_np_full_like, any=_np_any, nonzero=np.flatnonzero, to_float32=_np_float32, stack=_np_stack,
    copy=_np_copy, to_host=identity,
)
"""numpy's namespace (float64, int64, bool arrays)."""


# ---- torch -------------------------------------------------------------------------------------------------------

_TORCH_OPS: dict[str, Ops] = {}


def is_torch(x) -> bool:
    """Whether ``x`` is a torch tensor (without importing torch when it is not loaded)."""
    t = type(x)
    return t.__module__.startswith("torch") and t.__name__ in ("Tensor", "Parameter")


def _torch_scalar(v, like):
    import torch

    if isinstance(v, torch.Tensor):
        return v
    if isinstance(v, bool):
        return torch.tensor(v, dtype=torch.bool, device=like.device)
    if isinstance(v, int):
        return torch.tensor(v, dtype=torch.int64 if like.dtype != torch.float64 else torch.float64, device=like.device)
    return torch.tensor(float(v), dtype=torch.float64, device=like.device)


def _torch_where(c, a, b):
    import torch

    if not isinstance(a, torch.Tensor) and not isinstance(b, torch.Tensor):
        like = torch.empty((), dtype=torch.float64 if isinstance(a, float) or isinstance(b, float) else torch.int64,
                           device=c.device)
        a, b = _torch_scalar(a, like), _torch_scalar(b, like)
    return torch.where(c, a, b)


def _torch_extreme(a, b, name, bound):
    # torch.maximum/minimum, with a Python number on either side as a clamp (which keeps the tensor's dtype)
    import torch

    if not isinstance(a, torch.Tensor):
        a, b = b, a
    if isinstance(b, torch.Tensor):
        return getattr(torch, name)(a, b)
    return torch.clamp(a, **{bound: float(b) if a.dtype.is_floating_point else b})


def _torch_maximum(a, b):
    return _torch_extreme(a, b, "maximum", "min")


def _torch_minimum(a, b):
    return _torch_extreme(a, b, "minimum", "max")


def _torch_dtype(kind):
    import torch

    return {"float": torch.float64, "int": torch.int64, "bool": torch.bool}[kind]


def _torch_full(n, value, kind, device):
    import torch

    return torch.full((n,), value, dtype=_torch_dtype(kind), device=device)


def _torch_full_like(x, value, kind):
    import torch

    return torch.full(tuple(x.shape), value, dtype=_torch_dtype(kind), device=x.device)


def _torch_log(a):
    import torch

    return torch.log(a) if isinstance(a, torch.Tensor) else math.log(a)


def _torch_any(mask):
    return bool(mask.any())


def _torch_nonzero(mask):
    import torch

    return torch.nonzero(mask).reshape(-1)


def _torch_float32(a):
    import torch

    return a.to(torch.float32)


def _torch_stack(xs):
    import torch

    return torch.stack(xs, dim=-1)


def _torch_copy(a):
    return a.clone()


def _torch_to_host(a):
    return a.detach().cpu().numpy()


def torch_ops(device=None) -> Ops:
    """The torch namespace on ``device`` (default: the CPU); float64, int64 and bool tensors."""
    import torch

    dev = torch.device("cpu" if device is None else device)
    key = str(dev)
    if key not in _TORCH_OPS:
        _TORCH_OPS[key] = Ops(
            name="torch", where=_torch_where, maximum=_torch_maximum, minimum=_torch_minimum, abs=torch.abs,
            hypot=torch.hypot, atan2=torch.atan2, sin=torch.sin, cos=torch.cos, tan=torch.tan, log=_torch_log,
            isfinite=torch.isfinite, full=functools.partial(_torch_full, device=dev), full_like=_torch_full_like,
            any=_torch_any, nonzero=_torch_nonzero, to_float32=_torch_float32, stack=_torch_stack, copy=_torch_copy,
            to_host=_torch_to_host, device=dev,
        )
    return _TORCH_OPS[key]


def ops_named(name: str, device: str | None = None) -> Ops:
    """The namespace called ``name`` (``"scalar"``, ``"numpy"``, or ``"torch"`` on ``device``): how one unpickles."""
    if name == "torch":
        return torch_ops(device)
    try:
        return {"scalar": SCALAR, "numpy": NUMPY}[name]
    except KeyError:
        raise ValueError(f"no array namespace called {name!r} (scalar, numpy, torch)") from None


def copy(a):
    """A fresh copy of a numpy array or a tensor (on its device)."""
    return a.clone() if is_torch(a) else a.copy()


def to_host(a):
    """A tensor as a numpy array (copied from its device); anything else as it is."""
    return _torch_to_host(a) if is_torch(a) else a


def ops_for(x) -> Ops:
    """The namespace of the array ``x`` (for code at the edges): torch's on ``x``'s device for a tensor, else
    numpy's."""
    if is_torch(x):
        return torch_ops(x.device)
    return NUMPY
