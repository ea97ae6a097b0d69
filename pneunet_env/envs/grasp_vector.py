"""``PneuNetGrasp-v1`` natively batched: N grasps advanced together by one batched solve (no loop over envs).

:class:`PneuNetGraspVectorEnv` is what ``gym.make_vec("PneuNetGrasp-v1", num_envs=N)`` returns. It runs the
same rules as the single environment (:class:`pneunet_env.envs.grasp.PneuNetGraspEnv`), through the same pure
functions of :mod:`pneunet_env.task` called on ``(N,)`` arrays instead of scalars (gymnax style: the single
env is the N = 1 case), with a batched solve in place of the scalar one. Three back-ends: ``numba`` (the default
with numba: the whole step as one compiled loop, :func:`pneunet_env.fused.fused_step`), ``numpy`` (the array step
with :func:`pneunet_env.physics.batched.solve_batch`) and ``torch`` (the same array step on tensors of a device,
with the masked solver :mod:`pneunet_env.physics.masked`).

It is, step for step, ``gym.make_vec("PneuNetGrasp-v1", num_envs=N, vectorization_mode="sync",
vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP})`` (N single envs) computed as arrays: the same
observations, rewards, ends, info (Gymnasium's vector convention, a dict of ``(N,)`` arrays with ``_key``
masks) and random objects, with episodes that end and auto-reset. With the numba back-end's fused step that holds
bit for bit on one install (tested): both draw objects through the same ufuncs and step through the same compiled
loop. The array step (``fused=False``, numpy, torch) gives the same to round-off (tested to 1e-10), and follows no
free steps along the free actuator's table (``solver.free_table``), so against it compare with ``free_table=False``.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
import os
import threading
from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError, ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from pneunet_env import fused_cuda, task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.envs.grasp import observation_space
from pneunet_env.envs.streams import PCG64Streams
from pneunet_env.envs.streams import seed_words as _seed_words
from pneunet_env.fused import HAVE_FUSED, fused_step, new_cache
from pneunet_env.objects import GraspObject
from pneunet_env.physics.batched import BACKENDS, check_threads
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.physics.xp import NUMPY, is_torch, to_host, torch_ops
from pneunet_env.physics.xp import copy as _copy

__all__ = ["PneuNetGraspVectorEnv", "PCG64Streams"]


# ------------------------------------------------------------------------------------------------------
# The vector env
# ------------------------------------------------------------------------------------------------------


_MODES = (AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP)


def _autoreset_mode(mode) -> AutoresetMode:
    """``AutoresetMode.SAME_STEP`` or ``NEXT_STEP`` (the enum, its value ``"SameStep"``/``"NextStep"`` or its name)."""
    for m in _MODES:
        if mode is m or (isinstance(mode, str) and (mode == m.value or mode.upper() == m.name)):
            return m
    raise ValueError(f"autoreset_mode must be AutoresetMode.SAME_STEP or NEXT_STEP (or 'SameStep'/'NextStep'), "
                     f"got {mode!r}")


_INT64_MAX = 2**63 - 1
BYTES_PER_ENV = 4096
"""An upper estimate of the host memory one sub-env takes, in bytes: its state (300-400 B), a step's temporaries and
info arrays (1-2 KB measured at N = 20 000, numpy and numba back-ends) and its share of the batched spaces."""


def _memory_bytes() -> int | None:
    """This machine's physical memory in bytes (``None`` where the OS does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def max_num_envs() -> int:
    """The largest ``num_envs`` accepted: this machine's physical memory over :data:`BYTES_PER_ENV` (at least 1;
    ``2**31 - 1`` where the memory is unknown)."""
    mem = _memory_bytes()
    return 2**31 - 1 if mem is None else max(1, mem // BYTES_PER_ENV)


def _check_num_envs(num_envs) -> int:
    """``num_envs`` as an int in ``[1, max_num_envs()]``; ``ValueError`` naming it otherwise."""
    try:
        if isinstance(num_envs, (bool, np.bool_)):
            raise TypeError
        n = operator.index(num_envs)
    except TypeError:
        raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}") from None
    if n < 1:
        raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
    top = max_num_envs()
    if n > top:
        need = f"{n * BYTES_PER_ENV / 2**30:.3g}" if n < 2**900 else "more than 1e270"  # a float holds it
        raise ValueError(f"num_envs={n} is too large: it would need about {need} GiB "
                         f"({BYTES_PER_ENV} bytes per sub-env), more than this machine's memory allows "
                         f"(at most {top} envs)")
    return n


def _torch_device(device):
    """``device`` as a ``torch.device`` that can hold data (``None``: the CPU); ``ValueError`` naming it otherwise
    (an unknown or unavailable device, or ``"meta"``, which has shapes but no data)."""
    try:
        import torch
    except ImportError:
        raise ValueError("backend='torch' needs torch (pip install torch)") from None
    try:
        dev = torch.device("cpu" if device is None else device)
    except (RuntimeError, TypeError, ValueError) as exc:
        raise ValueError(f"device must name an available torch device, got {device!r} ({exc})") from None
    if dev.type == "meta":
        raise ValueError(f"device must be one that holds data (cpu, cuda, mps, ...), got {device!r}: a 'meta' "
                         f"tensor has a shape but no values")
    try:
        torch.zeros(1, device=dev).add_(1).cpu().item()  # a round trip: the device exists and holds values
    except (RuntimeError, TypeError, AssertionError, NotImplementedError) as exc:
        raise ValueError(f"device must name an available torch device, got {device!r} ({exc})") from None
    return dev


def _pin_rows(pins: dict[str, Any], idx: np.ndarray, n: int) -> dict[str, Any]:
    """The reset pins of the sub-envs ``idx``: an ``(n,)`` value gives each its own entry, anything else is shared
    (and checked by :func:`pneunet_env.task.object_from_uniforms`); ``ValueError`` naming a ragged value."""
    out = {}
    for k, v in pins.items():
        try:
            a = np.asarray(to_host(v))
        except (ValueError, TypeError):
            raise ValueError(f"reset option {k!r} must be a number or an ({n},) array of numbers, got {v!r}") from None
        out[k] = a[idx] if a.shape == (n,) else v
    return out


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
    """N pneu-net grasps (``PneuNetGrasp-v1``) stepped together, with one batched quasi-static solve per step.

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

    ``gym.make_vec("PneuNetGrasp-v1", num_envs=N, render_mode=None, config=None, **overrides)``, or
    ``PneuNetGraspVectorEnv(num_envs, ...)``:

    * ``config`` / ``overrides``: as for the single env (:func:`pneunet_env.config.load_config`), shared by all.
    * ``max_episode_steps``: a time limit (what ``gym.make``'s ``TimeLimit`` does: ``truncated`` once a
      sub-env has taken that many steps); ``make_vec`` passes the registered 100. ``None``: only the
      task's own end (``squeeze_steps + hold_steps``).
    * ``backend``: the batched solver's, ``"auto"`` (numba if installed, else numpy), ``"numba"``, ``"numpy"`` or
      ``"torch"``. With ``"torch"`` the whole state lives on ``device`` as float64 tensors and the step is the same
      pure :func:`pneunet_env.task.step` on tensors with the masked solver (:mod:`pneunet_env.physics.masked`):
      observations (float32), rewards (float64), flags and info values are **torch tensors on the device**
      (``obs.cpu().numpy()`` gives numpy; actions may be tensors or arrays; a tensor that requires grad is
      detached, so no autograd graph is kept from step to step). Objects are still drawn from the
      per-env PCG64 streams on the host (the same draws as every other backend) and sent to the device at reset.
      ``final_obs`` is then an ``(N, obs_dim)`` tensor masked by ``_final_obs`` (not an object array).
    * ``device``: torch only: ``"cpu"`` (default), ``"cuda"``, ``"cuda:1"``, ``"mps"``, ...: a device that holds data
      (checked by a round trip at construction; ``"meta"`` is refused).
    * ``compile``: torch only: run the solver's round through ``torch.compile`` (pays on a GPU; see the benchmark).
    * ``parallel``: numba only: split the solve over the cores (numba's threads, ``NUMBA_NUM_THREADS``); ``None``
      from :data:`pneunet_env.physics.batched.PARALLEL_MIN_ENVS` envs on. Pass ``False`` when other processes keep the
      cores busy: numba's threads then wait on each other (a step can take 10x longer). ``True``, ``False`` or
      ``None`` only (``TypeError`` otherwise: a string such as ``"no"`` is not read as a flag); ``True`` with
      ``backend="numpy"`` or ``"torch"`` is refused.
    * ``fused``: numba only (default there): the whole step as one compiled loop over the envs
      (:func:`pneunet_env.fused.fused_step`: the pressure update, the solve, the rules and the observation), bit for
      bit :func:`pneunet_env.task.step`'s result with ``free_table=False`` (with the free actuator's table, the
      default, a step that touches nothing is the same minimum to the solver's tolerance, in 1-2 evaluations);
      ``False``: the array step around the batched solve (no table).
    * ``kernel``: torch only: the fused step as one CUDA kernel (:mod:`pneunet_env.fused_cuda`, the fused loop's own
      code on the device; the same results as ``fused`` to round-off), the default (``None``) on a CUDA device where
      numba-cuda is installed (``pip install pneunet-env[gpu]``); ``False``: the masked solver round by round (as
      without numba-cuda, and as with ``compile=True``); ``True`` where it cannot run raises ``ValueError``.
    * ``info_keys``: the info keys to build each step (``None``: every key of ``info_level``; ``()``: none, the
      fastest, for training loops that read nothing from the info). ``final_obs`` and ``final_info`` (with
      ``is_success``) are always given where episodes end.
    * ``num_threads``: numba only: the parallel loop's threads (``None``: chosen by N,
      :func:`pneunet_env.physics.batched.threads_for`: one per 512 envs, at most ``NUMBA_NUM_THREADS``).

    * ``num_envs``: at most :func:`max_num_envs` (this machine's memory over :data:`BYTES_PER_ENV`), so that a
      too-large batch is refused by name at once rather than failing in an allocation.

    ``reset(options=...)`` takes the single env's pins (applied to every sub-env reset by the call; a value
    may be an ``(N,)`` array, one per sub-env) and ``"reset_mask"`` (an ``(N,)`` bool array: reset only
    those; the others keep their state and have ``_key`` masks false in the info). A mask must reset at least one
    sub-env (all false raises ``ValueError``, as Gymnasium's ``SyncVectorEnv`` does).

    ## Threads and pickling

    One env is stepped by one thread at a time: a ``step`` or ``reset`` that starts while another runs (from
    another thread) raises ``RuntimeError`` rather than losing or doubling steps; use one env per thread. The env
    pickles (``pickle``, ``cloudpickle``, ``copy.deepcopy``): the unpickled copy has the same state and random
    streams and steps on exactly as the original would (the backend's compiled functions are rebuilt on loading).
    ``gym.make_vec(..., vectorization_mode="async")`` runs single envs in subprocesses (their factories pickle); to
    hand this vector env to another process, send it or a factory (``functools.partial(PneuNetGraspVectorEnv, 64)``).

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
        kernel: bool | None = None,
        info_keys: Sequence[str] | None = None,
        **overrides: Any,
    ) -> None:
        n = _check_num_envs(num_envs)
        if render_mode is not None and not (isinstance(render_mode, str)
                                            and render_mode in self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if not isinstance(backend, str) or backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if parallel is not None and not isinstance(parallel, (bool, np.bool_)):
            raise TypeError(f"parallel must be True, False or None, got {parallel!r}")
        parallel = None if parallel is None else bool(parallel)
        if parallel and backend in ("numpy", "torch"):
            raise ValueError(f"parallel=True is for the numba backend only, got it with backend={backend!r}")
        if backend == "torch" and num_threads is not None:
            raise ValueError(f"num_threads is for the numba backend (torch: torch.set_num_threads), "
                             f"got {num_threads!r}")
        if backend == "numpy" and num_threads is not None:
            raise ValueError(f"num_threads is for the numba backend only, got {num_threads!r} with backend='numpy'")
        try:
            check_threads(num_threads)
        except ValueError as exc:
            raise ValueError(f"num_threads: {exc}") from None
        if not isinstance(compile, (bool, np.bool_)):
            raise ValueError(f"compile must be True or False, got {compile!r}")
        compile = bool(compile)
        if backend != "torch" and (device is not None or compile):
            raise ValueError(f"device and compile are for backend='torch' only, got device={device!r}, "
                             f"compile={compile!r} with backend={backend!r}")
        self.device = _torch_device(device) if backend == "torch" else None
        if not isinstance(info_level, str) or info_level not in task.INFO_LEVELS:
            raise ValueError(f"info_level must be one of {task.INFO_LEVELS}, got {info_level!r}")
        if max_episode_steps is not None:
            try:
                if isinstance(max_episode_steps, (bool, np.bool_)):
                    raise TypeError
                max_episode_steps = operator.index(max_episode_steps)
            except TypeError:
                raise ValueError(f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}") \
                    from None
            if not 1 <= max_episode_steps <= _INT64_MAX:  # the step counters are int64
                raise ValueError(f"max_episode_steps must be an integer in [1, 2**63 - 1] or None, got "
                                 f"{max_episode_steps!r}")
        if info_keys is not None:
            keys = None if isinstance(info_keys, (str, bytes)) or not isinstance(info_keys, Iterable) \
                else tuple(info_keys)
            if keys is None or not all(isinstance(k, str) for k in keys):
                raise ValueError(f"info_keys must be a sequence of key names (or None), got {info_keys!r}")
            info_keys = keys
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
        # the array namespace, chosen once and carried in the params (the task's functions never test their input)
        self._params = task.EnvParams.from_config(self.config, NUMPY if self.device is None else torch_ops(self.device))
        self.object_class_names: tuple[str, ...] = task.class_names(self.config)
        """The catalogue classes, by the integer code of ``info["object_class"]`` (-1: drawn from ranges)."""
        numba_backend = backend == "numba" or (backend == "auto" and HAVE_FUSED)
        if fused is None:
            fused = numba_backend
        if not isinstance(fused, bool) or (fused and not numba_backend):
            raise ValueError(f"fused must be True (numba backend only) or False, got {fused!r} with "
                             f"backend={backend!r}")
        self.fused = fused
        if kernel is not None and (not isinstance(kernel, bool) or backend != "torch"):
            raise ValueError(f"kernel must be True, False or None (backend='torch' only), got {kernel!r} with "
                             f"backend={backend!r}")
        can_kernel = backend == "torch" and fused_cuda.kernel_available(self.device)
        if kernel and (not can_kernel or compile):
            raise ValueError(f"kernel=True needs numba-cuda (pip install pneunet-env[gpu]) and a CUDA device, and "
                             f"no compile, got device={str(self.device)!r}, compile={compile!r}")
        self.kernel = bool(kernel) if kernel is not None else \
            can_kernel and not compile and self.device.type == "cuda"
        """Whether the step is the fused loop's CUDA kernel (:mod:`pneunet_env.fused_cuda`)."""
        self._compile = compile
        self._num_threads = num_threads
        if fused:
            # the energy evaluation each env's last step ended on: the next step's first (fused.fused_step)
            self._ev_cache = new_cache(n)
        elif self.kernel:  # the same, on the device
            self._ev_cache = fused_cuda.new_device_cache(n, self.device)
        self._busy = threading.Lock()  # the re-entrancy guard of step/reset: one thread at a time
        self._build_backend()
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.single_observation_space = observation_space(self.config)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._streams = PCG64Streams(n)
        self._seeded = False
        self._state: task.EnvState | None = None
        # the last state handed out (the state property), while the env's state still shares arrays with it (the
        # objects', the thresholds': a step passes them on): an autoreset copies those before writing, and writes
        # the others in place; after it, nothing is shared (None)
        self._handed_out: task.EnvState | None = None
        self._obs: np.ndarray | None = None
        self._pending = self._xp.full(n, False, "bool")  # NEXT_STEP: sub-envs to reset on the next step
        self._warned = False

    def _build_backend(self) -> None:
        """The array namespace and the step function of the backend (rebuilt on unpickling: they hold closures)."""
        if self.backend == "torch":
            self._xp = torch_ops(self.device)
            self._contact = functools.partial(task.torch_contact_batch, compile=self._compile)
        else:
            self._xp = NUMPY
            self._contact = functools.partial(task.newton_contact_batch, backend=self.backend, parallel=self.parallel,
                                              threads=self._num_threads)
        if self.kernel:
            self._step_fn = fused_cuda.DeviceStep(self._params, self._ev_cache, self.device)
        elif self.fused:
            self._step_fn = functools.partial(fused_step, params=self._params, parallel=self.parallel,
                                              threads=self._num_threads, cache=self._ev_cache)
        else:
            self._step_fn = functools.partial(task.step, params=self._params, contact=self._contact)

    # ---- pickling ------------------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """The env's state without what cannot be pickled (the backend's namespace and step function, the guard's
        lock): :meth:`__setstate__` rebuilds them, so an unpickled env steps on exactly as the original would."""
        if self._busy.locked():
            raise RuntimeError(f"{type(self).__name__} cannot be pickled while a step or reset runs in another "
                               f"thread")
        state = self.__dict__.copy()
        for key in ("_xp", "_contact", "_step_fn", "_busy"):
            state.pop(key, None)
        state["_handed_out"] = None  # the copy's state is handed to no one
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._busy = threading.Lock()
        self._build_backend()

    # ---- the re-entrancy guard ------------------------------------------------------------------------------
    def _enter(self, what: str) -> threading.Lock:
        """The guard's lock, for a ``with`` (its C ``__enter__`` takes it and arms the release at once: a Ctrl-C
        raised anywhere in the step cannot leave it held); a ``RuntimeError`` if a step or reset already runs. (Two
        calls that start at the same instant can both pass the check: the second then waits for the first, one at a
        time still, instead of raising.)"""
        if self.closed:  # as Gymnasium's AsyncVectorEnv: a closed env is not reopened
            raise ClosedEnvironmentError(f"{type(self).__name__}.{what}() after close(): a closed env is not "
                                         f"reopened; make a new one")
        if self._busy.locked():
            raise RuntimeError(f"{type(self).__name__}.{what}() called while another step() or reset() of the same "
                               f"env is running (from another thread, or re-entered): a vector env is stepped by one "
                               f"thread at a time")
        return self._busy

    # ---- state, for users ------------------------------------------------------------------------------
    @property
    def state(self) -> task.EnvState | None:
        """The whole state (:class:`pneunet_env.task.EnvState` of ``(N,)`` arrays; never changed in place)."""
        self._handed_out = self._state  # an autoreset must not write into the arrays someone may hold
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
        cache = self._ev_cache if self.fused or self.kernel else ()
        arrays = [s.command, *s.eq, *obj, *s.thresholds, *s.task, self._obs, *cache]
        size = sum(a.element_size() * a.nelement() if is_torch(a) else np.asarray(a).nbytes for a in arrays)
        return int(size) + self._streams.nbytes

    # ---- Gymnasium API -----------------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Reset all sub-envs (or those of ``options["reset_mask"]``, which must reset at least one, as Gymnasium's
        vector envs require); see the class docstring for seeds. One thread at a time (``RuntimeError`` otherwise).
        After :meth:`close`: ``gymnasium.error.ClosedEnvironmentError``, as for :meth:`step`."""
        with self._enter("reset"):
            return self._reset(seed, options)

    def _reset(self, seed, options):
        n = self.num_envs
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict (object pins, 'reset_mask'), got {options!r}")
        pins = dict(options or {})
        mask = pins.pop("reset_mask", None)
        if mask is not None:
            try:
                mask = np.asarray(to_host(mask))
            except (ValueError, TypeError):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},), got {mask!r}") from None
            if mask.dtype != bool or mask.shape != (n,):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},), got "
                                 f"{mask.dtype} {mask.shape}")
            if not mask.any():  # as gymnasium.vector.SyncVectorEnv.reset
                raise ValueError(f"options['reset_mask'] must reset at least one sub-env (a True value), got all "
                                 f"{n} False: to reset none, do not call reset")
            if self._state is None and not mask.all():
                raise ValueError("the first reset must reset every sub-env (reset_mask all true)")
            if mask.all():
                mask = None  # every sub-env: a full reset
        idx = np.arange(n) if mask is None else np.flatnonzero(mask)
        self._seed(seed, idx)
        pins = _pin_rows(pins, idx, n)
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
        self._handed_out = None  # a state of fresh arrays
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
        if self.fused or self.kernel:
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
            what = f"seed must be None, an int or a list of num_envs={n} ints/None, got {seed!r} ({type(seed).__name__}"
            if isinstance(seed, (str, bytes, bytearray)):  # not a list of seeds: its length counts characters
                raise ValueError(what + ")")
            try:
                seeds = list(seed)
            except TypeError:
                raise ValueError(what + ")") from None
            if len(seeds) != n:
                raise ValueError(f"{what} of {len(seeds)})")
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
        for k, v in info.items():  # every value is an (N,) array of the namespace (solver_status: on the host)
            out[k] = xp.copy(v) if id(v) in own else v  # the state's own arrays are never handed out
            out["_" + k] = _copy(base)  # one array per key, as Gymnasium's vector envs give
        return out

    def step(self, actions):
        """One step of every sub-env; see the class docstring. On the torch backend a tensor action that requires
        grad is detached (the env is not differentiable: keeping its graph would grow the memory every step).
        One thread at a time: a ``step`` or ``reset`` that overlaps another raises ``RuntimeError``."""
        with self._enter("step"):
            return self._step(actions)

    def _step(self, actions):
        if self._state is None:
            raise ResetNeeded("call reset() before step()")
        if is_torch(actions):
            actions = actions.detach()  # no autograd graph in the state (the env is not differentiable)
        a = task.batch_actions(actions, self.num_envs, self.device)
        res = self._step_fn(self._state, a)
        terminated, truncated, reward = res.terminated, res.truncated, res.reward
        state = res.state
        if self.max_episode_steps is not None:
            truncated = truncated | (state.task.step >= self.max_episode_steps)
        obs = res.obs  # fresh arrays, handed out to no one yet: the autoreset writes into them
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
        final_info = {k: self._scatter(v, host_idx, idx) for k, v in info.items() if k[0] != "_"}
        final_info["is_success"] = done & res.outcome.success
        final_info = {k2: v2 for k, v in final_info.items() for k2, v2 in ((k, v), ("_" + k, _copy(done)))}
        if xp is NUMPY:
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_obs[idx] = np.fromiter(obs[idx], dtype=object, count=idx.size)
        else:  # a tensor (N, obs_dim), masked by _final_obs
            final_obs = xp.where(done[:, None], obs, 0.0)
        self._state = task.autoreset(state, idx, self._draw(host_idx, {}), self._params, self._contact,
                                     own=task.fresh_arrays(state, self._handed_out))
        self._handed_out = None
        self._forget(idx)
        obs[idx] = self._observe_rows(self._state, idx)
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
            state = task.autoreset(state, idx, self._draw(host_idx, {}), self._params, self._contact,
                                   own=task.fresh_arrays(state, self._handed_out))
            self._handed_out = None
            self._forget(idx)
            obs[idx] = self._observe_rows(state, idx)
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
        on the host, ``idx`` on the backend's device) into ``info``: computed for those sub-envs only (every value is
        entry by entry) and scattered."""
        keys = self.info_keys
        if keys is not None and not keys:
            return
        rows = task.build_info(task.take(self._state, idx), self._params.task, None, self.info_level)
        for k, v in rows.items():
            if keys is not None and k not in keys:
                continue
            i = idx if is_torch(v) else host_idx
            if k in info:
                info[k][i] = v
            else:  # a key only a reset info has (the object's constants, at the lean level)
                info[k] = self._scatter(v, host_idx, idx, rows=True)
                info["_" + k] = _copy(reset)

    def _scatter(self, v, host_idx: np.ndarray, idx, rows: bool = False):
        """An ``(N,)`` array of ``v``'s dtype (and device) holding ``v``'s entries ``idx`` there (``rows``: ``v`` holds
        just those entries, in order) and the dtype's zero (``None`` for strings) elsewhere: what :meth:`_masked`
        gives with the mask of ``idx``, by a scatter."""
        if is_torch(v):
            import torch

            out = torch.zeros((self.num_envs,) + tuple(v.shape[1:]), dtype=v.dtype, device=v.device)
            out[idx] = v if rows else v[idx]
            return out
        v = np.asarray(v)
        shape = (self.num_envs,) + v.shape[1:]
        out = np.full(shape, None, dtype=object) if v.dtype == object else np.zeros(shape, dtype=v.dtype)
        out[host_idx] = v if rows else v[host_idx]
        return out

    def _observe_rows(self, state: task.EnvState, idx):
        """The observations of the sub-envs ``idx`` of ``state`` (rows of :meth:`_observe`, computed for those only)."""
        return task.observation(state.command[idx], state.eq.volume_change[idx], self._params.task,
                                self._params.volume_scale)

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
                'Pass render_mode="rgb_array" to gym.make_vec("PneuNetGrasp-v1", ...).'
            )
            return None
        from pneunet_env.envs.render import render_frame

        r = self.config.render
        return tuple(render_frame(self.render_state(i), r.width, r.height, chambers=r.chambers)
                     for i in range(self.num_envs))
