"""The action: checked, and turned into the next command (pressure, or a jaw's closure).

The envs' edges: :func:`single_action` (one env's action, a Python float) and :func:`batch_actions` (a batch's, an
``(N,)`` array or tensor) take what a user passes and name what is wrong with it. :func:`update_pressure` is the
step's first part: ``clip(p + clip(a, -1, 1) dp_max, 0, p_max)`` on the namespace the params carry.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pneunet_env.physics.xp import SCALAR, Ops, is_torch

__all__ = ["check_action", "single_action", "batch_actions", "update_pressure"]


def _finite_number(action):
    """One env's action as a Python float; ``ValueError`` naming it unless a finite real number."""
    if isinstance(action, float):
        if not math.isfinite(action):
            raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
        return action
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be real numbers, got {action!r}") from None
    if a.ndim != 0:
        raise ValueError(f"action must be one number (one env), got shape {a.shape}: {action!r}")
    x = float(a)  # a Python float: much cheaper arithmetic than a 0-d array
    if not math.isfinite(x):
        raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
    return x


def _finite_array(action):
    """A batch's actions as a float array; ``ValueError`` naming them unless all finite."""
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be real numbers, got {action!r}") from None
    if not np.isfinite(a).all():
        raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
    return a


def _finite_tensor(action):
    """A batch's actions, a tensor; ``ValueError`` naming the first NaN or inf (a host sync on a GPU)."""
    bad = ~action.isfinite()
    if bool(bad.any()):
        i = int(bad.reshape(-1).nonzero()[0, 0])
        raise ValueError(f"actions[{i}] must be finite (no NaN or inf), got {float(action.reshape(-1)[i])!r}")
    return action


_CHECKS = {"scalar": _finite_number, "numpy": _finite_array, "torch": _finite_tensor}
"""The check of :func:`check_action`, by namespace."""


def check_action(action, ops: Ops = SCALAR):
    """``action`` as the numbers of the namespace ``ops`` (a Python float for :data:`~pneunet_env.physics.xp.SCALAR`,
    a float array for numpy, the tensor for torch); ``ValueError`` naming it unless all finite."""
    return _CHECKS[ops.name](action)


_REAL_KINDS = "iuf"  # numpy dtype kinds of real numbers (not bool, complex, strings or objects)


def _real_array(action, name: str, shape_hint: str) -> np.ndarray:
    """``action`` as a float64 array if it is real numbers; ``TypeError`` naming what it got otherwise."""
    if isinstance(action, (str, bytes, bool, np.bool_)) or action is None:
        raise TypeError(f"{name} must be real numbers {shape_hint}, got {type(action).__name__} {action!r}")
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"{name} must be real numbers {shape_hint}, got {action!r}") from None
    if raw.dtype.kind not in _REAL_KINDS:
        if raw.dtype.kind == "O" and all(type(v) is int for v in raw.ravel()):  # ints too large for int64
            try:
                return np.array([float(v) for v in raw.ravel()], dtype=np.float64).reshape(raw.shape)
            except OverflowError:
                raise ValueError(f"{name} {action!r} is too large for a float") from None
        raise TypeError(f"{name} must be real numbers {shape_hint}, got dtype {raw.dtype}: {action!r}")
    return raw.astype(np.float64, copy=False)


def single_action(action) -> float:
    """A single env's action as a Python float: a real number, or an array of shape ``(1,)`` (or ``()``).

    ``TypeError`` naming it for anything that is not real numbers (``None``, strings, booleans, complex numbers,
    objects); ``ValueError`` for the wrong shape or a number too large for a float. (NaN and inf are caught by
    :func:`update_pressure`.) The common case, a float array of shape ``(1,)``, is read directly.
    """
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        return action.item()  # (a Python float, exactly the array's number)
    if type(action) in (float, int):
        try:
            return float(action)
        except OverflowError:
            raise ValueError(f"action {action!r} is too large for a float") from None
    arr = _real_array(action, "action", "(a number, or shape (1,))")
    if arr.shape not in ((1,), ()):
        raise ValueError(f"action must have shape (1,), got shape {arr.shape}: {action!r}")
    return float(arr.reshape(-1)[0])


def batch_actions(actions, n: int, device=None):
    """A batch's actions, shape ``(n, 1)`` or ``(n,)``, as a float64 ``(n,)`` array; errors name what they got
    (``TypeError`` for what is not real numbers, ``ValueError`` for the shape or a NaN/inf, with its index).

    With ``device`` (a torch device: the torch backend) the result is a float64 tensor there, from a tensor (moved
    if it is elsewhere) or from anything numpy takes; a NaN or inf is then caught once, by the step
    (:func:`update_pressure`), with its index. Without ``device`` a CPU tensor is taken as numpy takes it.
    """
    if device is not None:
        return _tensor_actions(actions, n, device)
    a = _real_array(actions, "actions", f"of shape ({n}, 1)")
    if a.shape == (n, 1):
        a = a[:, 0]
    elif a.shape != (n,):
        raise ValueError(f"actions must have shape ({n}, 1) (or ({n},)), got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"actions[{i}] must be finite (no NaN or inf), got {a[i]!r}")
    return a


def _tensor_actions(actions, n: int, device):
    import torch

    if is_torch(actions):
        if not (actions.dtype.is_floating_point
                or actions.dtype in (torch.int8, torch.int16, torch.int32, torch.int64, torch.uint8)):
            raise TypeError(f"actions must be real numbers of shape ({n}, 1), got a tensor of dtype {actions.dtype}")
        a = actions.to(dtype=torch.float64, device=device)
    else:
        a = torch.from_numpy(np.array(_real_array(actions, "actions", f"of shape ({n}, 1)"))).to(device)
    if tuple(a.shape) == (n, 1):
        a = a[:, 0]
    elif tuple(a.shape) != (n,):
        raise ValueError(f"actions must have shape ({n}, 1) (or ({n},)), got shape {tuple(a.shape)}")
    return a




def update_pressure(pressure, action, params: Any):
    """The pressure after one action: ``clip(p + clip(a, -1, 1) dp_max, 0, p_max)``, on the namespace ``params.ops``.

    Args:
        pressure: current ``p~`` (a float for one env, ``(N,)`` for a batch).
        action: one number per environment (same shape as ``pressure``), nominally in ``[-1, 1]``.
        params: the task's numbers (:class:`pneunet_env.task.TaskParams`, typed ``Any`` here since
            :mod:`pneunet_env.task` imports this module), with its array namespace.

    Returns:
        ``(new_pressure, action_clipped)``: ``action_clipped`` is true where ``|a| > 1`` was clipped.

    Raises:
        ValueError: a NaN or infinite action.
    """
    xp = params.ops
    a = check_action(action, xp)
    clipped = (a < -1.0) | (a > 1.0)
    a = xp.minimum(xp.maximum(a, -1.0), 1.0)
    return xp.minimum(xp.maximum(pressure + a * params.pressure_step, 0.0), params.pressure_max), clipped
