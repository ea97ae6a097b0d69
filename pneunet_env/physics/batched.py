"""The quasi-static solve for N independent actuators at once (the engine of a natively batched vector env).

:func:`solve_batch` advances N states ``(kappa~_i, e_s_i)``, each an equilibrium at its pressure
``p0_i``, to the pressures ``p1_i``, with the algorithm of :mod:`pneunet_env.physics.solver` (safeguarded
modified Newton with an Armijo line search that never leaves the domain, tangent-predictor pressure
continuation with sub-step control, fold detection and snap). Its answers are those of
:func:`pneunet_env.physics.solver.step_state` called env by env (to round-off), with two back-ends:

* ``"numba"`` (numba installed): one compiled loop over the envs calling the compiled scalar
  continuation itself, optionally split over the CPU's cores (``numba.prange``). About a tenth to
  half a microsecond per env for a small pressure step.
* ``"numpy"`` (always available; what ``"auto"`` picks when numba is absent or ``PNEUNET_DISABLE_NUMBA=1``):
  the same control flow, vectorised. Every env carries its own program position (which descent,
  which Newton iteration, which line-search trial, its own sub-step size); each round evaluates the
  energy once for every env that needs an evaluation (:func:`pneunet_env.physics.mechanics.make_terms`'s
  numpy instantiation, the same formulas), then advances each env's control flow with masks. Envs
  that have finished are out of every later round. No Python loop over envs.

All quantities are dimensionless (lengths / ``w``, stresses and pressure / ``mu``), as in
:mod:`pneunet_env.physics.solver`.
"""

from __future__ import annotations

import math
import os
import sys
import threading

import numpy as np

from pneunet_env.physics import _jit, contact, continuation, masked, mechanics, xp
from pneunet_env.physics import solver as _solver
from pneunet_env.physics._jit import HAVE_NUMBA, njit_cached
from pneunet_env.physics.continuation import (
    STATUS_CONVERGED,
    STATUS_INACTIVE,
    STATUS_OUTSIDE,
    STATUS_ROUNDOFF,
    Solve,
    _follow_ev,
)
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import DEFAULT_OPTIONS, Equilibrium, SolverOptions, params_tuple
from pneunet_env.physics.xp import NUMPY, Ops, copy, is_torch, to_host, torch_ops

__all__ = ["BACKENDS", "PARALLEL_MIN_ENVS", "ENVS_PER_THREAD", "threads_for", "check_threads", "compile_loops",
           "run_loop", "solve_batch", "solve_batch_numba", "solve_batch_numpy", "solve_batch_torch"]

BACKENDS = ("auto", "numba", "numpy", "torch")


# --------------------------------------------------------------------------------------------------
# Input handling


def _column(name: str, value) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be real numbers, got {value!r}") from None
    if a.ndim > 1:
        raise ValueError(f"{name} must be a scalar or one-dimensional, got shape {a.shape}")
    return a


def _first_bad(name: str, a: np.ndarray, bad: np.ndarray, rule: str) -> None:
    if bad.any():
        i = int(np.flatnonzero(bad)[0]) if a.ndim else 0
        where = f"{name}[{i}]" if a.ndim else name
        v = a[i] if a.ndim else a[()]
        raise ValueError(f"{where} {rule}, got {float(v)!r}")


def _prepare(kappa, side_strain, p0, p1, object_stiffness, object_curvature, active, validate):
    cols = {
        "kappa": kappa,
        "side_strain": side_strain,
        "p0": p0,
        "p1": p1,
        "object_stiffness": object_stiffness,
        "object_curvature": object_curvature,
    }
    arrays = {name: _column(name, v) for name, v in cols.items()}
    if validate:
        for name, a in arrays.items():
            _first_bad(name, a, ~np.isfinite(a), "must be finite")
        _first_bad("p0", arrays["p0"], arrays["p0"] < 0.0, "(p~ = p/mu) must be >= 0")
        _first_bad("p1", arrays["p1"], arrays["p1"] < 0.0, "(p~ = p/mu) must be >= 0")
        _first_bad("object_stiffness", arrays["object_stiffness"], arrays["object_stiffness"] < 0.0,
                   "(k~_obj = k_obj w/mu) must be >= 0")
        ko = arrays["object_curvature"]
        _first_bad("object_curvature", ko, ~((ko > 0.0) & (ko < math.pi)), "(w kappa_obj) must be in (0, pi)")
    try:
        shape = np.broadcast_shapes(*(a.shape for a in arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k}: {a.shape}" for k, a in arrays.items())
        raise ValueError(f"inputs must broadcast to one shape (N,), got {shapes}") from None
    if shape == ():
        shape = (1,)
    out = [np.ascontiguousarray(np.broadcast_to(a, shape)) for a in arrays.values()]
    if active is None:
        act = np.ones(shape, dtype=bool)
    else:
        act = np.asarray(active)
        if act.dtype != bool:
            raise ValueError(f"active must be a boolean mask, got dtype {act.dtype}")
        if act.shape != shape:
            raise ValueError(f"active has shape {act.shape}, expected {shape}")
        act = np.ascontiguousarray(act)
    return out, act


def _check_domain(result: Equilibrium, kappa: np.ndarray, side_strain: np.ndarray) -> None:
    """``ValueError`` naming the first start state outside the domain (``kappa``, ``side_strain``: the host inputs;
    ``result``'s arrays may be tensors)."""
    bad = to_host(result.status == STATUS_OUTSIDE)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"start state {i} (kappa[{i}]={float(kappa[i])!r}, side_strain[{i}]={float(side_strain[i])!r}) "
            "is outside the domain"
        )


def solve_batch(
    kappa,
    side_strain,
    p0,
    p1,
    object_stiffness=0.0,
    object_curvature=0.02,
    params: ActuatorParams | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
    *,
    active=None,
    backend: str = "auto",
    validate: bool = True,
    parallel: bool | None = None,
    device=None,
    threads: int | None = None,
) -> Equilibrium:
    """Follow N equilibria from pressures ``p0`` to ``p1`` (quasi-static loading), all at once.

    Args:
        kappa: ``kappa~_i = w kappa``: start curvatures, shape ``(N,)`` (or a scalar, broadcast).
        side_strain: ``e_s`` of the start states.
        p0: the pressures ``p~ = p/mu >= 0`` at which the start states are equilibria (they are
            polished there first, as :func:`pneunet_env.physics.solver.solve_equilibrium` does).
        p1: the target pressures ``p~ >= 0``.
        object_stiffness: ``k~_obj = k_obj w/mu >= 0`` per env (0: free actuator).
        object_curvature: ``w kappa_obj`` in ``(0, pi)`` per env.
        params: the actuator (shared by all envs); paper defaults if ``None``.
        options: solver tolerances (shared).
        active: optional boolean mask ``(N,)``; inactive envs are not solved: they keep their input state, with
            NaN energy, gradient norm, eigenvalue and volume change, zero counts, ``converged`` false and
            ``status`` -1 (``STATUS_INACTIVE``).
        backend: ``"auto"`` (numba if available, else numpy), ``"numba"``, ``"numpy"`` or ``"torch"`` (the masked
            solver on torch tensors; needs torch). With ``"torch"`` the result's arrays are float64 tensors on
            ``device``; the inputs may be numpy arrays, numbers or tensors.
        validate: check the inputs (finite, signs, ranges) and raise ``ValueError`` naming the first
            bad value. A start state outside the domain always raises.
        parallel: numba back-end only: split the envs over the cores (numba's threads). ``None``: from
            :data:`PARALLEL_MIN_ENVS` envs on, with :func:`threads_for` threads. ``False`` where the cores are busy
            with other work (numba's OpenMP threads wait actively and lose badly when oversubscribed).
        device: torch back-end only: the device (``"cpu"``, ``"cuda"``, ...); ``None``: that of the first tensor
            input, else the CPU.
        threads: numba back-end only: the number of threads of the parallel loop (``1 <= threads <=
            NUMBA_NUM_THREADS``; 1 runs the serial loop). ``None``: :func:`threads_for` ``(N)``.

    Returns:
        An :class:`~pneunet_env.physics.solver.Equilibrium` of ``(N,)`` arrays (fresh each call); entry ``i``
        equals ``solve_equilibrium(p1[i], ..., initial=(kappa[i], side_strain[i]), initial_pressure=p0[i])``.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numba" and not HAVE_NUMBA:
        raise ValueError("backend='numba' needs numba (pip install pneunet-env[fast]; PNEUNET_DISABLE_NUMBA unset)")
    if backend == "torch":
        return _solve_batch_torch_api(kappa, side_strain, p0, p1, object_stiffness, object_curvature, params, options,
                                      active, validate, device)
    if device is not None:
        raise ValueError(f"device is for backend='torch' only, got device={device!r} with backend={backend!r}")
    check_threads(threads)
    (k, s, a0, a1, kobj, ko), act = _prepare(kappa, side_strain, p0, p1, object_stiffness, object_curvature,
                                             active, validate)
    prm = params_tuple(params)
    opts = options.as_tuple()
    if backend == "numpy" or (backend == "auto" and not HAVE_NUMBA):
        result = solve_batch_numpy(k, s, a0, a1, kobj, ko, prm, opts, act)
    else:
        result = solve_batch_numba(k, s, a0, a1, kobj, ko, prm, opts, act, parallel, threads)
    _check_domain(result, k, s)
    return result


def _solve_batch_torch_api(kappa, side_strain, p0, p1, object_stiffness, object_curvature, params, options, active,
                           validate, device) -> Equilibrium:
    try:
        import torch
    except ImportError:
        raise ValueError("backend='torch' needs torch (pip install torch)") from None
    inputs = (kappa, side_strain, p0, p1, object_stiffness, object_curvature)
    if device is None:
        device = next((v.device for v in inputs if is_torch(v)), "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise ValueError(f"device must name a torch device, got {device!r} ({exc})") from None
    cols, act = _prepare(*(to_host(v) for v in inputs), to_host(active), validate)
    k, s, a0, a1, kobj, ko = (torch.tensor(c, dtype=torch.float64, device=dev) for c in cols)
    result = solve_batch_torch(k, s, a0, a1, kobj, ko, params_tuple(params), options.as_tuple(),
                               torch.as_tensor(act, device=dev))
    _check_domain(result, cols[0], cols[1])
    return result


def _result(raw: Solve, p1, kobj, ko, chamber_height: float, ops: Ops = NUMPY) -> Equilibrium:
    """The :class:`Equilibrium` of a back-end's outputs (a :class:`~pneunet_env.physics.solver.Solve` of ``(N,)``
    arrays): eq. 3.1 and ``e_m`` from the state, as the scalar
    :func:`pneunet_env.physics.solver.equilibrium` computes them (arrays of the namespace ``ops``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        delta, force, touching = masked.kernels(ops).contact(raw.kappa, kobj, ko)
    status = raw.status
    return Equilibrium(
        copy(p1), raw.kappa, raw.side_strain, chamber_height * (1.0 + raw.side_strain) * raw.kappa, force, delta,
        touching, raw.volume_change, raw.energy, raw.gradient_norm, raw.min_eigenvalue,
        (status >= STATUS_CONVERGED) & (status <= STATUS_ROUNDOFF), raw.iterations, raw.substeps, raw.snapped,
        status, copy(kobj), copy(ko), raw.evaluations, raw.backtracks,
    )


def _allocate(k, s) -> Solve:
    n = k.shape[0]
    return Solve(
        kappa=k.copy(),
        side_strain=s.copy(),
        energy=np.full(n, np.nan),
        gradient_norm=np.full(n, np.nan),
        min_eigenvalue=np.full(n, np.nan),
        iterations=np.zeros(n, dtype=np.int64),
        substeps=np.zeros(n, dtype=np.int64),
        snapped=np.zeros(n, dtype=bool),
        status=np.full(n, STATUS_INACTIVE, dtype=np.int64),
        volume_change=np.full(n, np.nan),
        evaluations=np.zeros(n, dtype=np.int64),
        backtracks=np.zeros(n, dtype=np.int64),
    )


# --------------------------------------------------------------------------------------------------
# Compiled back-end: a loop over envs around the compiled scalar continuation.

_PARALLEL_LOCK = threading.Lock()

ENVS_PER_THREAD = 512
"""The automatic thread count gives each of numba's threads at least this many envs (:func:`threads_for`)."""

PARALLEL_MIN_ENVS = 2 * ENVS_PER_THREAD
"""Below this many envs the serial compiled loop is used: a thread's start-up and wake-up cost more than it saves,
and on a loaded machine far more (measured on a loaded 2-core machine at N = 1,024: 132 k env-steps/s with the
parallel loop, 546 k with one thread)."""


def threads_for(n: int) -> int:
    """numba threads for ``n`` envs: ``n // ENVS_PER_THREAD``, at least 1, at most numba's ``NUMBA_NUM_THREADS``."""
    return int(max(1, min(_max_threads(), n // ENVS_PER_THREAD)))


def _max_threads() -> int:
    return numba.config.NUMBA_NUM_THREADS if HAVE_NUMBA else 1

def compile_loops(make_loop, modules) -> tuple:
    """The serial and the parallel loop of ``make_loop(stamp, variant)`` compiled by numba (for :func:`run_loop`),
    cached on disk under a hash of the sources of ``modules``: compiling a parallel loop takes seconds, and an edit
    of any of those sources recompiles it instead of loading a stale one. (The scalar solver's closures themselves
    are not cacheable: numba keys them by their pickled closure, which differs in every process.)"""
    return (njit_cached(lambda stamp: make_loop(stamp, 0), modules),
            njit_cached(lambda stamp: make_loop(stamp, 1), modules, parallel=True))


def _make_loop(stamp: int, variant: int):
    # ``stamp`` and ``variant`` are closure variables, so they are part of the key of numba's on-disk cache:
    # an edit of the solver or the energy recompiles the loop instead of loading a stale one, and the
    # serial and parallel loops (same code, same name) get separate entries.
    def _loop(k, s, p0, p1, kobj, ko, prm, opts, active, out):
        # out: a Solve of (N,) arrays, written env by env. Its arrays are taken out of the record before the loop, one
        # assignment each: numba's parallel loop loses the writes made through a record's field, or through arrays
        # unpacked from a tuple (numba 0.68; test_parallel_and_serial_loops_agree checks it).
        if stamp < 0 or variant < 0:
            return
        o_kappa = out.kappa
        o_side_strain = out.side_strain
        o_energy = out.energy
        o_gradient_norm = out.gradient_norm
        o_min_eigenvalue = out.min_eigenvalue
        o_iterations = out.iterations
        o_substeps = out.substeps
        o_snapped = out.snapped
        o_status = out.status
        o_volume_change = out.volume_change
        o_evaluations = out.evaluations
        o_backtracks = out.backtracks
        for i in numba.prange(k.shape[0]):
            if active[i]:
                r = _follow_ev(k[i], s[i], p0[i], p1[i], prm, kobj[i], ko[i], opts)  # step_state, compiled
                o_kappa[i] = r.kappa
                o_side_strain[i] = r.side_strain
                o_energy[i] = r.energy
                o_gradient_norm[i] = r.gradient_norm
                o_min_eigenvalue[i] = r.min_eigenvalue
                o_iterations[i] = r.iterations
                o_substeps[i] = r.substeps
                o_snapped[i] = r.snapped
                o_status[i] = r.status
                o_volume_change[i] = r.volume_change
                o_evaluations[i] = r.evaluations
                o_backtracks[i] = r.backtracks

    return _loop


TBB_LIBRARY = "libtbb.so.12"
"""The TBB runtime numba's ``tbb`` threading layer links against (what the ``fast`` extra's ``tbb`` installs)."""


def preload_tbb(prefixes=None) -> str | None:
    """Make the TBB runtime loadable where pip put it: ``lib/`` of this environment (a venv, a conda env), which the
    dynamic loader does not search. Without it numba finds no TBB in a venv and falls back to its workqueue layer
    (about 1.3x slower per step, and serialised). Returns the path loaded (``RTLD_GLOBAL``, so numba's ``tbbpool``
    extension then links to it), ``"default"`` when the loader finds TBB by itself, or ``None`` (none found; not
    Linux).

    ``prefixes``: the folders to look in (default: ``sys.prefix``, ``sys.base_prefix`` and ``$CONDA_PREFIX``).
    """
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    if prefixes is None:
        try:
            ctypes.CDLL(TBB_LIBRARY, mode=ctypes.RTLD_GLOBAL)  # already on the loader's path: leave it to the loader
            return "default"
        except OSError:
            pass
        prefixes = (sys.prefix, sys.base_prefix, os.environ.get("CONDA_PREFIX", ""))
    for prefix in dict.fromkeys(p for p in prefixes if p):
        path = os.path.join(prefix, "lib", TBB_LIBRARY)
        if os.path.isfile(path):
            try:
                ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
                return path
            except OSError:  # a broken or foreign-architecture file: try the next
                continue
    return None


TBB_LOADED: str | None = None
"""What :func:`preload_tbb` found at import (numba installed, the threading layer left to this package)."""

_WARNED_LAYER = False


def _warn_if_workqueue() -> None:
    """Once per process: say so when the parallel loop runs on numba's workqueue instead of TBB, and what it costs."""
    global _WARNED_LAYER
    if _WARNED_LAYER:
        return
    _WARNED_LAYER = True
    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel region has run
        return
    if layer == "workqueue":
        import warnings

        warnings.warn("numba's TBB threading layer is not available here (pip install tbb, the 'fast' extra): the "
                      "parallel step runs on numba's workqueue layer, about 1.3x slower, and parallel calls are "
                      "serialised", RuntimeWarning, stacklevel=3)


if HAVE_NUMBA:
    import numba

    if "NUMBA_THREADING_LAYER" not in os.environ and numba.config.THREADING_LAYER == "default":
        # GNU OpenMP (numba's usual pick) kills any child forked after a parallel loop ran: Gymnasium's
        # AsyncVectorEnv and multiprocessing pools fork by default on Linux. "forksafe" picks tbb if installed,
        # else the built-in workqueue, which is not thread-safe: _PARALLEL_LOCK serialises the parallel calls.
        numba.config.THREADING_LAYER = "forksafe"
        TBB_LOADED = preload_tbb()  # a venv's lib/ is not on the loader's path: without this, no TBB there

    _loop_serial, _loop_parallel = compile_loops(_make_loop, (mechanics, contact, continuation, _solver, _jit, xp,
                                                              sys.modules[__name__]))


def check_threads(threads) -> None:
    """``ValueError`` naming ``threads`` unless it is ``None`` or an int in ``[1, NUMBA_NUM_THREADS]``."""
    if threads is None:
        return
    top = _max_threads()
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or not 1 <= threads <= top:
        raise ValueError(f"threads must be None or an integer in [1, {top}] (NUMBA_NUM_THREADS), got {threads!r}")


def solve_batch_numba(k, s, p0, p1, kobj, ko, prm, opts, active, parallel: bool | None = None,
                      threads: int | None = None) -> Equilibrium:
    """The compiled back-end on prepared float64 arrays (no validation; see :func:`solve_batch`).

    ``prm`` is :func:`pneunet_env.physics.solver.params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`.
    ``parallel``: split the envs over the cores (``None``: when there are at least
    :data:`PARALLEL_MIN_ENVS`; the threads are numba's, ``NUMBA_NUM_THREADS``).
    """
    if not HAVE_NUMBA:
        raise RuntimeError("the numba back-end needs numba")
    out = _allocate(k, s)
    run_loop(_loop_serial, _loop_parallel, (k, s, p0, p1, kobj, ko, prm, opts, active, out), k.shape[0], parallel,
             threads)
    return _result(out, p1, kobj, ko, prm.chamber_height)


def run_loop(serial, parallel_loop, args: tuple, n: int, parallel: bool | None, threads: int | None) -> None:
    """Run a compiled loop over ``n`` envs: ``parallel_loop`` on :func:`threads_for` ``(n)`` threads (or ``threads``)
    when ``parallel`` (``None``: from :data:`PARALLEL_MIN_ENVS` envs and 2 threads on), else ``serial``."""
    n_threads = threads_for(n) if threads is None else int(threads)
    if parallel is None:
        parallel = n >= PARALLEL_MIN_ENVS and n_threads > 1
    if not parallel:
        serial(*args)
        return
    with _PARALLEL_LOCK:  # one parallel loop at a time (the workqueue layer aborts on concurrent use)
        before = numba.get_num_threads()
        numba.set_num_threads(n_threads)
        try:
            parallel_loop(*args)
        finally:
            numba.set_num_threads(before)
    if not _WARNED_LAYER:
        _warn_if_workqueue()


# --------------------------------------------------------------------------------------------------
# Array back-ends: the masked solver (physics.masked), written once for numpy and torch.


def solve_batch_numpy(k, s, p0, p1, kobj, ko, prm, opts, active) -> Equilibrium:
    """The vectorised (numpy-only) back-end on prepared float64 arrays (no validation; see :func:`solve_batch`):
    :func:`pneunet_env.physics.masked.solve_masked` on numpy, dropping finished envs from the rounds.

    ``prm`` is :func:`pneunet_env.physics.solver.params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`.
    """
    with np.errstate(all="ignore"):
        out = masked.solve_masked(k, s, p0, p1, kobj, ko, prm, opts, active, NUMPY, compact=True)
    return _result(Solve(**out), p1, kobj, ko, prm.chamber_height)


COMPILED_CHECK_EVERY = 8
"""Rounds between the checks for live envs with ``torch.compile``'s round on a GPU (each check is a host sync)."""


def solve_batch_torch(k, s, p0, p1, kobj, ko, prm, opts, active, *, compile: bool = False,
                      max_rounds: int | None = None) -> Equilibrium:
    """The torch back-end on float64 tensors of one device (no validation; see :func:`solve_batch`): the masked
    solver on torch, an :class:`Equilibrium` of tensors on that device.

    On every device it checks for live envs after every round and drops the finished ones once at most half are
    live (a gather). ``compile`` (:func:`compiled_round`, the round through ``torch.compile``) keeps N fixed instead
    (a changing N would recompile it): every env runs through every round, checked every
    :data:`COMPILED_CHECK_EVERY` rounds on a GPU. ``max_rounds``: a fixed budget (unfinished envs are flagged
    ``STATUS_BUDGET``).

    On an H200 at N = 2^22 (random actions; two runs, each on its own H200 machine) compaction doubled the
    env-steps/s (4.5 M to 8.9 M): a step takes 8 to 128 rounds, the batch's slowest env sets the count, and after 8
    rounds 3 % of the envs are live. At N <= 2^20, in one run, the two were within 10 %: there a round's cost is its
    kernel launches, not its envs (docs/performance.md).
    """
    ops = torch_ops(k.device)
    compact = not compile
    out = masked.solve_masked(k, s, p0, p1, kobj, ko, prm, opts, active, ops, compact=compact,
                              check_every=1 if compact or k.device.type == "cpu" else COMPILED_CHECK_EVERY,
                              max_rounds=max_rounds, round_fn=compiled_round() if compile else None)
    return _result(Solve(**out), p1, kobj, ko, prm.chamber_height, ops)


_COMPILED: list = []


def compiled_round():
    """``torch.compile`` of the masked solver's round (compiled once per process, on first use)."""
    if not _COMPILED:
        import torch

        _COMPILED.append(torch.compile(masked._round, dynamic=True))
    return _COMPILED[0]
