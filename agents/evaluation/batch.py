"""Batched evaluation: many objects x many candidate schedules as one vector env run, not an episode loop.

Every pair (candidate, object) is one sub-env of :class:`pneunet_env.envs.grasp_vector.PneuNetGraspVectorEnv`,
seeded with the object's episode seed, so sub-env ``c * M + m`` meets exactly the object that
``gym.make("PneuNetGrasp-v1").reset(seed=seeds[m])`` draws (the vector env's streams are numpy's PCG64, bit for
bit). The batch is stepped for one episode length; each sub-env's *first* episode is recorded (its outcome, its
return) and what autoreset starts after it is ignored. The scores are therefore the single env's, object for
object (``tests/agents/test_batch.py`` checks them against :func:`agents.evaluation.episodes.run_episode`).

* :func:`run_batch`: any stateless batch policy ``act(obs) -> actions`` on ``copies x M`` sub-envs.
* :func:`ramp_grid`: linear ramps to every target of a grid, each on every object: a
  :class:`RampGrid` of ``(targets, objects)`` outcomes, from which :mod:`agents.search` picks the best blind
  ramp and :mod:`agents.design` scores an actuator.

The ramp's duration does not change an outcome while it ends inside the squeeze phase: the model is
quasi-static, so a monotone loading path reaches the same equilibrium whatever its sub-steps
(:func:`duration_invariance` measures it; ``pneunet-grasp search`` therefore searches one duration).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig, load_config

__all__ = ["BatchOutcome", "RampGrid", "run_batch", "run_policy", "policy_episodes", "batchable", "draw_objects",
           "ramp_actions", "ramp_grid", "duration_invariance", "episode_seeds", "HELD_OUT_SEED"]

HELD_OUT_SEED = 1_000_000_000
"""Offset of held-out objects' seeds (``agents.evaluation.batch.HELD_OUT_SEED``): disjoint from the search's."""


def episode_seeds(n: int, seed: int = 0, held_out: bool = False) -> np.ndarray:
    """The episode seeds of ``n`` objects: ``seed * 1_000_003 + i`` (search objects), or the held-out ones
    ``HELD_OUT_SEED + seed * 1_000_003 + i`` (the demo's)."""
    if int(n) != n or n < 1:
        raise ValueError(f"the number of objects must be an integer >= 1, got {n!r}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    base = (HELD_OUT_SEED if held_out else 0) + int(seed) * 1_000_003
    return base + np.arange(int(n), dtype=np.int64)


@dataclass(frozen=True)
class BatchOutcome:
    """Each sub-env's first episode, shaped ``(copies, objects)``.

    Attributes:
        success, damaged, dropped: the episode's end flags (bool).
        returns: the episode's summed reward.
        steps: its length.
        solver_failed: whether any of its steps was flagged unconverged.
        peak_traction_kpa: the largest contact traction of its steps (kPa).
        stiffness, curvature: each object's ``k~`` and ``w kappa_obj`` (``(objects,)``, for this actuator).
        class_id: each object's catalogue class code (``-1``: drawn from ranges); names in ``class_names``.
        shear_modulus_kpa, radius_mm: the object's modulus and outer radius (``1 / kappa_obj``).
    """

    success: np.ndarray
    damaged: np.ndarray
    dropped: np.ndarray
    returns: np.ndarray
    steps: np.ndarray
    solver_failed: np.ndarray
    peak_traction_kpa: np.ndarray
    stiffness: np.ndarray
    curvature: np.ndarray
    class_id: np.ndarray
    class_names: tuple[str, ...]
    shear_modulus_kpa: np.ndarray
    radius_mm: np.ndarray

    @property
    def classes(self) -> list[str]:
        """Each object's class name (``"ranges"`` for one drawn from ranges)."""
        return [self.class_names[c] if c >= 0 else "ranges" for c in self.class_id]

    def episodes(self, copy: int = 0) -> list[dict[str, Any]]:
        """Copy ``copy``'s episodes as :func:`agents.evaluation.episodes.run_episode` reports them, one dict per
        object."""
        names = self.classes
        return [{"stiffness": float(self.stiffness[m]), "shear_modulus_kpa": float(self.shear_modulus_kpa[m]),
                 "curvature": float(self.curvature[m]), "object_class": names[m],
                 "success": bool(self.success[copy, m]), "damaged": bool(self.damaged[copy, m]),
                 "dropped": bool(self.dropped[copy, m]), "return": float(self.returns[copy, m]),
                 "steps": int(self.steps[copy, m]), "peak_traction_kpa": float(self.peak_traction_kpa[copy, m]),
                 "solver_failed": bool(self.solver_failed[copy, m])} for m in range(self.stiffness.size)]


_INFO_KEYS = ("damaged", "dropped", "solver_failed", "contact_force_kpa",  # each step's
              # the reset's (the oracle's plan): the object's constants
              "object_stiffness", "object_curvature", "failure_traction_kpa", "crush_indentation_mm",
              "grip_traction_kpa")


def _vector_env(config: EnvConfig, n: int, backend: str, parallel: bool | None):
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

    return PneuNetGraspVectorEnv(n, config=config, backend=backend, parallel=parallel,
                                 info_keys=_INFO_KEYS)


def run_batch(config: EnvConfig, seeds: Sequence[int], act: Callable[[np.ndarray, Any], np.ndarray], copies: int = 1,
              backend: str = "auto", parallel: bool | None = None,
              begin: Callable[[dict[str, Any]], None] | None = None,
              options: dict[str, Any] | None = None) -> BatchOutcome:
    """Run ``copies`` copies of every object of ``seeds`` together; sub-env ``c * M + m`` is copy ``c`` of object ``m``.

    Args:
        config: the env's config (actuator, objects, task).
        seeds: the objects' episode seeds (``M`` of them).
        act: ``act(obs, env) -> actions``: obs ``(copies * M, obs_dim)`` float32, actions ``(copies * M, 1)``;
            it is called once per step, and may read ``env`` (e.g. its reset objects) but is given no other
            memory: a stateless policy of the observation, as the blind schedules are.
        copies: how many times each object is run (``act`` tells the copies apart by index).
        backend, parallel: the vector env's (``"auto"``: numba's fused step where installed).
        begin: called once with the reset's info (the vector info: each object's constants as ``(N,)`` arrays),
            before the first step: what a policy that knows the object (the oracle) reads.
        options: the reset's object pins, as the single env's (``{"object_stiffness": k}``); a value may be an
            array with one entry per object (``(M,)``), repeated for every copy.
    """
    seeds = np.asarray(seeds, dtype=np.int64)
    if seeds.ndim != 1 or seeds.size < 1:
        raise ValueError(f"seeds must be a non-empty 1-d sequence of integers, got shape {seeds.shape}")
    if int(copies) != copies or copies < 1:
        raise ValueError(f"copies must be an integer >= 1, got {copies!r}")
    m, c = seeds.size, int(copies)
    n = m * c
    env = _vector_env(config, n, backend, parallel)
    try:
        pins = None if options is None else {
            k: (np.tile(np.asarray(v), c) if np.ndim(v) == 1 else v) for k, v in options.items()}
        obs, reset_info = env.reset(seed=np.tile(seeds, c).tolist(), options=pins)
        if begin is not None:
            begin(reset_info)
        obj = env.objects
        horizon = config.task.squeeze_steps + config.task.hold_steps
        done = np.zeros(n, bool)
        success = np.zeros(n, bool)
        damaged = np.zeros(n, bool)
        dropped = np.zeros(n, bool)
        failed = np.zeros(n, bool)
        returns = np.zeros(n)
        peak = np.zeros(n)
        steps = np.zeros(n, np.int64)
        for _ in range(horizon):
            obs, reward, terminated, truncated, info = env.step(act(obs, env))
            live = ~done
            returns[live] += reward[live]
            steps[live] += 1
            ended = live & (terminated | truncated)
            force, fail = info["contact_force_kpa"], info["solver_failed"]
            if ended.any():  # an ended sub-env's step info is in final_info (info holds its reset's)
                fi = info["final_info"]
                force = np.where(ended, fi["contact_force_kpa"], force)
                fail = np.where(ended, fi["solver_failed"], fail)
                success[ended] = fi["is_success"][ended]
                damaged[ended] = fi["damaged"][ended]
                dropped[ended] = fi["dropped"][ended]
                done |= ended
            failed |= live & fail
            peak = np.where(live, np.maximum(peak, force), peak)
            if done.all():
                break
        if not done.all():  # pragma: no cover - the task always ends by squeeze + hold steps
            raise RuntimeError(f"{int((~done).sum())} episodes did not end within {horizon} steps")
        names = env.object_class_names
    finally:
        env.close()
    shape = (c, m)
    return BatchOutcome(
        success=success.reshape(shape), damaged=damaged.reshape(shape), dropped=dropped.reshape(shape),
        returns=returns.reshape(shape), steps=steps.reshape(shape), solver_failed=failed.reshape(shape),
        peak_traction_kpa=peak.reshape(shape),
        stiffness=np.asarray(obj.stiffness[:m], float), curvature=np.asarray(obj.curvature[:m], float),
        class_id=np.asarray(obj.class_id[:m], np.int64), class_names=tuple(names),
        shear_modulus_kpa=np.asarray(obj.shear_modulus_kpa[:m], float),
        radius_mm=1e3 / np.asarray(obj.curvature_per_m[:m], float),
    )


def ramp_actions(targets: np.ndarray, n_steps: int | np.ndarray, config: EnvConfig) -> Callable:
    """The batch policy of :class:`agents.policies.scripted.LinearRamp` with a target (fraction of ``p_max``) per
    sub-env: the same arithmetic, so the same actions bit for bit."""
    targets = np.asarray(targets, dtype=np.float64)
    increment = targets / np.asarray(n_steps, dtype=np.float64)
    step_fraction = config.task.max_pressure_step_kpa / config.task.max_pressure_kpa

    def act(obs, env=None):
        p = np.asarray(obs, dtype=np.float64)[..., 0]
        up = np.minimum(p + increment, targets)
        nxt = np.where(p <= targets, up, targets)
        return np.clip((nxt - p) / step_fraction, -1.0, 1.0)[..., None].astype(np.float32)

    return act


@dataclass(frozen=True)
class RampGrid:
    """Linear ramps to ``targets`` (fractions of ``p_max``) over ``n_steps``, each on every object.

    ``outcome`` holds ``(targets, objects)`` arrays; ``pressure_kpa`` the targets in kPa.
    """

    targets: np.ndarray
    n_steps: int
    pressure_kpa: np.ndarray
    outcome: BatchOutcome

    def rates(self, mask: np.ndarray | None = None) -> np.ndarray:
        """Success rate per target over the objects of ``mask`` (all by default; NaN where the mask is empty)."""
        ok = self.outcome.success if mask is None else self.outcome.success[:, mask]
        return ok.mean(axis=1) if ok.shape[1] else np.full(len(self.targets), math.nan)

    def best(self) -> int:
        """The index of the best target: highest success; then highest mean return (a gentler failure: a late slip
        costs less than a crush); then the middle of the tied plateau (what :mod:`agents.search` has always done)."""
        rate = self.rates()
        ret = self.outcome.returns.mean(axis=1)
        tied = np.flatnonzero(rate >= rate.max() - 1e-12)
        tied = tied[ret[tied] >= ret[tied].max() - 1e-9]
        return int(tied[(len(tied) - 1) // 2])

    def oracle(self) -> np.ndarray:
        """Per object: whether *some* target of the grid holds it (a constant pressure chosen knowing the object;
        the ceiling of the blind ramps on this grid)."""
        return self.outcome.success.any(axis=0)

    def window(self, index: int, points: float = 0.05, mask: np.ndarray | None = None) -> tuple[float, float]:
        """The contiguous pressure window (kPa) around target ``index`` whose success stays within ``points`` of it."""
        rate = self.rates(mask)
        floor = rate[index] - points - 1e-12
        lo = hi = index
        while lo > 0 and rate[lo - 1] >= floor:
            lo -= 1
        while hi < len(rate) - 1 and rate[hi + 1] >= floor:
            hi += 1
        return float(self.pressure_kpa[lo]), float(self.pressure_kpa[hi])


def ramp_grid(config: EnvConfig, seeds: Sequence[int], targets: Sequence[float], n_steps: int = 20,
              backend: str = "auto", parallel: bool | None = None) -> RampGrid:
    """Every ramp of ``targets`` (fractions of ``p_max`` in ``(0, 1]``) over ``n_steps`` steps on every object of
    ``seeds``, as one vector env run of ``len(targets) * len(seeds)`` sub-envs."""
    t = np.asarray(targets, dtype=np.float64)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)) or t.min() <= 0.0 or t.max() > 1.0:
        raise ValueError(f"targets must be fractions of max_pressure_kpa in (0, 1], got {targets!r}")
    if int(n_steps) != n_steps or n_steps < 1:
        raise ValueError(f"n_steps must be an integer >= 1, got {n_steps!r}")
    m = len(seeds)
    act = ramp_actions(np.repeat(t, m), int(n_steps), config)
    out = run_batch(config, seeds, act, copies=t.size, backend=backend, parallel=parallel)
    return RampGrid(t, int(n_steps), t * config.task.max_pressure_kpa, out)


def duration_invariance(config: EnvConfig, seeds: Sequence[int], targets: Sequence[float],
                        durations: Sequence[int], backend: str = "auto") -> dict[str, Any]:
    """Whether ramps of different durations give the same outcome, object for object.

    Returns ``{"durations", "identical": [bool per duration, against the first], "differing_pairs": [...]}``.
    """
    grids = [ramp_grid(config, seeds, targets, n, backend) for n in durations]
    ref = grids[0].outcome
    same, differ = [], []
    for g in grids:
        eq = (g.outcome.success == ref.success) & (g.outcome.damaged == ref.damaged) & \
            (g.outcome.dropped == ref.dropped)
        same.append(bool(eq.all()))
        differ.append(int((~eq).sum()))
    return {"durations": [int(n) for n in durations], "identical": same, "differing_pairs": differ,
            "pairs": int(ref.success.size)}


def batchable(entry) -> bool:
    """Whether a policy entry (:class:`agents.policies.registry.PolicyEntry`) runs batched: a pneu-net policy that maps
    the observation alone to the action (a ramp, a step, a trained model) or reads only the object at reset (the
    oracle). The rigid jaw has no vector env: it runs episode by episode."""
    from agents.common.envs import PNEUNET_ENV
    from agents.policies.oracle import Oracle
    from agents.policies.sb3 import SB3Policy
    from agents.policies.scripted import LinearRamp, StepPolicy

    return entry.env_id == PNEUNET_ENV and isinstance(entry.policy, (LinearRamp, StepPolicy, Oracle, SB3Policy))


def run_policy(entry, config: EnvConfig, seeds: Sequence[int], backend: str = "auto",
               options: dict[str, Any] | None = None) -> BatchOutcome:
    """One episode of ``entry``'s policy per object of ``seeds``, batched (:func:`batchable` entries only); the
    env is the entry's (its ``env_kwargs``, e.g. a model's ``observe_volume``, on top of ``config``); ``options``:
    :func:`run_batch`'s object pins."""
    from agents.policies.oracle import Oracle

    if not batchable(entry):
        raise ValueError(f"policy {entry.name!r} does not run batched (the rigid jaw has no vector env)")
    cfg = load_config(config, **entry.env_kwargs) if entry.env_kwargs else config
    pol = entry.policy
    if not isinstance(pol, Oracle):
        return run_batch(cfg, seeds, lambda obs, env: pol(obs), backend=backend, options=options)
    targets = np.zeros(len(seeds))
    keys = ("object_stiffness", "object_curvature", "failure_traction_kpa", "crush_indentation_mm",
            "grip_traction_kpa")

    def begin(info):  # the oracle's plan for each object, from the reset's info (as run_episode gives it)
        for i in range(len(seeds)):
            pol.begin_episode({k: info[k][i] for k in keys})
            targets[i] = pol.plan["target"]

    def act(obs, env):  # Oracle.__call__, one target per sub-env
        p = np.asarray(obs, dtype=np.float64)[..., 0]
        return np.clip((targets - p) / pol.step_fraction, -1.0, 1.0)[..., None].astype(np.float32)

    return run_batch(cfg, seeds, act, backend=backend, begin=begin, options=options)


def policy_episodes(entry, config: EnvConfig, seeds: Sequence[int], options: dict[str, Any] | None = None,
                    bar=None) -> list[dict[str, Any]]:
    """One episode of ``entry``'s policy per seed, as :func:`agents.evaluation.episodes.run_episode` reports them:
    batched where the policy allows (:func:`batchable`), else episode by episode on ``entry.make_env(config)``; the same
    episodes either way. ``options``: the reset's pins, a value per seed (``(M,)``) or one for all; ``bar``: a
    progress bar, advanced by one per episode."""
    if batchable(entry):
        out = run_policy(entry, config, seeds, options=options).episodes()
        if bar is not None:
            bar.update(len(out))
        return out
    from agents.evaluation.episodes import run_episode

    env = entry.make_env(config)
    out = []
    try:
        for i, s in enumerate(seeds):
            pins = None if options is None else {
                k: (float(np.asarray(v)[i]) if np.ndim(v) == 1 else v) for k, v in options.items()}
            out.append(run_episode(env, entry.policy, int(s), pins))
            if bar is not None:
                bar.update()
    finally:
        env.close()
    return out


def draw_objects(config: EnvConfig, seeds: Sequence[int]):
    """The objects ``reset(seed=s)`` draws for each seed under ``config`` (a :class:`~pneunet_env.objects.GraspObject`
    of ``(M,)`` arrays): one vector env reset, no step."""
    env = _vector_env(config, len(seeds), "auto", None)
    try:
        env.reset(seed=[int(s) for s in seeds])
        return env.objects
    finally:
        env.close()
