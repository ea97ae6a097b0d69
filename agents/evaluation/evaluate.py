"""Policies evaluated over the stiffness grid (:func:`evaluate_policies`) and over the env's own object
distribution (:func:`evaluate_distribution`); one recorded episode per stiffness for ``schedules.png``
(:func:`record_schedules`). See :mod:`agents.evaluation.evaluate_cli` for the command.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from agents.common.regimes import SOFT_MAX, STIFF_MIN, object_regimes, regime_rates
from agents.evaluation.batch import HELD_OUT_SEED
from agents.evaluation.episodes import episode_seed
from agents.evaluation.objects import _edges_around, draw_bins
from pneunet_env.config import EnvConfig
from pneunet_env.progress import progress as progress_bar

__all__ = ["evaluate_policies", "evaluate_distribution", "record_schedules"]


def _counts(res, mask=None) -> dict[str, int]:
    """``{episodes, success, damaged, slipped}`` counts over episodes ``res`` (where ``mask``)."""
    m = np.ones(len(res), bool) if mask is None else np.asarray(mask, bool)
    pick = [r for r, keep in zip(res, m, strict=True) if keep]
    return {"episodes": len(pick), "success": int(sum(r["success"] for r in pick)),
            "damaged": int(sum(r["damaged"] for r in pick)), "slipped": int(sum(r["dropped"] for r in pick))}


def _row(entry, k: float, res, regimes: np.ndarray) -> dict[str, Any]:
    from pneunet_env.physics.regimes import REGIMES

    by_regime = {name: _counts(res, regimes == code) for code, name in enumerate(REGIMES)}
    return {
        "policy": entry.name,
        "label": entry.label,
        "object_stiffness": float(k),
        "success_rate": float(np.mean([r["success"] for r in res])),
        "damage_rate": float(np.mean([r["damaged"] for r in res])),
        "slip_rate": float(np.mean([r["dropped"] for r in res])),
        "episodes": len(res),
        "mean_return": float(np.mean([r["return"] for r in res])),
        "mean_peak_traction_kpa": float(np.mean([r["peak_traction_kpa"] for r in res])),
        "object_shear_modulus_kpa": float(np.mean([r["shear_modulus_kpa"] for r in res])),
        "solver_failures": int(sum(r["solver_failed"] for r in res)),
        "by_regime": {name: c for name, c in by_regime.items() if c["episodes"]},
    }


def evaluate_policies(entries, config: EnvConfig, grid, episodes: int, seed: int = 0,
                      progress: bool | None = None, edges=None) -> list[dict[str, Any]]:
    """Rows ``{policy, label, object_stiffness, success_rate, damage_rate, slip_rate, ...}``: one per policy, ``k~``.

    Objects from ranges: ``episodes`` episodes at each ``k~`` of ``grid``, pinned. Objects from the catalogue:
    ``episodes`` objects drawn by the env into each ``k~`` bin (:func:`draw_bins`; ``edges``: the bins' edges,
    default: around ``grid``'s points), nothing pinned; a row's ``object_stiffness`` is its bin's centre, its
    ``k_range`` the bin, and a bin no object reached has no row. Every row has ``by_regime`` (counts by the
    objects' regimes, :func:`object_regimes`); drawn objects also ``by_class``.

    ``progress``: a bar on stderr; ``None`` (default): when stderr is a terminal.
    """
    if int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    from agents.evaluation.batch import policy_episodes

    grid = np.asarray(grid, dtype=float)
    drawn = config.objects.from_catalogue
    if drawn:
        edges = _edges_around(grid) if edges is None else np.asarray(edges, dtype=float)
        if edges.size != grid.size + 1:
            raise ValueError(f"edges must be one more than the grid's {grid.size} points, got {edges.size}")
        bins, _ = draw_bins(config, edges, int(episodes), seed)
        seeds = [s for b in bins for s in b]
        options = None
        sizes = [len(b) for b in bins]
    else:
        seeds = [episode_seed(seed, i, e) for i in range(len(grid)) for e in range(episodes)]
        options = {"object_stiffness": np.repeat(grid, episodes)}
        sizes = [int(episodes)] * len(grid)
    bar = progress_bar(total=len(entries) * len(seeds), desc="evaluate", unit="episode", enabled=progress)
    rows = []
    regimes = None
    for entry in entries:
        # every object in one vector env run where the policy allows it (the same episodes)
        done = policy_episodes(entry, config, seeds, options, bar)
        if regimes is None:  # the same objects for every policy
            regimes = object_regimes([r["stiffness"] for r in done], [r["curvature"] for r in done], config)
        start = 0
        for i, k in enumerate(grid):
            res, reg = done[start:start + sizes[i]], regimes[start:start + sizes[i]]
            start += sizes[i]
            if not res:
                continue
            row = _row(entry, k, res, reg)
            if drawn:
                classes = [r["object_class"] for r in res]
                row.update(objects="drawn", k_range=[float(edges[i]), float(edges[i + 1])],
                           mean_object_stiffness=float(np.exp(np.mean(np.log([r["stiffness"] for r in res])))),
                           by_class={c: _counts(res, [x == c for x in classes]) for c in dict.fromkeys(classes)})
            rows.append(row)
    bar.close()
    return rows


def evaluate_distribution(entries, config: EnvConfig, n_objects: int, seed: int = 0,
                          progress: bool | None = None) -> dict[str, dict[str, float]]:
    """Each policy on ``n_objects`` objects drawn from the env's own distribution (held-out seeds
    ``HELD_OUT_SEED + seed * 1_000_003 + i``): ``{policy: {success_rate, damage_rate, slip_rate, objects, ...}}``,
    with success by regime (:func:`regime_rates`) and, for objects from ranges, by the paper's ``k~`` bins
    (``success_rate_soft``, ``success_rate_stiff``: ``None`` where no object falls in the bin)."""
    seeds = [HELD_OUT_SEED + seed * 1_000_003 + i for i in range(n_objects)]
    bar = progress_bar(total=len(entries) * n_objects, desc="distribution", unit="episode", enabled=progress)
    from agents.evaluation.batch import policy_episodes

    out = {}
    for entry in entries:
        res = policy_episodes(entry, config, seeds, bar=bar)  # batched where the policy allows: the same episodes
        k = np.array([r["stiffness"] for r in res])
        ok = np.array([r["success"] for r in res])
        d = {
            "objects": n_objects,
            "success_rate": float(ok.mean()),
            "damage_rate": float(np.mean([r["damaged"] for r in res])),
            "slip_rate": float(np.mean([r["dropped"] for r in res])),
            **{key: (None if isinstance(v, float) and math.isnan(v) else v)
               for key, v in regime_rates(ok, k, [r["curvature"] for r in res], config).items()},
        }
        if not config.objects.from_catalogue:  # the paper ring's k~ bins (every hand-scale object is above them)
            soft, stiff = k < SOFT_MAX, k >= STIFF_MIN
            d.update(success_rate_soft=float(ok[soft].mean()) if soft.any() else None,
                     success_rate_stiff=float(ok[stiff].mean()) if stiff.any() else None,
                     objects_soft=int(soft.sum()), objects_stiff=int(stiff.sum()))
        out[entry.name] = d
    bar.close()
    return out


def record_schedules(entries, config: EnvConfig, stiffnesses, seed: int = 0,
                     seeds=None) -> list[dict[str, Any]]:
    """One recorded episode per policy and stiffness: ``{policy, label, command, object_stiffness, ...outcome}``.

    ``seeds`` (one per stiffness): run those objects as the env draws them, nothing pinned (the catalogue's);
    else each ``k~`` is pinned."""
    from agents.evaluation.episodes import episode_seed, run_episode

    out = []
    for entry in entries:
        env = entry.make_env(config)
        for j, k in enumerate(stiffnesses):
            if seeds is None:
                r = run_episode(env, entry.policy, episode_seed(seed, 10_000 + j, 0), {"object_stiffness": float(k)},
                                record=True)
            else:
                r = run_episode(env, entry.policy, int(seeds[j]), record=True)
            r.update(policy=entry.name, label=entry.label, command=entry.command)
            out.append(r)
        env.close()
    return out
