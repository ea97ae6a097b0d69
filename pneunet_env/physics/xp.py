"""The array operations the batched physics is written against, for numpy and for torch (one namespace each).

The energy (:func:`pneunet_env.physics.mechanics.make_terms`), the 2x2 eigen helpers
(:func:`pneunet_env.physics.solver.make_sym2`), the contact (:func:`pneunet_env.physics.contact.make_contact`), the
masked solver (:mod:`pneunet_env.physics.masked`) and the task's rules (:mod:`pneunet_env.task`) are written once
against the handful of operations of :class:`Ops`, the way SciPy's array-API code is written against an
``array_namespace``: :func:`ops_for` returns :data:`NUMPY` for numpy arrays and the torch namespace for torch
tensors (on any device). torch is imported only when a tensor is seen, so the core imports without it.

Why not ``array_api_compat`` alone: the kernels mix arrays with Python floats (``where(c, 1.0, x)``,
``maximum(x, 0.0)``), which the array API only allows from its 2024 revision on; the torch namespace here makes
those calls keep float64 (torch's ``where`` of two Python floats gives float32) and keeps every result on the
tensors' device.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

__all__ = ["Ops", "NUMPY", "ops_for", "torch_ops", "is_torch", "copy", "to_host"]


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
    log: Callable
    isfinite: Callable
    full: Callable  # full(n, value, dtype_name) with dtype_name in {"float", "int", "bool"}
    any: Callable  # any(mask) -> Python bool (a host sync on a GPU)
    nonzero: Callable  # nonzero(mask) -> int index array
    to_float32: Callable
    stack: Callable  # stack(list of (N,) arrays) -> (N, k)
    device: Any = None


def _np_full(n, value, kind):
    return np.full(n, value, dtype={"float": np.float64, "int": np.int64, "bool": bool}[kind])


NUMPY = Ops(
    "numpy", np.where, np.maximum, np.minimum, np.abs, np.hypot, np.arctan2, np.sin, np.cos, np.log, np.isfinite,
    _np_full, lambda m: bool(m.any()), np.flatnonzero, lambda a: np.asarray(a, dtype=np.float32),
    lambda xs: np.stack(xs, axis=-1),
)
"""numpy's namespace (float64, int64, bool arrays)."""

_TORCH_OPS: dict[str, Ops] = {}


def is_torch(x) -> bool:
    """Whether ``x`` is a torch tensor (without importing torch when it is not loaded)."""
    t = type(x)
    return t.__module__.startswith("torch") and t.__name__ in ("Tensor", "Parameter")


def torch_ops(device=None) -> Ops:
    """The torch namespace on ``device`` (default: the CPU); float64, int64 and bool tensors."""
    import torch

    dev = torch.device("cpu" if device is None else device)
    key = str(dev)
    if key in _TORCH_OPS:
        return _TORCH_OPS[key]
    dtypes = {"float": torch.float64, "int": torch.int64, "bool": torch.bool}

    def scalar(v, like):
        if isinstance(v, torch.Tensor):
            return v
        if isinstance(v, bool):
            return torch.tensor(v, dtype=torch.bool, device=like.device)
        if isinstance(v, int):
            return torch.tensor(v, dtype=torch.int64 if like.dtype != torch.float64 else torch.float64,
                                device=like.device)
        return torch.tensor(float(v), dtype=torch.float64, device=like.device)

    def where(c, a, b):
        if not isinstance(a, torch.Tensor) and not isinstance(b, torch.Tensor):
            like = torch.empty((), dtype=torch.float64 if isinstance(a, float) or isinstance(b, float)
                               else torch.int64, device=c.device)
            a, b = scalar(a, like), scalar(b, like)
        return torch.where(c, a, b)

    def extreme(tensor_fn, bound):
        # torch.maximum/minimum, with a Python number on either side as a clamp (which keeps the tensor's dtype)
        def fn(a, b):
            if not isinstance(a, torch.Tensor):
                a, b = b, a
            if isinstance(b, torch.Tensor):
                return tensor_fn(a, b)
            return torch.clamp(a, **{bound: float(b) if a.dtype.is_floating_point else b})

        return fn

    maximum, minimum = extreme(torch.maximum, "min"), extreme(torch.minimum, "max")

    def full(n, value, kind):
        return torch.full((n,), value, dtype=dtypes[kind], device=dev)

    def log(a):
        return torch.log(a) if isinstance(a, torch.Tensor) else math.log(a)

    ops = Ops(
        "torch", where, maximum, minimum, torch.abs, torch.hypot, torch.atan2, torch.sin, torch.cos, log,
        torch.isfinite, full, lambda m: bool(m.any()), lambda m: torch.nonzero(m).reshape(-1),
        lambda a: a.to(torch.float32), lambda xs: torch.stack(xs, dim=-1), dev,
    )
    _TORCH_OPS[key] = ops
    return ops


def copy(a):
    """A fresh copy of a numpy array or a tensor (on its device)."""
    return a.clone() if is_torch(a) else a.copy()


def to_host(a):
    """A tensor as a numpy array (copied from its device); anything else as it is."""
    return a.detach().cpu().numpy() if is_torch(a) else a


def ops_for(x) -> Ops:
    """The namespace of ``x``: torch's on ``x``'s device for a tensor, else numpy's."""
    if is_torch(x):
        return torch_ops(x.device)
    return NUMPY
