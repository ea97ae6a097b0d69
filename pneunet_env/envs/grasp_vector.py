"""``PneuNetGrasp-v0`` natively batched: N grasps advanced together by one batched solve (no loop over envs).

:class:`PneuNetGraspVectorEnv` is what ``gym.make_vec("PneuNetGrasp-v0", num_envs=N)`` returns. It runs the
same rules as the single environment (:class:`pneunet_env.envs.grasp.PneuNetGraspEnv`), through the same pure
functions of :mod:`pneunet_env.task` called on ``(N,)`` arrays instead of scalars (gymnax style: the single
env is the N = 1 case), with a batched solve in place of the scalar one. Three back-ends: ``numba`` (the default
with numba: the whole step as one compiled loop, :func:`pneunet_env.fused.fused_step`), ``numpy`` (the array step
with :func:`pneunet_env.physics.batched.solve_batch`) and ``torch`` (the same array step on tensors of a device,
with the masked solver :mod:`pneunet_env.physics.masked`).

It is, step for step, ``gym.make_vec("PneuNetGrasp-v0", num_envs=N, vectorization_mode="sync",
vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP})`` (N single envs) computed as arrays: the same
observations, rewards, ends, info (Gymnasium's vector convention, a dict of ``(N,)`` arrays with ``_key``
masks) and random objects, to round-off (tested to 1e-10, with episodes that end and auto-reset).
"""

from __future__ import annotations

import dataclasses
import functools
import operator
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from pneunet_env import task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.envs.grasp import observation_space
from pneunet_env.fused import HAVE_FUSED, fused_step, new_cache
from pneunet_env.objects import GraspObject
from pneunet_env.physics.batched import BACKENDS, check_threads
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.physics.xp import NUMPY, is_torch, to_host, torch_ops
from pneunet_env.physics.xp import copy as _copy

__all__ = ["PneuNetGraspVectorEnv", "PCG64Streams"]


# ------------------------------------------------------------------------------------------------------
# One random stream per sub-env, advanced as arrays: numpy's PCG64 seeded through SeedSequence
# ------------------------------------------------------------------------------------------------------

_M32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_MASK32 = 0xFFFFFFFF
# numpy's SeedSequence (bit_generator.pyx): hash constants and a pool of 4 uint32 words.
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
# PCG64 (pcg64.h): the 128-bit LCG multiplier, as two 64-bit halves.
_MULT_HI = np.uint64(2549297995355413924)
_MULT_LO = np.uint64(4865540595714422341)
_SEED_LIMIT = 1 << (32 * _POOL)


def _hashmix(value: np.ndarray, hc: int) -> tuple[np.ndarray, int]:
    value = value ^ np.uint32(hc)
    hc = (hc * _MULT_A) & _MASK32
    value = value * np.uint32(hc)
    return value ^ (value >> np.uint32(16)), hc


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    r = np.uint32(_MIX_MULT_L) * x - np.uint32(_MIX_MULT_R) * y
    return r ^ (r >> np.uint32(16))


def _seed_sequence_words(words: np.ndarray) -> list[np.ndarray]:
    """``SeedSequence(seed).generate_state(8, uint32)`` for every column of ``words`` ((4, n) uint32: the seed's
    32-bit words, least significant first, zero-padded; numpy pads a short entropy the same way)."""
    hc = _INIT_A
    pool = []
    for i in range(_POOL):
        v, hc = _hashmix(words[i], hc)
        pool.append(v)
    for i_src in range(_POOL):
        for i_dst in range(_POOL):
            if i_src != i_dst:
                h, hc = _hashmix(pool[i_src], hc)
                pool[i_dst] = _mix(pool[i_dst], h)
    hc = _INIT_B
    out = []
    for i in range(2 * _POOL):
        v = pool[i % _POOL] ^ np.uint32(hc)
        hc = (hc * _MULT_B) & _MASK32
        v = v * np.uint32(hc)
        out.append(v ^ (v >> np.uint32(16)))
    return out


def _mulhi64(x: np.ndarray, y: np.uint64) -> np.ndarray:
    """The high 64 bits of the 128-bit product ``x * y`` (32-bit limbs)."""
    x0, x1 = x & _M32, x >> _S32
    y0, y1 = y & _M32, y >> _S32
    p00, p01, p10, p11 = x0 * y0, x0 * y1, x1 * y0, x1 * y1
    mid = (p00 >> _S32) + (p01 & _M32) + (p10 & _M32)
    return p11 + (p01 >> _S32) + (p10 >> _S32) + (mid >> _S32)


def _lcg_step(hi, lo, ihi, ilo):
    """``state * MULT + inc`` modulo 2**128, states as (high, low) uint64 halves."""
    nlo = lo * _MULT_LO
    nhi = _mulhi64(lo, _MULT_LO) + lo * _MULT_HI + hi * _MULT_LO
    lo2 = nlo + ilo
    return nhi + ihi + (lo2 < nlo).astype(np.uint64), lo2


class PCG64Streams:
    """N independent random streams, each numpy's ``Generator(PCG64(SeedSequence(seed_i)))``, drawn as arrays.

    Stream ``i`` seeded with ``seed_i`` yields exactly (bit for bit) the doubles of
    ``np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed_i))).random()``, which is what
    ``env.reset(seed=seed_i)`` gives a single Gymnasium env as ``env.np_random``. Seeding and drawing are
    array operations over the streams (numpy's SeedSequence hash and the 128-bit PCG64 LCG with its XSL-RR
    output, emulated with uint32/uint64 arithmetic), so there is no Python loop over envs.
    Each stream's state is 32 bytes.
    """

    def __init__(self, n: int) -> None:
        self.hi = np.zeros(n, np.uint64)
        self.lo = np.zeros(n, np.uint64)
        self.inc_hi = np.zeros(n, np.uint64)
        self.inc_lo = np.ones(n, np.uint64)

    @property
    def nbytes(self) -> int:
        return self.hi.nbytes + self.lo.nbytes + self.inc_hi.nbytes + self.inc_lo.nbytes

    def seed(self, idx: np.ndarray, words: np.ndarray) -> None:
        """Seed streams ``idx`` from their seeds' 32-bit words ``words`` ((4, len(idx)) uint32, least significant
        first): what ``PCG64(SeedSequence(seed))`` does."""
        with np.errstate(over="ignore"):
            st = _seed_sequence_words(words)
            v = [st[2 * k].astype(np.uint64) | (st[2 * k + 1].astype(np.uint64) << _S32) for k in range(4)]
            s_hi, s_lo, q_hi, q_lo = v
            # pcg_setseq_128_srandom_r: inc = (initseq << 1) | 1; state = 0; step; state += initstate; step.
            ihi = (q_hi << np.uint64(1)) | (q_lo >> np.uint64(63))
            ilo = (q_lo << np.uint64(1)) | np.uint64(1)
            hi, lo = _lcg_step(np.zeros_like(s_hi), np.zeros_like(s_lo), ihi, ilo)
            lo2 = lo + s_lo
            hi = hi + s_hi + (lo2 < lo).astype(np.uint64)
            hi, lo = _lcg_step(hi, lo2, ihi, ilo)
        self.hi[idx], self.lo[idx], self.inc_hi[idx], self.inc_lo[idx] = hi, lo, ihi, ilo

    def random(self, idx: np.ndarray, count: int) -> np.ndarray:
        """``count`` doubles in ``[0, 1)`` from each stream ``idx``: shape ``(count, len(idx))``; advances them."""
        hi, lo, ihi, ilo = self.hi[idx], self.lo[idx], self.inc_hi[idx], self.inc_lo[idx]
        out = np.empty((count, len(idx)))
        with np.errstate(over="ignore"):
            for j in range(count):
                hi, lo = _lcg_step(hi, lo, ihi, ilo)
                x = hi ^ lo
                rot = hi >> np.uint64(58)
                u = (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))  # XSL-RR output
                out[j] = (u >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)
        self.hi[idx], self.lo[idx] = hi, lo
        return out

    def generator(self, i: int) -> np.random.Generator:
        """A ``np.random.Generator`` in the state of stream ``i`` (a copy: drawing from it does not advance ``i``)."""
        bg = np.random.PCG64()
        bg.state = {
            "bit_generator": "PCG64",
            "state": {"state": (int(self.hi[i]) << 64) | int(self.lo[i]),
                      "inc": (int(self.inc_hi[i]) << 64) | int(self.inc_lo[i])},
            "has_uint32": 0,
            "uinteger": 0,
        }
        return np.random.Generator(bg)


def _seed_words(seeds: Sequence[int] | int, n: int) -> np.ndarray:
    """The (4, n) uint32 words of the seeds ``seed + i`` (an int) or of a list of n ints; ``ValueError`` if invalid."""
    words = np.zeros((_POOL, n), np.uint32)
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, (bool, np.bool_)):
        s = int(seeds)
        if s < 0 or s + n > _SEED_LIMIT:
            raise ValueError(f"seed must be an integer in [0, 2**128 - num_envs], got {seeds!r}")
        carry = np.arange(n, dtype=np.uint64)
        for j in range(_POOL):
            v = np.uint64((s >> (32 * j)) & _MASK32) + carry
            words[j] = (v & _M32).astype(np.uint32)
            carry = v >> _S32
        return words
    values = []
    for i, s in enumerate(seeds):  # a user's list of n seeds is converted once, at reset(seed=[...])
        try:
            v = operator.index(s)
        except TypeError:
            raise ValueError(f"seed[{i}] must be an integer, got {s!r}") from None
        if isinstance(s, (bool, np.bool_)) or v < 0 or v >= _SEED_LIMIT:
            raise ValueError(f"seed[{i}] must be an integer in [0, 2**128), got {s!r}")
        values.append(v)
    for j in range(_POOL):
        words[j] = np.array([(v >> (32 * j)) & _MASK32 for v in values], dtype=np.uint32)
    return words


# ------------------------------------------------------------------------------------------------------
# The vector env
# ------------------------------------------------------------------------------------------------------


_MODES = (AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP)


def _autoreset_mode(mode) -> AutoresetMode:
    """``AutoresetMode.SAME_STEP`` or ``NEXT_STEP`` (the enum, its value ``"SameStep"``/``"NextStep"`` or its name)."""
    for m in _MODES:
        if mode is m or mode == m.value or (isinstance(mode, str) and mode.upper() == m.name):
            return m
    raise ValueError(f"autoreset_mode must be AutoresetMode.SAME_STEP or NEXT_STEP (or 'SameStep'/'NextStep'), "
                     f"got {mode!r}")


def _zero_like(a):
    """The zero of ``a``'s dtype (``False`` for flags) that fills the entries a mask leaves out."""
    if is_torch(a):
        import torch

        return torch.zeros((), dtype=a.dtype).item()  # on the host: no device sync
    return None if a.dtype == object else a.dtype.type(0)


def _on_host(record):
    """A state record (NamedTuples and dataclasses, nested) with every tensor as a numpy array."""
    if isinstance(record, tuple):
        return type(record)(*(_on_host(v) for v in record))
    if dataclasses.is_dataclass(record):
        return type(record)(*(_on_host(getattr(record, f.name)) for f in dataclasses.fields(record)))
    return to_host(record)


class PneuNetGraspVectorEnv(VectorEnv):
    """N pneu-net grasps (``PneuNetGrasp-v0``) stepped together, with one batched quasi-static solve per step.

    ## Description

    Each sub-environment is a :class:`pneunet_env.envs.grasp.PneuNetGraspEnv` (see its docstring for the task,
    reward and episode end); they are advanced together as arrays: the pressure update, the damage/slip
    rules, the reward, the observation and the info are the :mod:`pneunet_env.task` functions on ``(N,)``
    arrays, and the equilibria are one :func:`pneunet_env.physics.batched.solve_batch` call (numba's compiled
    loop, split over the cores for large N, or the vectorised numpy back-end without numba). Nothing in
    ``step`` or ``reset`` loops over envs in Python.

    ## Spaces

    | space                     | value                                                            |
    |---------------------------|------------------------------------------------------------------|
    | ``single_action_space``   | ``Box(-1, 1, (1,), float32)``: pressure change / ``max_pressure_step_kpa`` |
    | ``action_space``          | ``Box(-1, 1, (N, 1), float32)`` (``(N,)`` arrays are accepted too) |
    | ``single_observation_space`` | ``Box(0, 1, (1,), float32)`` (``[p/p_max, dV]`` with ``observe_volume``) |
    | ``observation_space``     | the batch of it, ``(N, 1)`` (or ``(N, 2)``)                     |

    Rewards: ``(N,)`` float64; terminations and truncations: ``(N,)`` bool.

    ## Autoreset: ``SAME_STEP`` (default) or ``NEXT_STEP``

    ``autoreset_mode=AutoresetMode.NEXT_STEP`` (or ``"NextStep"``) gives Gymnasium's default convention, the one
    most user code is written for: the step that ends an episode returns that episode's last observation and info
    (with ``is_success``), and the *next* ``step`` resets that sub-env instead of stepping it (its action is
    ignored; reward 0, not terminated or truncated; the reset's observation and info). It equals
    ``SyncVectorEnv(..., autoreset_mode=NEXT_STEP)`` step for step (tested).

    By default ``metadata["autoreset_mode"]`` is ``AutoresetMode.SAME_STEP``: a sub-env whose episode ends (terminated
    or truncated) is reset *within the same* ``step`` call. For that sub-env, the step returns the reward,
    ``terminated`` and ``truncated`` of the step that ended the episode, but the **first observation of the
    next episode**; the last observation of the ended episode is ``info["final_obs"][i]`` and that step's
    info is ``info["final_info"]`` (a dict of arrays, with ``is_success``), both masked by
    ``info["_final_obs"]`` / ``info["_final_info"]``. The top-level info of a reset sub-env is its reset info.

    Why SAME_STEP (and not Gymnasium's default NEXT_STEP): every ``step`` then acts in a live episode (with
    NEXT_STEP the step after an episode's end is a reset, its action ignored and its reward 0, so 1 step in
    ``episode_steps + 1`` = 1 % of the batch's work would be wasted and must be masked out of training
    data), and it is the convention of Stable-Baselines3 (``terminal_observation``), which
    :class:`pneunet_env.envs.sb3.SB3VecEnv` passes straight through. For users: bootstrap a truncated episode's
    value from ``info["final_obs"]``, not from the returned observation; Gymnasium's vector wrappers
    (``RecordEpisodeStatistics``, ...) read the mode from the metadata and handle it.

    ## Determinism and random streams

    Sub-env ``i`` draws its objects from its own stream, exactly the ``np_random`` a single env gets from
    ``reset(seed=seed_i)`` (numpy's ``PCG64(SeedSequence(seed_i))``, emulated as arrays by
    :class:`PCG64Streams`): ``reset(seed=s)`` seeds sub-env ``i`` with ``s + i`` (Gymnasium's sync vector env
    convention), ``reset(seed=[s_0, ..., s_{N-1}])`` with ``s_i`` (``None`` entries keep their stream), and
    ``reset()`` continues the streams (the first unseeded ``reset`` picks a random ``s``). An auto-reset draws
    the next object from the sub-env's stream, as ``env.reset()`` would. So N single envs seeded ``s + i``,
    reset when their episodes end, and one vector env seeded ``s`` give the same trajectories.
    ``self.np_random`` (Gymnasium's vector-level generator) is not used; :meth:`sub_env_generator` returns a
    copy of a sub-env's stream.

    ## Arguments

    ``gym.make_vec("PneuNetGrasp-v0", num_envs=N, render_mode=None, config=None, **overrides)``, or
    ``PneuNetGraspVectorEnv(num_envs, ...)``:

    * ``config`` / ``overrides``: as for the single env (:func:`pneunet_env.config.load_config`), shared by all.
    * ``max_episode_steps``: a time limit (what ``gym.make``'s ``TimeLimit`` does: ``truncated`` once a
      sub-env has taken that many steps); ``make_vec`` passes the registered 100. ``None``: only the
      task's own end (``squeeze_steps + hold_steps``).
    * ``backend``: the batched solver's, ``"auto"`` (numba if installed, else numpy), ``"numba"``, ``"numpy"`` or
      ``"torch"``. With ``"torch"`` the whole state lives on ``device`` as float64 tensors and the step is the same
      pure :func:`pneunet_env.task.step` on tensors with the masked solver (:mod:`pneunet_env.physics.masked`):
      observations (float32), rewards (float64), flags and info values are **torch tensors on the device**
      (``obs.cpu().numpy()`` gives numpy; actions may be tensors or arrays). Objects are still drawn from the
      per-env PCG64 streams on the host (the same draws as every other backend) and sent to the device at reset.
      ``final_obs`` is then an ``(N, obs_dim)`` tensor masked by ``_final_obs`` (not an object array).
    * ``device``: torch only: ``"cpu"`` (default), ``"cuda"``, ``"cuda:1"``, ...
    * ``compile``: torch only: run the solver's round through ``torch.compile`` (pays on a GPU; see the benchmark).
    * ``parallel``: numba only: split the solve over the cores (numba's threads, ``NUMBA_NUM_THREADS``); ``None``
      from :data:`pneunet_env.physics.batched.PARALLEL_MIN_ENVS` envs on. Pass ``False`` when other processes keep the
      cores busy: numba's threads then wait on each other (a step can take 10x longer).
    * ``fused``: numba only (default there): the whole step as one compiled loop over the envs
      (:func:`pneunet_env.fused.fused_step`: the pressure update, the solve, the rules and the observation), bit for
      bit :func:`pneunet_env.task.step`'s result; ``False``: the array step around the batched solve.
    * ``info_keys``: the info keys to build each step (``None``: every key of ``info_level``; ``()``: none, the
      fastest, for training loops that read nothing from the info). ``final_obs`` and ``final_info`` (with
      ``is_success``) are always given where episodes end.
    * ``num_threads``: numba only: the parallel loop's threads (``None``: chosen by N,
      :func:`pneunet_env.physics.batched.threads_for`: one per 512 envs, at most ``NUMBA_NUM_THREADS``).

    ``reset(options=...)`` takes the single env's pins (applied to every sub-env reset by the call; a value
    may be an ``(N,)`` array, one per sub-env) and ``"reset_mask"`` (an ``(N,)`` bool array: reset only
    those; the others keep their state and have ``_key`` masks false in the info).

    ## Info

    The single env's keys (see :class:`pneunet_env.envs.grasp.PneuNetGraspEnv`), each an ``(N,)`` array with a
    ``_key`` bool mask, plus ``final_obs``/``final_info`` on steps where an episode ended. Every array is
    fresh (not shared with the env's state or with earlier infos).

    ## Rendering

    ``render_mode="rgb_array"``: ``render()`` returns a tuple of N frames, one per sub-env (as Gymnasium's
    sync vector env does): ``N * 480 * 360 * 3`` bytes, meant for small N.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20, "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        config: Any = None,
        max_episode_steps: int | None = None,
        backend: str = "auto",
        parallel: bool | None = None,
        info_level: str = "lean",
        autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
        device: Any = None,
        compile: bool = False,
        num_threads: int | None = None,
        fused: bool | None = None,
        info_keys: Sequence[str] | None = None,
        **overrides: Any,
    ) -> None:
        try:
            n = operator.index(num_envs)
        except TypeError:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}") from None
        if n < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if backend == "torch" and num_threads is not None:
            raise ValueError(f"num_threads is for the numba backend (torch: torch.set_num_threads), "
                             f"got {num_threads!r}")
        if backend != "torch" and (device is not None or compile):
            raise ValueError(f"device and compile are for backend='torch' only, got device={device!r}, "
                             f"compile={compile!r} with backend={backend!r}")
        if not isinstance(compile, bool):
            raise ValueError(f"compile must be True or False, got {compile!r}")
        if backend == "torch":
            try:
                import torch
            except ImportError:
                raise ValueError("backend='torch' needs torch (pip install torch)") from None
            try:
                self._xp = torch_ops("cpu" if device is None else device)
                torch.zeros(1, device=self._xp.device)
            except (RuntimeError, TypeError, AssertionError) as exc:
                raise ValueError(f"device must name an available torch device, got {device!r} ({exc})") from None
            self.device = self._xp.device
        else:
            self._xp = NUMPY
            self.device = None
        if info_level not in task.INFO_LEVELS:
            raise ValueError(f"info_level must be one of {task.INFO_LEVELS}, got {info_level!r}")
        if max_episode_steps is not None:
            try:
                max_episode_steps = operator.index(max_episode_steps)
            except TypeError:
                raise ValueError(f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}") \
                    from None
            if max_episode_steps < 1:
                raise ValueError(f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}")
        if info_keys is not None:
            if isinstance(info_keys, str) or not all(isinstance(k, str) for k in info_keys):
                raise ValueError(f"info_keys must be a sequence of key names (or None), got {info_keys!r}")
            valid = task.info_keys(info_level)
            unknown = sorted(set(info_keys) - set(valid))
            if unknown:
                raise ValueError(f"info_keys {unknown} are not keys of the {info_level!r} info; valid: {list(valid)}")
            info_keys = frozenset(info_keys)
        self.info_keys: frozenset[str] | None = info_keys
        """The info keys built each step (``None``: all of the info level's); ``final_obs``/``final_info`` always."""
        self.num_envs = n
        self.render_mode = render_mode
        self.max_episode_steps = max_episode_steps
        self.backend = backend
        self.parallel = parallel
        self.info_level = info_level
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.config: EnvConfig = load_config(config, **overrides)
        self._params = task.EnvParams.from_config(self.config)
        self.object_class_names: tuple[str, ...] = task.class_names(self.config)
        """The catalogue classes, by the integer code of ``info["object_class"]`` (-1: drawn from ranges)."""
        if backend == "torch":
            self._contact = functools.partial(task.torch_contact_batch, compile=compile)
        else:
            check_threads(num_threads)
            self._contact = functools.partial(task.newton_contact_batch, backend=backend, parallel=parallel,
                                              threads=num_threads)
        numba_backend = backend == "numba" or (backend == "auto" and HAVE_FUSED)
        if fused is None:
            fused = numba_backend
        if not isinstance(fused, bool) or (fused and not numba_backend):
            raise ValueError(f"fused must be True (numba backend only) or False, got {fused!r} with "
                             f"backend={backend!r}")
        self.fused = fused
        if fused:
            # the energy evaluation each env's last step ended on: the next step's first (fused.fused_step)
            self._ev_cache = new_cache(n)
            self._step_fn = functools.partial(fused_step, params=self._params, parallel=parallel, threads=num_threads,
                                              cache=self._ev_cache)
        else:
            self._step_fn = functools.partial(task.step, params=self._params, contact=self._contact)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.single_observation_space = observation_space(self.config)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._streams = PCG64Streams(n)
        self._seeded = False
        self._state: task.EnvState | None = None
        self._obs: np.ndarray | None = None
        self._pending = self._xp.full(n, False, "bool")  # NEXT_STEP: sub-envs to reset on the next step
        self._warned = False

    # ---- state, for users ------------------------------------------------------------------------------
    @property
    def state(self) -> task.EnvState | None:
        """The whole state (:class:`pneunet_env.task.EnvState` of ``(N,)`` arrays; never changed in place)."""
        return self._state

    @property
    def objects(self) -> GraspObject | None:
        """The current objects: a :class:`~pneunet_env.objects.GraspObject` of ``(N,)`` arrays (copies)."""
        if self._state is None:
            return None
        obj = self._state.obj
        return GraspObject(*(_copy(getattr(obj, f.name)) for f in dataclasses.fields(obj)))

    @property
    def equilibria(self) -> Equilibrium | None:
        """The current quasi-static states: an :class:`~pneunet_env.physics.solver.Equilibrium` of ``(N,)`` arrays
        (copies)."""
        return None if self._state is None else Equilibrium(*(_copy(v) for v in self._state.eq))

    def equilibrium(self, i: int) -> Equilibrium:
        """Sub-env ``i``'s state as the single env's :class:`~pneunet_env.physics.solver.Equilibrium` (scalars)."""
        if self._state is None:
            raise RuntimeError("call reset() first")
        return Equilibrium(*(v[i].item() for v in self._state.eq))

    def sub_env_generator(self, i: int) -> np.random.Generator:
        """A copy of sub-env ``i``'s random stream (what a single env's ``np_random`` would be now)."""
        return self._streams.generator(i)

    def state_nbytes(self) -> int:
        """Bytes of state kept between steps, all envs (the :class:`~pneunet_env.task.EnvState`'s arrays, the last
        observation, the random streams and, for the fused step, its evaluation cache)."""
        s = self._state
        obj = [getattr(s.obj, f.name) for f in dataclasses.fields(s.obj)]
        arrays = [s.command, *s.eq, *obj, *s.thresholds, *s.task, self._obs, *(self._ev_cache if self.fused else ())]
        size = sum(a.element_size() * a.nelement() if is_torch(a) else np.asarray(a).nbytes for a in arrays)
        return int(size) + self._streams.nbytes

    # ---- Gymnasium API -----------------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Reset all sub-envs (or those of ``options["reset_mask"]``); see the class docstring for seeds."""
        n = self.num_envs
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict (object pins, 'reset_mask'), got {options!r}")
        pins = dict(options or {})
        mask = pins.pop("reset_mask", None)
        if mask is not None:
            mask = np.asarray(to_host(mask))
            if mask.dtype != bool or mask.shape != (n,):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},), got "
                                 f"{mask.dtype} {mask.shape}")
            if self._state is None and not mask.all():
                raise ValueError("the first reset must reset every sub-env (reset_mask all true)")
            if mask.all():
                mask = None  # every sub-env: a full reset
        idx = np.arange(n) if mask is None else np.flatnonzero(mask)
        self._seed(seed, idx)
        pins = {k: (np.asarray(v)[idx] if np.ndim(v) == 1 and np.shape(v) == (n,) else v) for k, v in pins.items()}
        obj = self._draw(idx, pins)
        if mask is None:
            self._pending = self._xp.full(n, False, "bool")
            self._state = task.reset_state(obj, self._params, self._contact)
            self._forget(None)
            obs, info = self._observe(self._state), self._info(self._state, None, None)
        else:
            mask, idx = self._to_device(mask), self._to_device(idx)
            self._pending = self._pending & ~mask
            self._state = task.autoreset(self._state, idx, obj, self._params, self._contact)
            self._forget(idx)
            obs = _copy(self._obs)
            obs[idx] = self._observe(self._state)[idx]
            info = self._info(self._state, None, mask)
            info = {k: self._masked(mask, v) if k[0] != "_" else v for k, v in info.items()}
        self._obs = _copy(obs)
        return obs, info

    def _to_device(self, a):
        """A host array (or a :class:`GraspObject` of them) on the backend's device: itself for numpy back-ends."""
        if self._xp is NUMPY:
            return a
        import torch

        if isinstance(a, GraspObject):
            return GraspObject(*(self._to_device(np.asarray(getattr(a, f.name))) for f in dataclasses.fields(a)))
        return torch.from_numpy(np.ascontiguousarray(a)).to(self.device)

    def _forget(self, idx) -> None:
        """Invalidate the fused step's evaluation cache for the sub-envs ``idx`` (all if ``None``) after a reset."""
        if self.fused:
            self._ev_cache[1][slice(None) if idx is None else idx] = False

    def _masked(self, mask, v):
        """``v`` where ``mask``, else its dtype's zero (a numpy array, e.g. of strings, stays on the host)."""
        if is_torch(v):
            return self._xp.where(mask, v, _zero_like(v))
        return np.where(to_host(mask), v, _zero_like(v))

    def _draw(self, idx: np.ndarray, pins: dict[str, Any]) -> GraspObject:
        """Objects for sub-envs ``idx``, from each one's own stream (the vector env's only source of randomness)."""
        u = self._streams.random(idx, task.draw_count(self.config))
        pins = {k: to_host(v) for k, v in pins.items()}
        obj = task.object_from_uniforms(u, self.config, pinned=pins, batch=True)
        self._warned = task.warn_if_beyond_convergence(obj, self._warned)
        return self._to_device(obj)

    def _observe(self, state: task.EnvState) -> np.ndarray:
        return task.observation(state.command, state.eq.volume_change, self._params.task, self._params.volume_scale)

    def _seed(self, seed, idx: np.ndarray) -> None:
        n = self.num_envs
        if seed is None:
            if self._seeded:
                return
            root = int(np.random.SeedSequence().generate_state(2, np.uint64)[0] >> np.uint64(1))
            seed = root
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
            # sub-env i is seeded seed + i, and only the sub-envs being reset (as SyncVectorEnv's reset_mask does)
            self._streams.seed(idx, _seed_words(seed, n)[:, idx])
            super().reset(seed=int(seed))  # Gymnasium's vector-level np_random (not used by this env)
        else:
            try:
                seeds = list(seed)
            except TypeError:
                raise ValueError(f"seed must be None, an int or a list of {n} ints/None, got {seed!r}") from None
            if len(seeds) != n:
                raise ValueError(f"seed must be None, an int or a list of num_envs={n} seeds, got {len(seeds)}")
            given = np.array([s is not None for s in seeds], dtype=bool)
            if not self._seeded and not given.all():
                raise ValueError("the first seeding must give a seed for every sub-env (no None)")
            sel = np.intersect1d(np.flatnonzero(given), idx)  # a seed for a sub-env not being reset is unused
            if sel.size:
                self._streams.seed(sel, _seed_words([seeds[i] for i in sel], sel.size))
        self._seeded = True

    def _info(self, state: task.EnvState, res: task.Step | None, mask: np.ndarray | None) -> dict[str, Any]:
        """The info of ``state`` (after ``res``, or at reset), as Gymnasium's vector info: ``(N,)`` arrays, each
        with a ``_key`` mask (``mask``, or all true). Fresh arrays: the state is never handed out."""
        n = self.num_envs
        keys = self.info_keys
        if keys is not None and not keys:
            return {}
        info = task.build_info(state, self._params.task, res, self.info_level)
        if keys is not None:
            info = {k: v for k, v in info.items() if k in keys}
        own = {id(v) for rec in (state.eq, state.thresholds, state.task) for v in rec}
        own.update(id(getattr(state.obj, f.name)) for f in dataclasses.fields(state.obj))
        if res is not None:
            own.update(id(v) for v in res.solve)
        xp = self._xp
        base = xp.full(n, True, "bool") if mask is None else mask
        out: dict[str, Any] = {}
        for k, v in info.items():
            if is_torch(v):
                v = v.expand(n).clone() if v.ndim == 0 else (v.clone() if id(v) in own else v)
            elif np.ndim(v) == 0:
                v = np.full(n, v)
                if xp is not NUMPY:
                    v = self._to_device(v)
            elif id(v) in own:
                v = v.copy()
            out[k] = v
            out["_" + k] = _copy(base)  # one array per key, as Gymnasium's vector envs give
        return out

    def step(self, actions):
        if self._state is None:
            raise ResetNeeded("call reset() before step()")
        a = task.batch_actions(actions, self.num_envs, self.device)
        res = self._step_fn(self._state, a)
        terminated, truncated, reward = res.terminated, res.truncated, res.reward
        if self._xp is NUMPY:
            terminated = np.asarray(terminated, dtype=bool)
            truncated = np.asarray(truncated, dtype=bool)
            reward = np.asarray(reward, dtype=np.float64)
        state = res.state
        if self.max_episode_steps is not None:
            truncated = truncated | (state.task.step >= self.max_episode_steps)
        obs = res.obs
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            return self._step_next(res, obs, reward, terminated, truncated)
        info = self._info(state, res, None)
        self._state = state
        done = terminated | truncated
        if not done.any():
            self._obs = _copy(obs)
            return obs, reward, terminated, truncated, info

        # SAME_STEP autoreset: the ended step's observation and info go to final_obs / final_info.
        xp = self._xp
        host_idx = np.flatnonzero(to_host(done))
        idx = self._to_device(host_idx)
        final_info = {k: self._masked(done, v) for k, v in info.items() if k[0] != "_"}
        final_info["is_success"] = done & res.outcome.success
        final_info = {k2: v2 for k, v in final_info.items() for k2, v2 in ((k, v), ("_" + k, _copy(done)))}
        if xp is NUMPY:
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_obs[idx] = np.fromiter(obs[idx], dtype=object, count=idx.size)
        else:  # a tensor (N, obs_dim), masked by _final_obs
            final_obs = xp.where(done[:, None], obs, 0.0)
        self._state = task.autoreset(state, idx, self._draw(host_idx, {}), self._params, self._contact)
        self._forget(idx)
        obs = _copy(obs)
        obs[idx] = self._observe(self._state)[idx]
        self._merge_reset_info(info, done, host_idx, idx)
        info["final_obs"], info["_final_obs"] = final_obs, _copy(done)
        info["final_info"], info["_final_info"] = final_info, _copy(done)
        self._obs = _copy(obs)
        return obs, reward, terminated, truncated, info

    def _step_next(self, res: task.Step, obs, reward, terminated, truncated):
        """NEXT_STEP autoreset: a sub-env whose episode ended on the previous step is reset now (its action is
        ignored): the reset's observation and info, reward 0, not terminated or truncated."""
        pending = self._pending
        state = res.state
        done = (terminated | truncated) & ~pending
        info = self._info(state, res, None)
        if done.any():
            info["is_success"] = done & res.outcome.success
            info["_is_success"] = _copy(done)
        if pending.any():
            host_idx = np.flatnonzero(to_host(pending))
            idx = self._to_device(host_idx)
            state = task.autoreset(state, idx, self._draw(host_idx, {}), self._params, self._contact)
            self._forget(idx)
            obs = _copy(obs)
            obs[idx] = self._observe(state)[idx]
            reward = self._xp.where(pending, 0.0, reward)
            terminated, truncated = terminated & ~pending, truncated & ~pending
            self._state = state
            self._merge_reset_info(info, pending, host_idx, idx)
        self._state = state
        self._pending = done
        self._obs = _copy(obs)
        return obs, reward, terminated, truncated, info

    def _merge_reset_info(self, info: dict[str, Any], reset, host_idx: np.ndarray, idx) -> None:
        """Put the reset info of the sub-envs ``reset`` (already reset in ``self._state``; their indices ``host_idx``
        on the host, ``idx`` on the backend's device) into ``info``."""
        for k, v in self._info(self._state, None, reset).items():
            if k[0] == "_":
                continue
            if k in info:
                i = idx if is_torch(v) else host_idx
                info[k][i] = v[i]
            else:  # a key only a reset info has (the object's constants, at the lean level)
                info[k] = self._masked(reset, v)
                info["_" + k] = _copy(reset)

    # ---- rendering ----------------------------------------------------------------------------------------
    def render_state(self, i: int):
        """What :func:`pneunet_env.envs.render.render_frame` draws for sub-env ``i``."""
        from pneunet_env.envs.render import render_state

        if self._state is None:
            raise RuntimeError("call reset() before render()")
        return render_state(_on_host(self._state), self._params, i, class_names=self.object_class_names)

    def render(self) -> tuple[np.ndarray, ...] | None:
        """``rgb_array``: one frame per sub-env (a tuple of ``(H, W, 3)`` uint8 arrays)."""
        if self.render_mode is None:
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                'Pass render_mode="rgb_array" to gym.make_vec("PneuNetGrasp-v0", ...).'
            )
            return None
        from pneunet_env.envs.render import render_frame

        r = self.config.render
        return tuple(render_frame(self.render_state(i), r.width, r.height, chambers=r.chambers)
                     for i in range(self.num_envs))
