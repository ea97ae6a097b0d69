"""``pneunet-grasp bench speed``: the environment's speed against CartPole, measured in one run.

What it measures (all in one process, one after the other, on whatever machine runs it):

* **Single env.** The median wall time of one ``env.step`` through ``gym.make("PneuNetGrasp-v1")`` and through
  ``gym.make("CartPole-v1")`` (default wrappers: order enforcing, passive checker, time limit), actions drawn
  up front from the action space, each step timed alone (``time.perf_counter``), resets outside the timing;
  the two are measured in alternating rounds so that drifts of the machine hit both; each env is also timed
  unwrapped (``env.unwrapped.step``). Target: ratio <= 0.8 (issue 23's; it was 2).
* **Single env with its resets.** A user's loop, steps and a reset at each episode's end, each timed alone: the
  env's time per env-step with its resets, under random actions and under the best blind ramp, against CartPole-v1's
  with its resets, and each env's median reset, unseeded and seeded (:mod:`pneunet_env.bench.episodes`). Target
  (issue 36): random <= 1.0x CartPole-v1, the reset under 50 us.
* **Vector env.** Env-steps per second (``N`` times steps over the wall time of the step loop, auto-resets
  included) of ``gym.make_vec("PneuNetGrasp-v1", num_envs=N)`` (``PneuNetGraspVectorEnv``)
  and of ``gym.make_vec("CartPole-v1", num_envs=N)`` (Gymnasium's ``CartPoleVectorEnv``) at N = 1, 64,
  1,024 and 16,384, actions drawn up front; the best of a few repeats. Targets at N = 16,384: >= 1,000,000, and
  (issue 23) at least 0.15x CartPoleVectorEnv with random actions, 0.33x with the best blind ramp.
* **Solves.** ``solve_equilibrium`` calls per second (the public API, warm-started along random pressure
  walks, as an env calls it), and for reference the compiled ``step_state`` from Python and ``solve_batch``
  per env at N = 16,384.
* **Memory at N = 16,384.** The state kept between steps (``PneuNetGraspVectorEnv.state_nbytes()``: the
  arrays of equilibria, objects, thresholds, task state, observation and random streams) per env (target:
  <= 1 KiB), and the peak of Python/numpy allocations (``tracemalloc``) while making the env, resetting it
  and stepping it 10 times, per env (this includes the info dicts and the solver's temporaries).
* **Accuracy.** Over every solve of the run (single and vector env steps): the worst gradient norm and the
  fraction of converged solves (target: all, ``|grad| <= 1e-10``), so that speed is never bought with
  wrong answers.

Outputs in ``--out`` (default ``bench_out/speed``): ``speed.json`` (every figure, the machine, versions),
``speed.png`` (the chart). ``--quick`` (CI: well under a minute) takes fewer steps and repeats; its figures
are noisier. No thresholds are asserted: the targets are printed next to the figures.
"""

from __future__ import annotations

import argparse
import math
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env import arguments as checks
from pneunet_env.bench import episodes
from pneunet_env.bench.machine import load_average, machine
from pneunet_env.files import atomic_write_json, save_figure
from pneunet_env.progress import add_progress_argument
from pneunet_env.progress import progress as progress_bar
from pneunet_env.yamlio import load_json_file

__all__ = ["add_arguments", "run", "run_benchmark", "format_table", "plot", "NUM_ENVS", "TARGETS"]

NUM_ENVS = (1, 64, 1024, 16384)
"""The vector env sizes measured."""

TARGETS = {
    "single_step_ratio_max": 0.8,
    "vector_steps_per_s_at_16384_min": 1_000_000.0,
    "vector_ratio_at_16384_min": {"random": 0.15, "ramp": 0.33},
    "state_bytes_per_env_max": 1024.0,
    "gradient_norm_max": 1e-10,
    "single_with_resets": episodes.TARGETS,
}
"""The targets printed next to the figures (never asserted): issue 4's, and issue 23's single-env ratio (0.8x
CartPole-v1's step, was 2x) and vector ratios to CartPoleVectorEnv at N = 16,384."""


class _Accuracy:
    """Accumulates the solves' convergence and gradient norms."""

    def __init__(self) -> None:
        self.solves = 0
        self.converged = 0
        self.worst_gradient = 0.0
        self.nan = 0

    def add(self, gradient_norm, converged) -> None:
        g = np.asarray(gradient_norm, dtype=float).ravel()
        c = np.asarray(converged, dtype=bool).ravel()
        self.solves += g.size
        self.converged += int(c.sum())
        self.nan += int(np.isnan(g).sum())
        if g.size:
            self.worst_gradient = max(self.worst_gradient, float(np.nanmax(g, initial=0.0)))

    def as_dict(self) -> dict[str, Any]:
        return {
            "solves": self.solves,
            "converged_fraction": self.converged / self.solves if self.solves else math.nan,
            "worst_gradient_norm": self.worst_gradient,
            "nan_gradient_norms": self.nan,
        }


# --------------------------------------------------------------------------------------------------------
# Single env
# --------------------------------------------------------------------------------------------------------


def _time_steps(env, actions) -> np.ndarray:
    """Time each ``env.step`` alone; reset (untimed) when an episode ends. Nothing else runs between the steps: work
    there (reading the state, numpy calls) evicts the step's code and data from the caches and slows the next step
    (by about 7 us a step when the accuracy was read there, up to 0.10), so the accuracy has its own pass."""
    times = np.empty(len(actions))
    clock = time.perf_counter
    step = env.step
    for i, a in enumerate(actions):
        t0 = clock()
        out = step(a)
        times[i] = clock() - t0
        if out[2] or out[3]:
            env.reset()
    return times


def _check_steps(env, actions, acc: _Accuracy) -> None:
    """The accuracy of the same steps as :func:`_time_steps` takes (untimed): each accepted state's diagnostics."""
    for a in actions:
        out = env.step(a)
        eq = env.unwrapped.state.eq  # (the lean info has no gradient norm)
        acc.add(eq.gradient_norm, eq.converged)
        if out[2] or out[3]:
            env.reset()


def bench_single(steps: int, rounds: int, seed: int = 0, acc: _Accuracy | None = None) -> dict[str, Any]:
    """Median ``env.step`` time of ``gym.make("PneuNetGrasp-v1")`` and ``gym.make("CartPole-v1")``, and of each
    env unwrapped (``env.unwrapped.step``: Gymnasium's default wrappers' share apart). Each round times the same
    actions from the same seed on both, and then (untimed) reads the accuracy of those steps into ``acc``."""
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers the environment)

    acc = _Accuracy() if acc is None else acc
    envs = {"PneuNetGrasp-v1": gym.make("PneuNetGrasp-v1"), "CartPole-v1": gym.make("CartPole-v1")}
    times: dict[str, list[np.ndarray]] = {k: [] for k in envs}
    bare: dict[str, list[np.ndarray]] = {k: [] for k in envs}
    for env in envs.values():  # warm up (the first numba call compiles; caches)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        _time_steps(env, [env.action_space.sample() for _ in range(200)])
    per_round = max(1, steps // rounds)
    for r in range(rounds):
        for name, env in envs.items():
            env.reset(seed=seed + r)
            actions = [env.action_space.sample() for _ in range(per_round)]  # drawn up front
            times[name].append(_time_steps(env, actions))
            env.reset(seed=seed + r)
            bare[name].append(_time_steps(env.unwrapped, actions))
            if name == "PneuNetGrasp-v1":
                env.reset(seed=seed + r)
                _check_steps(env, actions, acc)
    for env in envs.values():
        env.close()
    med = {k: float(np.median(np.concatenate(v))) for k, v in times.items()}
    return {
        "steps_per_env": per_round * rounds,
        "rounds": rounds,
        "median_step_s": med,
        "mean_step_s": {k: float(np.mean(np.concatenate(v))) for k, v in times.items()},
        "median_unwrapped_step_s": {k: float(np.median(np.concatenate(v))) for k, v in bare.items()},
        "ratio": med["PneuNetGrasp-v1"] / med["CartPole-v1"],
    }


# --------------------------------------------------------------------------------------------------------
# Vector env
# --------------------------------------------------------------------------------------------------------


RAMP_TARGET_KPA = 35.1
"""The ramp workload's target: the default task's best blind ramp (``agents/best_ramp.json``, found by
``pneunet-grasp search``; a test keeps the two equal). The library does not read ``agents``' files."""
RAMP_STEPS = 20
"""The ramp workload's steps from 0 to the target (best-ramp's)."""
POLICIES = ("random", "ramp")
"""The vector env's workloads: uniform random actions (what most benchmarks run: the finger rarely touches, episodes
end early), and the best blind ramp (what users run: a grasp, then the pressure held)."""


def ramp_policy(config=None, target_kpa: float = RAMP_TARGET_KPA, n_steps: int = RAMP_STEPS):
    """The best blind ramp as a function of a batch of observations ``(N, 1 or 2)`` -> float32 actions ``(N, 1)``:
    the same formula as ``agents.policies.scripted.LinearRamp`` (raise ``p/p_max`` by ``target / n_steps`` a step, then
    hold it), written here so that the benchmark needs nothing from ``agents``."""
    from pneunet_env.config import EnvConfig

    task = (EnvConfig() if config is None else config).task
    target = target_kpa / task.max_pressure_kpa
    increment = target / n_steps
    step_fraction = task.max_pressure_step_kpa / task.max_pressure_kpa

    def act(obs):
        p = np.asarray(obs, dtype=np.float64)[..., 0]
        change = np.where(p <= target, np.minimum(p + increment, target), target) - p
        change = np.where(np.abs(change) <= np.spacing(p.astype(np.float32)), 0.0, change)  # hold: exactly 0
        return np.clip(change / step_fraction, -1.0, 1.0)[..., None].astype(np.float32)

    return act


def _vector_run(env, actions, collect: Any = None, policy=None, obs=None) -> float:
    """Wall time of ``len(actions)`` steps (auto-resets included). With ``policy``, each step's action is
    ``policy(obs)`` (computed inside the timing, as a user's loop does), ``actions`` only sets the count. ``collect``:
    anything with ``append`` (a list, or a :class:`_Work`), given each step's info."""
    step = env.step
    t0 = time.perf_counter()
    if policy is not None:
        for _ in range(len(actions)):
            obs, _, _, _, info = step(policy(obs))
            if collect is not None:
                collect.append(info)
    elif collect is None:
        for a in actions:
            step(a)
    else:
        append = collect.append
        for a in actions:
            append(step(a)[4])
    return time.perf_counter() - t0


WORKLOAD_MIN_STEPS = 100
"""The untimed full-info pass that counts the work per env-step runs at least this many steps: one default episode
(``squeeze_steps + hold_steps``), so that the ramp's hold is counted too."""

_COUNT_KEYS = {"solver_iterations": "newton_iterations", "solver_substeps": "substeps",
               "solver_evaluations": "energy_evaluations", "solver_backtracks": "backtracks"}
"""Full-info keys counted per env-step (those the installed solver reports) -> their name in the JSON."""


class _Work:
    """Per env-step counts over a run's full infos, added one step at a time (``append``: what :func:`_vector_run`
    calls), so that no info is kept: solver work, contact share, unchanged-pressure share, resets. The step that ends
    an episode reports its solve in ``final_info``."""

    def __init__(self, acc: _Accuracy | None) -> None:
        self.acc = acc
        self.sums: dict[str, float] = {}
        self.n = self.touch = self.unchanged = self.resets = 0
        self.prev = None

    def append(self, info: dict[str, Any]) -> None:
        final = info.get("final_info")
        done = final["_pressure"] if final is not None else None

        def pick(key):
            v = np.asarray(info[key])
            return v if final is None or key not in final else np.where(done, final[key], v)

        if self.acc is not None:
            self.acc.add(pick("gradient_norm"), pick("solver_converged"))
        for key, name in _COUNT_KEYS.items():
            if key in info:
                self.sums[name] = self.sums.get(name, 0.0) + float(np.sum(pick(key)))
        pressure = pick("pressure")
        self.touch += int(np.sum(pick("in_contact")))
        if self.prev is not None:
            same = pressure == self.prev
            self.unchanged += int(np.sum(same if done is None else same & ~done))
        self.resets += 0 if done is None else int(np.sum(done))
        self.prev = np.asarray(info["pressure"])  # after an autoreset: the new episode's start
        self.n += pressure.size

    def result(self) -> dict[str, Any]:
        n = self.n
        out: dict[str, Any] = {name: v / n for name, v in self.sums.items()} if n else {}
        out.update(env_steps=n, contact_share=self.touch / n if n else math.nan,
                   unchanged_pressure_share=self.unchanged / n if n else math.nan,
                   episode_end_share=self.resets / n if n else math.nan)
        return out


def _workload(infos, acc: _Accuracy | None) -> dict[str, Any]:
    """Per env-step counts over a run's full infos (see :class:`_Work`)."""
    work = _Work(acc)
    for info in infos:
        work.append(info)
    return work.result()


CONTINUATION = "continuation"
"""The variant measured beside the default at the largest N, on numba: the env without the free actuator's table
(``free_table=False``: every step the continuation's), so that one run gives what the table buys."""
JUMP = "jump"
"""The other variant measured there: the solver's ``step_control="jump"`` (every sub-step within ``max_jump`` of its
start: the default until 0.12, ``"branch"`` since), so that one run gives what the default's longer sub-steps buy."""
VARIANTS = {CONTINUATION: {"free_table": False}, JUMP: {"step_control": "jump"}}
"""The variants at the largest N (numba), by name: their config overrides."""


def bench_vector(num_envs: tuple[int, ...], env_steps: int, min_steps: int, repeats: int, seed: int = 0,
                 backend: str = "auto", acc: _Accuracy | None = None, progress=None,
                 policies: tuple[str, ...] = POLICIES, compare: bool = True) -> list[dict[str, Any]]:
    """Env-steps per second of the batched env (per workload in ``policies``) and of CartPole's vector env (random
    actions) at each N, and each workload's per-env-step solver counts (an untimed pass at the full info level).

    With ``compare`` (and numba), at the largest N the same workloads also run in each of :data:`VARIANTS` (without
    the free actuator's table, :data:`CONTINUATION`; with the step control "jump", :data:`JUMP`), in the same
    rounds: ``steps_per_s["PneuNetGrasp-v1 <workload>, <variant>"]``, ``ratio_<variant>`` and
    ``workload_<variant>``."""
    import gymnasium as gym

    import pneunet_env  # noqa: F401
    from pneunet_env.physics._jit import HAVE_NUMBA

    for name in policies:
        if name not in POLICIES:
            raise ValueError(f"policies: unknown workload {name!r}; known: {', '.join(POLICIES)}")
    ramp = ramp_policy()
    rows = []
    for n in num_envs:
        steps = int(max(min_steps, min(4000, env_steps // n)))
        rng = np.random.default_rng(seed + n)
        pn = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend=backend)
        cp = gym.make_vec("CartPole-v1", num_envs=n)
        pn_actions = rng.uniform(-1.0, 1.0, (steps, n, 1)).astype(np.float32)
        cp_actions = rng.integers(0, 2, (steps, n))
        runs = [(f"PneuNetGrasp-v1 {p}", pn, pn_actions, ramp if p == "ramp" else None) for p in policies]
        variant = compare and n == max(num_envs) and getattr(pn.unwrapped, "fused", False) and HAVE_NUMBA
        variants = VARIANTS if variant else {}
        others = {v: gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend=backend, **kw) for v, kw in variants.items()}
        for v, env_v in others.items():
            runs += [(f"PneuNetGrasp-v1 {p}, {v}", env_v, pn_actions, ramp if p == "ramp" else None)
                     for p in policies]
        runs.append(("CartPole-v1", cp, cp_actions, None))
        rates: dict[str, list[float]] = {name: [] for name, *_ in runs}
        for r in range(repeats):
            for name, env, acts, policy in runs:
                obs, _ = env.reset(seed=seed + r)
                obs = env.step(acts[0] if policy is None else policy(obs))[0]  # warm-up (numba starts its threads)
                dt = _vector_run(env, acts, None, policy, obs)
                rates[name].append(n * steps / dt)
        workloads: dict[str, Any] = {}
        workloads_v: dict[str, dict[str, Any]] = {v: {} for v in variants}
        if acc is not None:  # the same steps again, untimed, with the full info (solver diagnostics and counts),
            # over at least one whole episode (a short timed run sees only the ramp's start)
            w_actions = pn_actions if steps >= WORKLOAD_MIN_STEPS else np.concatenate(
                [pn_actions, rng.uniform(-1.0, 1.0, (WORKLOAD_MIN_STEPS - steps, n, 1)).astype(np.float32)])
            for p in policies:
                for v, kw in {None: {}, **variants}.items():
                    full = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend=backend, info_level="full", **kw)
                    obs, _ = full.reset(seed=seed)
                    work = _Work(acc)
                    _vector_run(full, w_actions, work, ramp if p == "ramp" else None, obs)
                    full.close()
                    (workloads if v is None else workloads_v[v])[p] = work.result()
        state_bytes = pn.unwrapped.state_nbytes()
        pn.close()
        cp.close()
        for env_v in others.values():
            env_v.close()
        best = {k: max(v) for k, v in rates.items()}
        cart = best["CartPole-v1"]
        row = {
            "num_envs": n,
            "steps": steps,
            "repeats": repeats,
            "steps_per_s": best,
            "ratio": {p: best[f"PneuNetGrasp-v1 {p}"] / cart for p in policies},
            "time_per_step_s": {k: n / v for k, v in best.items()},
            "state_bytes_per_env": state_bytes / n,
            "workload": workloads,
        }
        for v in variants:
            row[f"ratio_{v}"] = {p: best[f"PneuNetGrasp-v1 {p}, {v}"] / cart for p in policies}
            row[f"workload_{v}"] = workloads_v[v]
        rows.append(row)
        if progress is not None:
            progress.update(1)
    return rows


# --------------------------------------------------------------------------------------------------------
# Solves, memory
# --------------------------------------------------------------------------------------------------------


def bench_solves(calls: int, batch_n: int, seed: int = 0, backend: str = "auto",
                 acc: _Accuracy | None = None) -> dict[str, Any]:
    """``solve_equilibrium`` calls/s (warm-started walks), ``step_state`` from Python, ``solve_batch`` per env."""
    from pneunet_env.physics.batched import solve_batch
    from pneunet_env.physics.solver import DEFAULT_OPTIONS, params_tuple, solve_equilibrium, step_state

    walks = 20
    per_walk = max(1, calls // walks)
    rng = np.random.default_rng(seed)
    kobjs = np.where(rng.random(walks) < 0.15, 0.0, 10.0 ** rng.uniform(-5.0, -1.0, walks))
    paths = np.clip(np.cumsum(rng.uniform(-0.06, 0.06, (walks, per_walk)), axis=1) + 0.3, 0.0, 1.2)
    solve_equilibrium(0.1, 1e-4, 0.02)  # compile / warm up
    t_api = 0.0
    gns, conv = [], []
    for w in range(walks):
        k = float(kobjs[w])
        eq = solve_equilibrium(0.0, k, 0.02)
        ps = paths[w].tolist()
        t0 = time.perf_counter()
        for p in ps:
            eq = solve_equilibrium(p, k, 0.02, initial=eq)
        t_api += time.perf_counter() - t0
        gns.append(eq.gradient_norm)
        conv.append(eq.converged)
    # the compiled kernel alone, called from Python on the same walks
    prm = params_tuple(None)
    opts = DEFAULT_OPTIONS.as_tuple()
    t_kernel = 0.0
    for w in range(walks):
        k = float(kobjs[w])
        s_k, s_s, p0 = 0.0, 0.0, 0.0
        ps = paths[w].tolist()
        t0 = time.perf_counter()
        for p in ps:
            r = step_state(s_k, s_s, p0, p, prm, k, 0.02, opts)
            s_k, s_s, p0 = r[0], r[1], p
        t_kernel += time.perf_counter() - t0
        gns.append(r[3])
        conv.append(r[8] <= 1)
    # the batched solver: N envs, each one env-like step from an equilibrium
    brng = np.random.default_rng(seed + 1)
    kb = np.where(brng.random(batch_n) < 0.15, 0.0, 10.0 ** brng.uniform(-5.0, -1.0, batch_n))
    ko = np.full(batch_n, 0.02)
    p0 = brng.uniform(0.0, 1.2, batch_n)
    z = np.zeros(batch_n)
    start = solve_batch(z, z, z, p0, kb, ko, backend=backend)
    p1 = np.clip(p0 + brng.uniform(-0.06, 0.06, batch_n), 0.0, 1.2)
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        res = solve_batch(start.curvature, start.side_strain, p0, p1, kb, ko, backend=backend, validate=False)
        times.append(time.perf_counter() - t0)
    if acc is not None:
        acc.add(np.array(gns), np.array(conv))
        acc.add(res.gradient_norm, res.converged)
    n_calls = walks * per_walk
    return {
        "solve_equilibrium_calls_per_s": n_calls / t_api,
        "step_state_calls_per_s": n_calls / t_kernel,
        "solve_batch_num_envs": batch_n,
        "solve_batch_solves_per_s": batch_n / min(times),
        "calls": n_calls,
    }


def bench_memory(num_envs: int, steps: int, seed: int = 0, backend: str = "auto") -> dict[str, Any]:
    """State bytes per env, and the tracemalloc peak per env over make + reset + ``steps`` steps."""
    import gymnasium as gym

    import pneunet_env  # noqa: F401

    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, (steps, num_envs, 1)).astype(np.float32)
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        env = gym.make_vec("PneuNetGrasp-v1", num_envs=num_envs, backend=backend)
        env.reset(seed=seed)
        for a in actions:
            env.step(a)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    state = env.unwrapped.state_nbytes()
    env.close()
    return {
        "num_envs": num_envs,
        "state_bytes_per_env": state / num_envs,
        "peak_bytes_per_env": (peak - base) / num_envs,
        "peak_method": f"tracemalloc peak over gym.make_vec + reset + {steps} steps, minus the baseline",
        "state_method": "PneuNetGraspVectorEnv.state_nbytes(): arrays kept between steps",
    }


# --------------------------------------------------------------------------------------------------------
# The whole benchmark
# --------------------------------------------------------------------------------------------------------


def run_benchmark(quick: bool = False, progress: bool | None = None, backend: str = "auto", seed: int = 0,
                  num_envs: tuple[int, ...] = NUM_ENVS) -> dict[str, Any]:
    """Run every part; return the results (what ``speed.json`` holds).

    ``progress``: a bar on stderr; ``None`` (default): when stderr is a terminal.
    """
    from pneunet_env.physics._jit import HAVE_NUMBA

    t_start = time.perf_counter()
    load_start = load_average()
    acc = _Accuracy()
    bar = progress_bar(total=4 + len(num_envs), desc="bench speed", unit="part", enabled=progress)
    bar.set_description_str("single env vs CartPole")
    single = bench_single(steps=4000 if quick else 40000, rounds=4 if quick else 10, seed=seed, acc=acc)
    bar.update(1)
    bar.set_description_str("single env with its resets vs CartPole")
    with_resets = episodes.bench_single_with_resets(steps=3000 if quick else 30000, rounds=3 if quick else 10,
                                                    resets=300 if quick else 3000, ramp=ramp_policy(), seed=seed)
    bar.update(1)
    bar.set_description_str("vector env vs CartPoleVectorEnv")
    vector = bench_vector(num_envs, env_steps=150_000 if quick else 3_000_000, min_steps=5 if quick else 50,
                          repeats=1 if quick else 3, seed=seed, backend=backend, acc=acc, progress=bar)
    bar.set_description_str("solves")
    solves = bench_solves(calls=2000 if quick else 40000, batch_n=max(num_envs), seed=seed, backend=backend, acc=acc)
    bar.update(1)
    bar.set_description_str("memory")
    memory = bench_memory(max(num_envs), steps=3 if quick else 10, seed=seed, backend=backend)
    bar.update(1)
    bar.close()
    return {
        "quick": quick,
        "backend": backend if backend != "auto" else ("numba" if HAVE_NUMBA else "numpy"),
        "machine": machine(),
        "single_env": single,
        "single_env_with_resets": with_resets,
        "vector_env": vector,
        "solves": solves,
        "memory": memory,
        "accuracy": acc.as_dict(),
        "targets": TARGETS,
        "load_average": {"start": load_start, "end": load_average()},
        "wall_s": time.perf_counter() - t_start,
    }


def _short(x: float) -> str:
    """3.2M, 145k, 7.4k."""
    for div, unit in ((1e6, "M"), (1e3, "k")):
        if x >= div:
            return f"{x / div:.3g}{unit}"
    return f"{x:.3g}"


def _fmt_rate(x: float) -> str:
    return f"{x:,.0f}"


def record_env_id(res: dict[str, Any]) -> str:
    """The env id a speed record measured (``PneuNetGrasp-v1`` since 0.14; an older record's own, so that
    ``--plot-only`` redraws any record): the single env's timed env that is not CartPole."""
    return next((k for k in res["single_env"]["median_step_s"] if k != "CartPole-v1"), "PneuNetGrasp-v1")


def format_table(res: dict[str, Any]) -> str:
    """The printed table."""
    env_id = record_env_id(res)
    s = res["single_env"]
    m = res["machine"]
    lines = [
        f"{env_id} speed ({'quick' if res['quick'] else 'full'} run; backend {res['backend']}; "
        f"{m['cpus']} CPUs; numpy {m['numpy']}, gymnasium {m['gymnasium']}, numba {m['numba']}; threading layer "
        f"{m.get('threading_layer') or 'none run'})",
        "",
        "single env: median env.step (gym.make, default wrappers; unwrapped: env.unwrapped.step)",
        *(f"  {k:<22}{s['median_step_s'][k] * 1e6:>10.2f} us   unwrapped "
          f"{s.get('median_unwrapped_step_s', {}).get(k, math.nan) * 1e6:.2f} us" for k in s["median_step_s"]),
        f"  {'ratio':<22}{s['ratio']:>10.2f} x    (target <= {TARGETS['single_step_ratio_max']:g})",
        *(["", *episodes.format_lines(res["single_env_with_resets"])] if "single_env_with_resets" in res else []),
        "",
        "vector env: env-steps/s (gym.make_vec); workloads: random actions, and the best blind ramp "
        f"({RAMP_TARGET_KPA:g} kPa over {RAMP_STEPS} steps, then held); CartPole: random actions",
        f"  {'N':>6}  {'random':>12}  {'ramp':>12}  {'CartPoleVectorEnv':>18}  {'ratio random':>12}  "
        f"{'ratio ramp':>10}",
    ]
    for row in res["vector_env"]:
        r, q = row["steps_per_s"], row["ratio"]
        cells = [f"{_fmt_rate(r[k]):>12}" if k in r else f"{'-':>12}"
                 for k in (f"{env_id} random", f"{env_id} ramp")]
        ratios = [f"{q[p]:>12.3f}" if p in q else f"{'-':>12}" for p in ("random", "ramp")]
        lines.append(f"  {row['num_envs']:>6}  {cells[0]}  {cells[1]}  {_fmt_rate(r['CartPole-v1']):>18}  "
                     f"{ratios[0]}  {ratios[1][2:]}")
    last = res["vector_env"][-1]
    headings = {  # each variant's lines: the heading, the variant's word, and "default / variant" or its inverse
        CONTINUATION: (f"the free actuator's table at N = {last['num_envs']:,}, same rounds: with it (the default) and "
                       f"without ({CONTINUATION}: free_table=False)", "without", "x faster", True),
        JUMP: (f"the solver's step control at N = {last['num_envs']:,}, same rounds: branch (the default: longer "
               f"sub-steps on one branch) and {JUMP} (step_control='{JUMP}', the default until 0.12)", JUMP,
               "x faster", True),
    }
    for v, (heading, word, unit, inverse) in headings.items():
        if f"ratio_{v}" not in last:
            continue
        r, q, qv = last["steps_per_s"], last["ratio"], last[f"ratio_{v}"]
        lines += ["", heading]
        for p in qv:
            default, variant = r[f"{env_id} {p}"], r[f"{env_id} {p}, {v}"]
            factor = default / variant if inverse else variant / default
            lines.append(f"  {p:<8}{_fmt_rate(default):>12} ({q[p]:.3f}x)  {word:<7} {_fmt_rate(variant):>12} "
                         f"({qv[p]:.3f}x)   {factor:.2f}{unit}")
    work = last.get("workload") or {}
    if work:
        work_c = {f"{p}, no table": w for p, w in (last.get("workload_continuation") or {}).items()}
        work_b = {f"{p}, {JUMP}": w for p, w in (last.get(f"workload_{JUMP}") or {}).items()}
        columns = {**work, **work_c, **work_b}
        keys = [k for k in ("energy_evaluations", "newton_iterations", "substeps", "backtracks", "contact_share",
                            "unchanged_pressure_share", "episode_end_share")
                if any(k in w for w in columns.values())]
        lines += ["", f"per env-step at N = {last['num_envs']:,} (untimed pass, full info)",
                  f"  {'':<26}" + "".join(f"{p:>17}" for p in columns)]
        for k in keys:
            lines.append(f"  {k:<26}" + "".join(f"{w.get(k, math.nan):>17.3f}" for w in columns.values()))
    lines.append(f"  (targets at N = 16,384: >= {_fmt_rate(TARGETS['vector_steps_per_s_at_16384_min'])} env-steps/s; "
                 + ", ".join(f"ratio {p} >= {v:g}" for p, v in TARGETS["vector_ratio_at_16384_min"].items()) + ")")
    sv = res["solves"]
    lines += [
        "",
        "solves",
        f"  solve_equilibrium (public API)   {_fmt_rate(sv['solve_equilibrium_calls_per_s']):>12} calls/s "
        f"({1e6 / sv['solve_equilibrium_calls_per_s']:.2f} us/call)",
        f"  step_state (the kernel, from Python){_fmt_rate(sv['step_state_calls_per_s']):>9} calls/s "
        f"({1e6 / sv['step_state_calls_per_s']:.2f} us/call)",
        f"  solve_batch N={sv['solve_batch_num_envs']:<6}            {_fmt_rate(sv['solve_batch_solves_per_s']):>12} "
        f"solves/s ({1e6 / sv['solve_batch_solves_per_s']:.3f} us/env)",
    ]
    mem = res["memory"]
    lines += [
        "",
        f"memory at N = {mem['num_envs']:,}",
        f"  state kept between steps   {mem['state_bytes_per_env']:>8.0f} B/env   "
        f"(target <= {TARGETS['state_bytes_per_env_max']:.0f} B)",
        f"  peak allocations (tracemalloc, make + reset + steps) {mem['peak_bytes_per_env'] / 1024:>6.2f} KiB/env",
    ]
    a = res["accuracy"]
    load = res.get("load_average") or {}
    if load.get("start") is not None:
        lines += ["", f"load average (1 min) at start {load['start'][0]:.2f}, at end {load['end'][0]:.2f} "
                      f"(other processes on the {m['cpus']} CPUs slow every figure down)"]
    lines += [
        "",
        f"accuracy over {a['solves']:,} solves: converged {100 * a['converged_fraction']:.4f} %, worst |grad U| "
        f"{a['worst_gradient_norm']:.2e} (target: all, <= {TARGETS['gradient_norm_max']:g}), "
        f"NaN {a['nan_gradient_norms']}",
    ]
    return "\n".join(lines)


def plot(res: dict[str, Any], path: Path) -> None:
    """The chart: single-env step times, and vector env-steps/s against N (log-log), both against CartPole."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pn_c, cp_c = "#c0392b", "#2c6fbb"
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4), gridspec_kw={"width_ratios": [1, 1.6]})
    env_id = record_env_id(res)
    s = res["single_env"]["median_step_s"]
    names = [env_id, "CartPole-v1"]
    vals = [s[n] * 1e6 for n in names]
    bars = ax1.bar(names, vals, color=[pn_c, cp_c], width=0.6)
    for b, v in zip(bars, vals, strict=True):
        ax1.text(b.get_x() + b.get_width() / 2, v, f"{v:.2f} µs", ha="center", va="bottom", fontsize=10)
    limit = TARGETS["single_step_ratio_max"] * s["CartPole-v1"] * 1e6
    ax1.axhline(limit, color="0.3", ls="--", lw=1)
    ax1.text(1.32, limit, f"target:\n{TARGETS['single_step_ratio_max']:g}× CartPole", va="center", fontsize=8,
             color="0.3")
    ax1.set_ylim(0, max(max(vals), limit) * 1.25)
    ax1.set_ylabel("median env.step time (µs)")
    ax1.set_title(f"single env (gym.make): ratio {res['single_env']['ratio']:.2f}×", fontsize=11)
    ax1.set_xlim(-0.6, 1.9)

    rows = res["vector_env"]
    n = np.array([r["num_envs"] for r in rows])
    cp = np.array([r["steps_per_s"]["CartPole-v1"] for r in rows])
    workloads = [p for p in POLICIES if all(f"{env_id} {p}" in r["steps_per_s"] for r in rows)]
    pn = np.array([[r["steps_per_s"][f"{env_id} {p}"] for r in rows] for p in workloads]).reshape(-1, len(n))
    for j, p in enumerate(workloads):
        ax2.loglog(n, pn[j], "o-" if p == "random" else "D--", color=pn_c, label=f"PneuNetGraspVectorEnv, {p}")
    ax2.loglog(n, cp, "s-", color=cp_c, label="CartPoleVectorEnv")
    if workloads:  # the last workload's figures (the ramp: what users run)
        y_last, p_last = pn[-1], workloads[-1]
        for x, y, c, r in zip(n, y_last, cp, rows, strict=True):
            text = f"{_short(y)}/s\n{r['ratio'][p_last]:.2f}× CP"
            if x == n[-1] and len(n) > 1:  # left of the last point (the target's mark is right of it)
                ax2.annotate(text, (x, y), textcoords="offset points", xytext=(-10, 0), ha="right", va="center",
                             fontsize=8, color=pn_c)
                continue
            above = c / y > 8.0  # room between the two curves on the log scale; else below the point
            ax2.annotate(text, (x, y), textcoords="offset points", xytext=(0, 9 if above else -9), ha="center",
                         va="bottom" if above else "top", fontsize=8, color=pn_c)
    target = TARGETS["vector_steps_per_s_at_16384_min"]
    ax2.plot([n[-1]], [target], marker="_", markersize=22, mew=2, color="0.25", ls="none")
    ax2.annotate("target\n10⁶/s", (n[-1], target), textcoords="offset points", xytext=(14, 0), ha="left",
                 va="center", fontsize=8, color="0.25")
    ax2.set_xlabel("number of envs N")
    ax2.set_ylabel("env-steps per second")
    ax2.set_xticks(n)
    ax2.set_xticklabels([f"{v:,}" for v in n])
    ax2.set_xlim(n[0] / 2.5, n[-1] * 8)
    ax2.set_ylim(min(pn.min(initial=cp.min()), cp.min()) / 8, max(pn.max(initial=cp.max()), cp.max()) * 4)
    ax2.set_title("vector env (gym.make_vec)", fontsize=11)
    ax2.legend(loc="upper left", fontsize=9, title="CP: CartPole", title_fontsize=8)
    ax2.grid(True, which="major", alpha=0.3)
    a = res["accuracy"]
    m = res["machine"]
    fig.suptitle(
        f"{env_id} speed, {m['cpus']} CPUs, backend {res['backend']}: every one of {a['solves']:,} solves "
        f"{'converged' if a['converged_fraction'] == 1 else 'NOT all converged'}, worst |∇U| = "
        f"{a['worst_gradient_norm']:.1e}", fontsize=10,
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="fewer steps and repeats (CI: well under a minute)")
    parser.add_argument("--out", type=checks.output_dir, default="bench_out/speed",
                        help="output folder (speed.json, speed.png), checked before the benchmark")
    parser.add_argument("--backend", choices=("auto", "numba", "numpy", "torch"), nargs="+", default=["auto"],
                        help="the vector env's batched solver (default: numba if installed). Several, or torch: "
                             "the backend sweep instead (env-steps/s against N per backend and device, against "
                             "CartPoleVectorEnv and numba; backends.json, backends.png)")
    parser.add_argument("--device", nargs="+", default=None,
                        help="torch's devices for the backend sweep (default: cpu), e.g. --device cpu cuda")
    parser.add_argument("--num-envs", type=checks.integer(1, 2**26), nargs="+", default=None,
                        help="the sweep's N (default: 256 4096 16384; 16384 262144 1048576 4194304 on a GPU)")
    parser.add_argument("--compile", action="store_true",
                        help="torch: also measure it with the solver's round through torch.compile")
    add_progress_argument(parser)
    parser.add_argument("--plot-only", action="store_true",
                        help="measure nothing: redraw speed.png and reprint the table from OUT/speed.json")


def run(args: argparse.Namespace) -> int:
    from pneunet_env.physics._jit import HAVE_NUMBA

    backends = list(dict.fromkeys(args.backend))
    if "numba" in backends and not HAVE_NUMBA:
        raise SystemExit("--backend numba needs numba (pip install pneunet-env[fast])")
    if len(backends) > 1 or backends == ["torch"] or args.device or args.num_envs or args.compile:
        return _run_sweep(args, backends)
    args.backend = backends[0]
    out: Path = args.out
    if args.plot_only:
        path = out / "speed.json"
        if not path.is_file():
            raise SystemExit(f"--plot-only needs {path} (from an earlier run with --out {out})")
        try:
            res = load_json_file(path, "speed record")
        except ValueError as exc:
            raise SystemExit(f"--plot-only: {path} is not a readable speed record ({exc})") from None
        plot(res, out / "speed.png")
        print(format_table(res))
        print(f"\nredrew {out}/speed.png from {path}")
        return 0
    res = run_benchmark(quick=args.quick, progress=args.progress, backend=args.backend)
    atomic_write_json(out / "speed.json", res)
    plot(res, out / "speed.png")
    print(format_table(res))
    print(f"\nwrote {out}/speed.json, speed.png ({res['wall_s']:.1f} s)")
    return 0


def _run_sweep(args: argparse.Namespace, backends: list[str]) -> int:
    from pneunet_env.bench import backends as sweep
    from pneunet_env.physics._jit import HAVE_NUMBA

    if "auto" in backends:
        backends = [("numba" if HAVE_NUMBA else "numpy") if b == "auto" else b for b in backends]
        backends = list(dict.fromkeys(backends))
    if "torch" in backends:
        try:
            import torch
        except ImportError:
            raise SystemExit("--backend torch needs torch (pip install torch)") from None
    devices = args.device or ["cpu"]
    if "torch" in backends:
        for d in devices:
            try:
                torch.zeros(1, device=d)
            except (RuntimeError, AssertionError) as exc:
                raise SystemExit(f"--device {d}: not available ({exc})") from None
    gpu = any(str(d).startswith("cuda") for d in devices) and "torch" in backends
    num_envs = args.num_envs or ([16384, 262144, 1048576, 4194304] if gpu else [256, 4096, 16384])
    if any(n < 1 for n in num_envs):
        raise SystemExit(f"--num-envs must be positive integers, got {num_envs}")
    res = sweep.run_sweep(backends, devices, num_envs, env_steps=100_000 if args.quick else 2_000_000,
                          min_steps=3 if args.quick else 20, max_steps=20 if args.quick else 200,
                          compile=args.compile)
    sweep.write(res, args.out)
    print(sweep.format_sweep(res))
    print(f"\nwrote {args.out}/backends.json, backends.png ({res['wall_s']:.1f} s)")
    return 0
