"""A reference run of every env: seeded episodes through autoresets, every state field and full-level info key.

:func:`record` runs the scenarios of :data:`SCENARIOS` (the single env, the vector env on the numba (fused and
array step), numpy and torch (CPU) back-ends, with ``SAME_STEP`` and ``NEXT_STEP`` autoresets and a masked reset, and
the rigid env) and returns one flat dict of arrays. ``tests/data/reference_run.npz`` holds it as recorded from the
code before the refactor of issue 22 (re-recorded for the changes ``tests/test_reference_run.py`` lists);
``tests/test_reference_run.py`` reruns it and asserts bit-for-bit equality.

Each entry ``"<scenario>/<kind>/<key>"`` is the concatenation, over the events (resets and steps) where the key was
present, of its values flattened; ``"...#at"`` gives those events' indices and ``"...#type"`` the Python/numpy types
its values had (so a float that became an ``np.float64`` is caught too). Strings are stored as unicode arrays.

Rerun ``python tests/reference_run.py tests/data/reference_run.npz`` only to record a deliberate change of behaviour.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

import pneunet_env  # noqa: F401  (registers the envs)

EPISODE = {"squeeze_steps": 4, "hold_steps": 4, "max_pressure_step_kpa": 20.0}
"""Short episodes and large steps, so that a few dozen steps go through several autoresets, with damage, drops and
successes."""
BUDGET = {"max_substeps": 10}
"""A solver budget that some steps spend: unconverged solves (the state kept, the episode truncated)."""


def _host(v) -> np.ndarray:
    """``v`` as a numpy array (a tensor copied to the host; strings as unicode)."""
    if type(v).__module__.startswith("torch"):
        v = v.detach().cpu().numpy()
    a = np.asarray(v)
    if a.dtype == object:
        flat = list(a.ravel())
        if all(isinstance(x, str) or x is None for x in flat):  # strings masked by None
            return np.array(["<None>" if x is None else x for x in flat], dtype=str).reshape(a.shape)
        width = max(np.size(x) for x in flat if x is not None)  # final_obs: observations masked by None
        return np.array([np.full(width, np.nan) if x is None else np.asarray(x, dtype=float).ravel() for x in flat])
    return a


def _type_name(v) -> str:
    t = type(v)
    if t.__module__.startswith("torch"):
        return f"Tensor:{v.dtype}"
    if isinstance(v, np.ndarray):
        return f"ndarray:{v.dtype}"
    return t.__name__


class _Recorder:
    def __init__(self, out: dict[str, np.ndarray], scenario: str) -> None:
        self.out, self.scenario = out, scenario
        self.values: dict[str, list[np.ndarray]] = {}
        self.at: dict[str, list[int]] = {}
        self.types: dict[str, set[str]] = {}
        self.event = 0

    def add(self, kind: str, key: str, v) -> None:
        name = f"{self.scenario}/{kind}/{key}"
        if isinstance(v, dict):
            for k2, v2 in v.items():
                self.add(kind, f"{key}.{k2}", v2)
            return
        self.values.setdefault(name, []).append(_host(v).ravel())
        self.at.setdefault(name, []).append(self.event)
        self.types.setdefault(name, set()).add(_type_name(v))

    def state(self, state) -> None:
        """Every field of an :class:`~pneunet_env.task.EnvState` (nested records flattened)."""
        for field, value in zip(type(state)._fields, state, strict=True):
            if dataclasses.is_dataclass(value):
                items = [(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)]
            elif isinstance(value, tuple):
                items = list(zip(type(value)._fields, value, strict=True))
            else:
                items = [("", value)]
            for name, v in items:
                self.add("state", f"{field}.{name}" if name else field, v)

    def next(self) -> None:
        self.event += 1

    def close(self) -> None:
        for name, vs in self.values.items():
            self.out[name] = np.concatenate(vs)
            self.out[name + "#at"] = np.asarray(self.at[name], dtype=np.int32)
            self.out[name + "#type"] = np.array("|".join(sorted(self.types[name])))


def _actions(seed: int, shape: tuple[int, ...], steps: int) -> np.ndarray:
    """Actions biased to squeeze (some beyond [-1, 1], to exercise the clip): damage, drops and time limits."""
    return np.random.default_rng(seed).uniform(-0.5, 1.4, (steps,) + shape)


def _single(out, scenario: str, env_id: str, steps: int, seed: int, **kwargs) -> None:
    rec = _Recorder(out, scenario)
    env = gym.make(env_id, info_level="full", **EPISODE, **kwargs)
    obs, info = env.reset(seed=seed)
    rec.add("reset", "obs", obs)
    rec.add("reset", "info", info)
    rec.state(env.unwrapped.state)
    for a in _actions(seed, (1,), steps):
        rec.next()
        obs, reward, terminated, truncated, info = env.step(a.astype(np.float32))
        for k, v in (("obs", obs), ("reward", reward), ("terminated", terminated), ("truncated", truncated),
                     ("info", info)):
            rec.add("step", k, v)
        rec.state(env.unwrapped.state)
        if terminated or truncated:
            rec.next()
            obs, info = env.reset()
            rec.add("reset", "obs", obs)
            rec.add("reset", "info", info)
            rec.state(env.unwrapped.state)
    env.close()
    rec.close()


def _vector(out, scenario: str, steps: int, seed: int, n: int = 4, mask_at: int | None = None, **kwargs) -> None:
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

    rec = _Recorder(out, scenario)
    env = PneuNetGraspVectorEnv(n, info_level="full", max_episode_steps=100, **EPISODE, **kwargs)
    obs, info = env.reset(seed=seed)
    rec.add("reset", "obs", obs)
    rec.add("reset", "info", info)
    rec.state(env.state)
    for t, a in enumerate(_actions(seed, (n, 1), steps)):
        rec.next()
        if t == mask_at:  # a partial reset, with a pin
            mask = np.arange(n) % 2 == 0
            obs, info = env.reset(options={"reset_mask": mask, "object_thickness_mm": 6.0})
            rec.add("reset", "obs", obs)
            rec.add("reset", "info", info)
            rec.state(env.state)
            rec.next()
        obs, reward, terminated, truncated, info = env.step(a.astype(np.float32))
        for k, v in (("obs", obs), ("reward", reward), ("terminated", terminated), ("truncated", truncated),
                     ("info", info)):
            rec.add("step", k, v)
        rec.state(env.state)
    env.close()
    rec.close()


JUMP = {"step_control": "jump"}
"""The solver's step control before 0.12 (``"branch"`` since): the scenarios recorded before it keep it."""
CONTINUATION = {"free_table": False, **JUMP}
"""The compiled steps without the free actuator's table: every solve the continuation's (the scenarios recorded
before the table; the ``*_free_table`` ones run with it)."""

SCENARIOS: dict[str, Callable[[dict[str, Any]], None]] = {
    "single": lambda out: _single(out, "single", "PneuNetGrasp-v1", 40, 7, **CONTINUATION),
    "single_paper_volume": lambda out: _single(out, "single_paper_volume", "PneuNetGrasp-Paper-v0", 30, 11,
                                               observe_volume=True, **CONTINUATION),
    "single_budget": lambda out: _single(out, "single_budget", "PneuNetGrasp-v1", 24, 17, **BUDGET, **CONTINUATION),
    "single_free_table": lambda out: _single(out, "single_free_table", "PneuNetGrasp-v1", 40, 7, **JUMP),
    "rigid": lambda out: _single(out, "rigid", "RigidGrasp-v1", 30, 5),
    "vector_numba": lambda out: _vector(out, "vector_numba", 24, 3, backend="numba", mask_at=9, **CONTINUATION),
    "vector_numba_free_table": lambda out: _vector(out, "vector_numba_free_table", 24, 3, backend="numba",
                                                   mask_at=9, **JUMP),
    "vector_numba_budget": lambda out: _vector(out, "vector_numba_budget", 16, 23, backend="numba", **BUDGET,
                                               **CONTINUATION),
    "vector_numba_array": lambda out: _vector(out, "vector_numba_array", 16, 23, backend="numba", fused=False,
                                              **BUDGET, **JUMP),
    "vector_numba_next": lambda out: _vector(out, "vector_numba_next", 20, 13, backend="numba",
                                             autoreset_mode="NextStep", observe_volume=True, **CONTINUATION),
    "vector_numpy": lambda out: _vector(out, "vector_numpy", 14, 3, backend="numpy", mask_at=6, **JUMP),
    "vector_torch": lambda out: _vector(out, "vector_torch", 10, 29, backend="torch", mask_at=4, max_substeps=14,
                                        **JUMP),
    # the defaults since 0.12 (the free table and step_control "branch"); their "jump" twins: single_free_table,
    # single_paper_volume (also without the table), vector_numba_free_table, vector_numpy (none for the budget's one)
    "single_branch": lambda out: _single(out, "single_branch", "PneuNetGrasp-v1", 40, 7),
    "single_paper_branch": lambda out: _single(out, "single_paper_branch", "PneuNetGrasp-Paper-v0", 30, 11,
                                               observe_volume=True),
    "vector_numba_branch": lambda out: _vector(out, "vector_numba_branch", 24, 3, backend="numba", mask_at=9),
    "vector_numba_array_branch": lambda out: _vector(out, "vector_numba_array_branch", 16, 23, backend="numba",
                                                     fused=False, **BUDGET),
    "vector_numpy_branch": lambda out: _vector(out, "vector_numpy_branch", 14, 3, backend="numpy", mask_at=6),
}
"""The scenarios, by name: each records its entries into the dict it is given."""


def record(names=None) -> dict[str, np.ndarray]:
    """The reference run's arrays (of the scenarios ``names``; all by default)."""
    out: dict[str, np.ndarray] = {}
    for name in SCENARIOS if names is None else names:
        SCENARIOS[name](out)
    return out


def pack(data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``data`` as a few arrays (one per dtype, and a table of names, dtypes, offsets and shapes): compact in an npz."""
    by_dtype: dict[str, list[np.ndarray]] = {}
    table = []
    for name, a in data.items():
        chunks = by_dtype.setdefault(a.dtype.str, [])
        offset = sum(c.size for c in chunks)
        chunks.append(a.ravel())
        table.append(f"{name}\t{a.dtype.str}\t{offset}\t{','.join(map(str, a.shape))}")
    packed = {f"values{i}": np.concatenate(chunks) for i, chunks in enumerate(by_dtype.values())}
    packed["dtypes"] = np.array(list(by_dtype))
    packed["table"] = np.array(table)
    return packed


def unpack(packed) -> dict[str, np.ndarray]:
    """The dict :func:`pack` packed."""
    values = {dt: packed[f"values{i}"] for i, dt in enumerate(packed["dtypes"].tolist())}
    out = {}
    for row in packed["table"].tolist():
        name, dt, offset, shape = row.split("\t")
        dims = tuple(int(d) for d in shape.split(",") if d)
        size = int(np.prod(dims, dtype=np.int64))
        out[name] = values[dt][int(offset):int(offset) + size].reshape(dims)
    return out


def load(path) -> dict[str, np.ndarray]:
    """The reference run saved at ``path``."""
    with np.load(path) as f:
        return unpack(f)


REL_TOL = 1e-12
"""Across machines and dependency versions, a float matches within ``REL_TOL`` of its own magnitude or of its entry's
largest one: numpy picks its ``power``/``exp``/``log`` kernels by the CPU's SIMD level (AVX-512 or not), numba
compiles for the host CPU and libm has FMA and non-FMA variants, so the last bits move from machine to machine."""
ROUNDOFF_TOL = 1e-12
"""Residuals that are round-off by construction (``gradient_norm``, at most the solver's ``gtol`` = 1e-11 at an
accepted state) match within this absolute tolerance: a tenth of ``gtol``."""
ROUNDOFF_KEYS = ("gradient_norm",)


def _float_mismatch(k: str, a: np.ndarray, b: np.ndarray, tolerance: bool) -> str | None:
    """Why float arrays ``a`` (expected) and ``b`` (got) of one shape differ, or None. Bit for bit (NaNs where they
    sat, signs of zeros) unless ``tolerance``; then NaN and infinity places and signs exactly, finite values within
    :data:`REL_TOL` (or :data:`ROUNDOFF_TOL` for :data:`ROUNDOFF_KEYS`)."""
    if not tolerance:
        bad = ~((a == b) | (np.isnan(a) & np.isnan(b))) | (np.signbit(a) != np.signbit(b))
        if not bad.any():
            return None
        i = int(np.flatnonzero(bad)[0])
        return f"{k}[{i}]: {a[i]!r} became {b[i]!r}"
    finite = np.isfinite(a)
    same_special = (np.isnan(a) == np.isnan(b)) & (np.isinf(a) == np.isinf(b)) & (finite | (a == b) | np.isnan(a))
    if not same_special.all():
        i = int(np.flatnonzero(~same_special)[0])
        return f"{k}[{i}]: {a[i]!r} became {b[i]!r} (a NaN or infinity moved)"
    both = finite & np.isfinite(b)
    x, y = a[both], b[both]
    if k.rsplit(".", 1)[-1].rsplit("/", 1)[-1] in ROUNDOFF_KEYS:
        allowed = np.full(x.shape, ROUNDOFF_TOL)
    else:
        scale = float(np.max(np.abs(x))) if x.size else 0.0
        allowed = REL_TOL * np.maximum(np.maximum(np.abs(x), np.abs(y)), scale)
    over = np.abs(x - y) > allowed
    if not over.any():
        return None
    i = int(np.flatnonzero(both)[np.flatnonzero(over)[0]])
    return (f"{k}[{i}]: {a[i]!r} became {b[i]!r} (|diff| {abs(a[i] - b[i]):.3g} > allowed "
            f"{float(allowed[np.flatnonzero(over)[0]]):.3g})")


def mismatches(expected: dict[str, np.ndarray], got: dict[str, np.ndarray], tolerance: bool = False) -> list[str]:
    """The entries that differ, with why.

    ``tolerance=False``: bit for bit (dtype, shape and bytes; NaNs must sit where they sat), what one install
    promises run after run. ``tolerance=True``: what holds across machines and dependency versions: dtypes, shapes,
    integers, flags, strings, types and NaN/infinity places exactly, finite floats within :data:`REL_TOL`.
    """
    bad = [f"{k}: missing" for k in sorted(set(expected) - set(got))]
    bad += [f"{k}: new" for k in sorted(set(got) - set(expected))]
    for k in sorted(set(expected) & set(got)):
        a, b = expected[k], got[k]
        if a.dtype != b.dtype or a.shape != b.shape:
            bad.append(f"{k}: {a.dtype}{a.shape} became {b.dtype}{b.shape}")
        elif a.tobytes() != b.tobytes():
            if a.dtype.kind == "f":
                why = _float_mismatch(k, a.ravel(), b.ravel(), tolerance)
                if why is not None:
                    bad.append(why)
            else:
                bad.append(f"{k}: {a!r} became {b!r}"[:300])
    return bad


if __name__ == "__main__":  # record: python tests/reference_run.py tests/data/reference_run.npz
    import io

    from pneunet_env.files import atomic_write_bytes

    data = record()
    buf = io.BytesIO()
    np.savez_compressed(buf, **pack(data))
    path = atomic_write_bytes(sys.argv[1], buf.getvalue())
    print(f"{len(data)} arrays, {sum(a.nbytes for a in data.values())} bytes raw -> {path}")
