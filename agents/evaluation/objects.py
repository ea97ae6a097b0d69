"""The objects an evaluation meets: the stiffness grid and its bins over the task's objects, and objects drawn by
the env into those bins (:func:`draw_bins`) or nearest given stiffnesses (:func:`nearest_drawn`).
"""

from __future__ import annotations

import math

import numpy as np

from pneunet_env.config import EnvConfig

__all__ = ["catalogue_stiffness_range", "stiffness_grid", "stiffness_bins", "GRID_SEED", "draw_bins", "nearest_drawn"]


def catalogue_stiffness_range(config: EnvConfig) -> tuple[float, float]:
    """The smallest and largest ``k~`` the catalogue classes of ``config`` can draw (weight > 0): eq. 3.2's ``k~``
    rises with the modulus, the thickness and the curvature, so the extremes are at the corners of each class's
    ranges (the softest, thinnest, largest object; the stiffest, thickest, smallest)."""
    from pneunet_env.objects import stiffness_per_modulus

    t = config.objects.table
    lo = stiffness_per_modulus(t.thickness_mm[0], 1e3 / t.radius_mm[1], config.scales) * t.shear_modulus_kpa[0]
    hi = stiffness_per_modulus(t.thickness_mm[1], 1e3 / t.radius_mm[0], config.scales) * t.shear_modulus_kpa[1]
    return float(np.min(lo)), float(np.max(hi))


def _stiffness_bounds(config: EnvConfig, k_min: float | None, k_max: float | None) -> tuple[float, float]:
    if config.objects.from_catalogue:
        lo, hi = catalogue_stiffness_range(config)
    else:
        from pneunet_env.objects import stiffness_per_modulus

        oc = config.objects
        unit = float(stiffness_per_modulus(np.mean(oc.object_thickness_mm), np.mean(oc.object_curvature_per_m),
                                           config.scales))
        lo, hi = unit * oc.object_shear_modulus_kpa[0], unit * oc.object_shear_modulus_kpa[1]
    lo = lo if k_min is None else float(k_min)
    hi = hi if k_max is None else float(k_max)
    if not 0.0 < lo <= hi:
        raise ValueError(f"need 0 < k_min <= k_max, got {lo!r} and {hi!r}")
    return lo, hi


def _check_size(n) -> None:
    if int(n) != n or n < 1:
        raise ValueError(f"stiffness grid size must be an integer >= 1, got {n!r}")


def stiffness_grid(config: EnvConfig, n: int, k_min: float | None = None, k_max: float | None = None) -> np.ndarray:
    """``n`` log-spaced ``k~`` spanning the task's objects: the catalogue classes' range
    (:func:`catalogue_stiffness_range`), or, for objects from ranges, ``object_shear_modulus_kpa`` at the middle
    object size. ``k_min`` and ``k_max`` replace the ends."""
    _check_size(n)
    lo, hi = _stiffness_bounds(config, k_min, k_max)
    if n == 1:
        return np.array([math.sqrt(lo * hi)])
    return np.logspace(math.log10(lo), math.log10(hi), int(n))


def stiffness_bins(config: EnvConfig, n: int, k_min: float | None = None,
                   k_max: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(centres, edges)`` of ``n`` log-equal ``k~`` bins over the range :func:`stiffness_grid` spans (``edges``:
    ``n + 1`` values from its low end to its high end; ``centres``: their geometric midpoints)."""
    _check_size(n)
    lo, hi = _stiffness_bounds(config, k_min, k_max)
    if lo == hi:
        lo, hi = lo / 1.01, hi * 1.01
    log_edges = np.linspace(math.log10(lo), math.log10(hi), int(n) + 1)
    # the geometric midpoints, taken in log space: a product of two edges overflows near the float's limit
    return 10.0 ** (0.5 * (log_edges[:-1] + log_edges[1:])), 10.0 ** log_edges


def _edges_around(grid) -> np.ndarray:
    """Bin edges around log-spaced centres (geometric midpoints; a decade around a single one)."""
    g = np.log10(np.asarray(grid, dtype=float))
    if g.size == 1:
        e = np.array([g[0] - 0.5, g[0] + 0.5])
    else:
        mid = 0.5 * (g[1:] + g[:-1])
        e = np.concatenate([[2 * g[0] - mid[0]], mid, [2 * g[-1] - mid[-1]]])
    return 10.0 ** e


GRID_SEED = 2_000_000_000
"""Offset of the seeds of the objects drawn into ``k~`` bins (:func:`draw_bins`): disjoint from the search's
(``seed * 1_000_003 + i``) and the held-out ones (:data:`HELD_OUT_SEED`)."""


def draw_bins(config: EnvConfig, edges, per_bin: int, seed: int = 0, chunk: int = 20_000,
              max_draws: int = 400_000) -> tuple[list[list[int]], int]:
    """Seeds of objects drawn by the env (``reset(seed=s)``, nothing pinned) whose ``k~`` falls in each bin
    ``[edges[i], edges[i + 1])``: the first ``per_bin`` of the stream ``GRID_SEED + seed * 1_000_003 + j``, drawn
    ``chunk`` at a time until every bin is full or ``max_draws`` are drawn (a bin the objects seldom reach may stay
    short, or empty). Returns ``(seeds per bin, objects drawn)``."""
    from agents.evaluation.batch import draw_objects

    edges = np.asarray(edges, dtype=float)
    bins: list[list[int]] = [[] for _ in range(edges.size - 1)]
    base = GRID_SEED + seed * 1_000_003
    drawn = 0
    while drawn < max_draws and any(len(b) < per_bin for b in bins):
        seeds = np.arange(base + drawn, base + drawn + chunk)
        k = np.asarray(draw_objects(config, seeds.tolist()).stiffness, dtype=float)
        idx = np.searchsorted(edges, k, side="right") - 1
        idx[k == edges[-1]] = edges.size - 2  # the top edge belongs to the last bin
        for s, i in zip(seeds.tolist(), idx.tolist(), strict=True):
            if 0 <= i < len(bins) and len(bins[i]) < per_bin:
                bins[i].append(s)
        drawn += chunk
    return bins, drawn


def nearest_drawn(config: EnvConfig, stiffnesses, seed: int = 0, draws: int = 4000) -> list[int]:
    """For each ``k~``, the seed of the object nearest it (in ``log k~``) among ``draws`` drawn by the env."""
    from agents.evaluation.batch import draw_objects
    from agents.evaluation.objects import GRID_SEED

    seeds = np.arange(GRID_SEED + seed * 1_000_003, GRID_SEED + seed * 1_000_003 + draws)
    k = np.log(np.asarray(draw_objects(config, seeds.tolist()).stiffness, dtype=float))
    return [int(seeds[np.argmin(np.abs(k - math.log(t)))]) for t in stiffnesses]
