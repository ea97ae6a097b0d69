"""``pneunet-grasp evaluate``: policies against object stiffness, with fixed seeds, on the active task.

``pneunet-grasp evaluate --policy NAME_OR_MODEL_PATH [--policy ...] --stiffness-grid N --episodes M --out DIR``

For every policy (:mod:`agents.policies`: ``ramp``, ``step``, ``best-ramp``, ``oracle``, ``rigid`` or a
stable-baselines3 ``.zip``) it runs episodes across ``N`` log-spaced values of the object stiffness ``k~``. How
depends on where the task's objects come from (:func:`task_description`):

* **objects from the catalogue** (the default task, ``PneuNetGrasp-v0``: its *kitchen* use case): ``N`` log-spaced
  ``k~`` bins span the use case's classes (:func:`catalogue_stiffness_range`; 1.6e-3 to 37 for the kitchen), and
  each bin holds ``M`` objects *drawn by the env* whose ``k~`` falls in it (:func:`draw_bins`: real apples, gels,
  ..., nothing pinned; seeds ``GRID_SEED + seed * 1_000_003 + j``). Pinning a ``k~`` onto a catalogue draw would
  give an apple the modulus of a gel but keep its failure stress: not an object of the task.
* **objects from ranges** (the paper's task, ``PneuNetGrasp-Paper-v0``: its 250 mm ring): ``N`` log-spaced ``k~``
  spanning the ranges (``k~`` of ``object_shear_modulus_kpa`` at the middle object size: 6.8e-6 to 0.10), ``M``
  episodes each with ``k~`` pinned (``reset(seed=..., options={"object_stiffness": k})``, seed
  ``seed * 1_000_003 + 1000 i + e``).

Seeds are fixed and shared by every policy, so the policies face the same objects. It then

* prints the task (its objects, its damage rule in words, its slip rule) and, per policy, success / damage / slip
  by stiffness decade and by regime, read off the mechanics (:mod:`pneunet_env.physics.regimes`:
  force-controlled or position-controlled); on the catalogue also by class; on the paper's ring also by the
  paper's own ``k~`` bins, soft (``k~ < 1e-4``) and stiff (``k~ >= 1e-3``), which mean nothing at hand scale;
* writes ``DIR/evaluation.json``: a list of rows ``{policy, object_stiffness, success_rate, damage_rate,
  slip_rate}`` (plus ``label``, ``episodes``, ``mean_return``, ``mean_peak_traction_kpa``,
  ``object_shear_modulus_kpa``, ``solver_failures``, ``by_regime``; drawn objects: ``k_range``, ``by_class``), and
  ``DIR/evaluation_summary.json`` (the task, per policy and regime, the config and seeds);
* writes ``DIR/success_vs_stiffness.png``: every policy on one chart, with the regimes (on the ring: the paper's
  ``k~`` bins, and the stiffness below which no state both holds and spares the object under the crush-fraction
  rule, :func:`agents.oracle.feasible_stiffness`);
* with ``--objects N``, runs N objects drawn from the env's own distribution (held-out seeds) and reports each
  policy's overall success rate (the number the best-ramp search maximises, on objects it did not see);
* writes ``DIR/schedules.png``: the pressure (or jaw closure) each policy actually applied, step by step, for
  objects from soft to stiff (``--schedule-stiffness``; on the catalogue, the drawn object nearest each ``k~``).

``--config`` and ``--set KEY=VALUE`` change the environment (e.g. ``--set object_density_kg_m3=30`` for a
sensitivity run, ``--set use_case=null --set damage_rule=crush_fraction`` for the paper's task); the defaults are
the env's physically justified thresholds (``docs/env.md``). The PNGs need matplotlib (extra ``plot``), checked
before any episode runs; ``--no-plots`` does without.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from agents.plotting import (  # noqa: F401 (their old home)
    _matplotlib,
    _style,
    nearest_drawn,
    plot_schedules,
    plot_success,
    record_schedules,
)
from pneunet_env import arguments as checks
from pneunet_env.config import EnvConfig, ObjectConfig, load_config
from pneunet_env.files import atomic_write_text
from pneunet_env.progress import add_progress_argument
from pneunet_env.progress import progress as progress_bar

__all__ = ["run_episode", "stiffness_grid", "stiffness_bins", "catalogue_stiffness_range", "draw_bins",
           "evaluate_policies", "evaluate_distribution", "decade_table",
           "regime_summary", "object_regimes", "regime_rates", "use_case_regimes", "task_description",
           "damage_rule_text", "slip_rule_text", "regime_text", "is_paper_ring", "default_model", "usage_error",
           "rate_parts",
           "plot_success", "plot_schedules", "parse_overrides", "SOFT_MAX", "STIFF_MIN",
           "add_arguments", "run"]

SOFT_MAX = 1e-4
"""The paper's soft regime on its ring: ``k~ < 1e-4`` (a 1.5 kPa gel at the paper's object size)."""
STIFF_MIN = 1e-3
"""The paper's stiff regime on its ring: ``k~ >= 1e-3`` (a 15 kPa elastomer)."""

DEFAULT_POLICIES = ("best-ramp", "oracle", "rigid")
DEFAULT_MODEL = Path(__file__).resolve().parent / "models" / "ppo_kitchen.zip"
"""PPO trained on the default task (pressure only); ``models/ppo_pneunet.zip`` was trained on the paper's task."""
PAPER_MODEL = DEFAULT_MODEL.with_name("ppo_pneunet.zip")
"""PPO trained on the paper's task (its ring, the crush-fraction rule)."""

PAPER_SCHEDULE_STIFFNESS = (1e-5, 3e-4, 1.2e-3, 1e-2)
"""The ``k~`` of ``schedules.png`` on the paper's ring (on the catalogue: four across the grid)."""


# ---------------------------------------------------------------------------------------------
# The active task, in words
# ---------------------------------------------------------------------------------------------


def _fmt_range(r, unit: str = "") -> str:
    u = f" {unit}" if unit else ""
    return f"{r[0]:g}{u}" if r[0] == r[1] else f"{r[0]:g}-{r[1]:g}{u}"


def is_paper_ring(config: EnvConfig) -> bool:
    """Whether ``config``'s objects are the paper's ring: drawn from ranges whose size is the paper's (its defaults,
    ``R = 250 mm``, ``H = 10 mm``)."""
    oc = config.objects
    default = {f.name: f.default for f in fields(ObjectConfig)}
    return (not oc.from_catalogue and oc.object_curvature_per_m == default["object_curvature_per_m"]
            and oc.object_thickness_mm == default["object_thickness_mm"])


def task_description(config: EnvConfig) -> str:
    """The task's objects in words: the catalogue's use case (or classes) with their weights, or the ranges (the
    paper's 250 mm ring by default)."""
    oc = config.objects
    if oc.from_catalogue:
        weights = ", ".join(f"{n.replace('_', ' ')} {w:.0%}" for n, w in _class_weights(config).items())
        if oc.class_weights is not None:
            return f"catalogue classes ({weights})"
        return f"the catalogue's {oc.use_case!r} use case ({weights})"
    radius = tuple(1e3 / c for c in oc.object_curvature_per_m[::-1])
    what = "the paper's ring" if is_paper_ring(config) else "objects from ranges"
    return (f"{what}: R = {_fmt_range(np.round(radius, 3), 'mm')}, H = {_fmt_range(oc.object_thickness_mm, 'mm')}, "
            f"mu_obj {_fmt_range(oc.object_shear_modulus_kpa, 'kPa')}, "
            f"rho {_fmt_range(oc.object_density_kg_m3, 'kg/m^3')}, failure strain "
            f"{_fmt_range(oc.object_failure_strain)}")


def _class_weights(config: EnvConfig) -> dict[str, float]:
    """``{class: normalised weight}`` of the classes a catalogue config draws (weight > 0)."""
    items = [(n, float(w)) for n, w in config.objects.class_items if w > 0]
    total = sum(w for _, w in items)
    return {n: w / total for n, w in items}


def damage_rule_text(config: EnvConfig) -> str:
    """The config's damage rule (``damage_rule``, whatever the objects), in words."""
    tc = config.task
    if tc.damage_rule == "hoop_strain":
        stress = "its class's failure stress" if config.objects.from_catalogue else "its failure stress 3 eps_f mu_obj"
        return (f"damaged when the hoop strain delta kappa_obj exceeds the object's failure strain eps_f, or the "
                f"traction F exceeds {stress} (damage_rule hoop_strain)")
    return (f"damaged when the indentation delta exceeds {tc.crush_fraction:g} H (crush_fraction {tc.crush_fraction:g}"
            f"), or the traction F exceeds 3 eps_f mu_obj (damage_rule crush_fraction)")


def slip_rule_text(config: EnvConfig) -> str:
    """The slip rule in words (the hold phase's)."""
    tc = config.task
    rho = "" if config.objects.from_catalogue else f", rho = {_fmt_range(config.objects.object_density_kg_m3)} kg/m^3"
    return (f"slipped (hold phase) when F < rho g H / ({tc.grip_faces} mu_f), mu_f = {tc.friction_coefficient:g}"
            f"{rho}")


def regime_text(config: EnvConfig) -> str:
    """How an object's regime is read off the mechanics (:mod:`pneunet_env.physics.regimes`), in words."""
    return (f"regime from the mechanics at {config.task.max_pressure_kpa:g} kPa: force-controlled when the object "
            "blocks less than half of the curl the free finger would make past its surface (it yields; "
            "blocked_fraction phi < 1/2), position-controlled otherwise (it stops the finger)")


def default_model(config: EnvConfig) -> Path | None:
    """The shipped PPO model of ``config``'s task, if present: :data:`DEFAULT_MODEL` on the catalogue's objects,
    :data:`PAPER_MODEL` on the paper's ring under its crush-fraction rule, else ``None``."""
    if config.objects.from_catalogue:
        path = DEFAULT_MODEL
    elif is_paper_ring(config) and config.task.damage_rule == "crush_fraction":
        path = PAPER_MODEL
    else:
        return None
    return path if path.is_file() else None


def usage_error(prog: str, message: str) -> None:
    """An argument error, argparse's way: one line ``PROG: error: MESSAGE`` on stderr, exit status 2."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def rate_parts(parts) -> str:
    """``"force-controlled 75% of 195, position-controlled 99% of 205"`` from ``(name, rate, n)``; a group of no
    objects is left out, and none at all reads ``"no objects"``."""
    out = [f"{name} {_pct1(rate)} of {n}" for name, rate, n in parts if n]
    return ", ".join(out) if out else "no objects"


def _pct1(x: float) -> str:
    return f"{x:.0%}" if x in (0.0, 1.0) else f"{x:.1%}"


# ---------------------------------------------------------------------------------------------
# Episodes
# ---------------------------------------------------------------------------------------------


def run_episode(env, policy, seed: int | None = None, options: dict[str, Any] | None = None,
                record: bool = False) -> dict[str, Any]:
    """One episode of ``policy`` on ``env``; its outcome.

    ``policy.begin_episode(info)`` (if present) is called with ``reset``'s info. With ``record``, the
    command applied at each step (``pressure_kpa``, or ``jaw_closure_mm`` for the rigid gripper) is kept,
    from the reset state (index 0) to the last step.

    Returns:
        ``{stiffness, shear_modulus_kpa, success, damaged, dropped, return, steps, peak_traction_kpa,
        solver_failed, commands}`` (``commands`` only with ``record``).
    """
    obs, info = env.reset(seed=seed, options=options)
    reset_info = info  # the object's constants are in the reset info
    begin = getattr(policy, "begin_episode", None)
    if begin is not None:
        begin(info)
    key = "jaw_closure_mm" if "jaw_closure_mm" in info else "pressure_kpa"
    commands = [float(info[key])] if record else None
    ret, steps, peak, failed = 0.0, 0, 0.0, False
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        steps += 1
        peak = max(peak, float(info["contact_force_kpa"]))
        failed = failed or bool(info.get("solver_failed", False))
        if record:
            commands.append(float(info[key]))
        if terminated or truncated:
            break
    out = {
        "stiffness": float(reset_info["object_stiffness"]),
        "shear_modulus_kpa": float(reset_info["object_shear_modulus_kpa"]),
        "curvature": float(reset_info["object_curvature"]),
        "object_class": str(reset_info.get("object_class", "ranges")),
        "success": bool(info.get("is_success", False)),
        "damaged": bool(info["damaged"]),
        "dropped": bool(info["dropped"]),
        "return": float(ret),
        "steps": steps,
        "peak_traction_kpa": peak,
        "solver_failed": failed,
    }
    if record:
        out["commands"] = commands
    return out


def catalogue_stiffness_range(config: EnvConfig) -> tuple[float, float]:
    """The smallest and largest ``k~`` the catalogue classes of ``config`` can draw (weight > 0): eq. 3.2's ``k~``
    rises with the modulus, the thickness and the curvature, so the extremes are at the corners of each class's
    ranges (the softest, thinnest, largest object; the stiffest, thickest, smallest)."""
    from pneunet_env.catalogue import class_table
    from pneunet_env.objects import stiffness_per_modulus

    t = class_table(config.objects.class_items)
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


def episode_seed(seed: int, grid_index: int, episode: int) -> int:
    """The seed of episode ``episode`` at grid point ``grid_index`` (shared by every policy)."""
    return seed * 1_000_003 + 1000 * grid_index + episode


GRID_SEED = 2_000_000_000
"""Offset of the seeds of the objects drawn into ``k~`` bins (:func:`draw_bins`): disjoint from the search's
(``seed * 1_000_003 + i``) and the held-out ones (:data:`HELD_OUT_SEED`)."""


def draw_bins(config: EnvConfig, edges, per_bin: int, seed: int = 0, chunk: int = 20_000,
              max_draws: int = 400_000) -> tuple[list[list[int]], int]:
    """Seeds of objects drawn by the env (``reset(seed=s)``, nothing pinned) whose ``k~`` falls in each bin
    ``[edges[i], edges[i + 1])``: the first ``per_bin`` of the stream ``GRID_SEED + seed * 1_000_003 + j``, drawn
    ``chunk`` at a time until every bin is full or ``max_draws`` are drawn (a bin the objects seldom reach may stay
    short, or empty). Returns ``(seeds per bin, objects drawn)``."""
    from agents.batch import draw_objects

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
    from agents.batch import policy_episodes

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


HELD_OUT_SEED = 1_000_000_000
"""Offset of the ``--objects`` episodes' seeds: disjoint from the search's (``seed * 1_000_003 + i``)."""


def evaluate_distribution(entries, config: EnvConfig, n_objects: int, seed: int = 0,
                          progress: bool | None = None) -> dict[str, dict[str, float]]:
    """Each policy on ``n_objects`` objects drawn from the env's own distribution (held-out seeds
    ``HELD_OUT_SEED + seed * 1_000_003 + i``): ``{policy: {success_rate, damage_rate, slip_rate, objects, ...}}``,
    with success by regime (:func:`regime_rates`) and, for objects from ranges, by the paper's ``k~`` bins
    (``success_rate_soft``, ``success_rate_stiff``: ``None`` where no object falls in the bin)."""
    seeds = [HELD_OUT_SEED + seed * 1_000_003 + i for i in range(n_objects)]
    bar = progress_bar(total=len(entries) * n_objects, desc="distribution", unit="episode", enabled=progress)
    from agents.batch import policy_episodes

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


# ---------------------------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------------------------


def _rates(rows) -> dict[str, Any]:
    """Episode-weighted rates over ``rows``; ``None`` rates where there is no episode."""
    w = np.array([r["episodes"] for r in rows], dtype=float)
    if w.sum() == 0:
        return {"episodes": 0, "success_rate": None, "damage_rate": None, "slip_rate": None}
    avg = lambda key: float(np.dot(w, [r[key] for r in rows]) / w.sum())  # noqa: E731
    return {"episodes": int(w.sum()), "success_rate": avg("success_rate"), "damage_rate": avg("damage_rate"),
            "slip_rate": avg("slip_rate")}


def _count_rates(counts) -> dict[str, Any]:
    """Rates from summed ``{episodes, success, damaged, slipped}`` counts (``None`` where there is no episode)."""
    n = sum(c["episodes"] for c in counts)
    if n == 0:
        return {"episodes": 0, "success_rate": None, "damage_rate": None, "slip_rate": None}
    tot = lambda key: sum(c[key] for c in counts) / n  # noqa: E731
    return {"episodes": n, "success_rate": tot("success"), "damage_rate": tot("damaged"), "slip_rate": tot("slipped")}


def _paper_bins(rows) -> bool:
    """Whether the paper's ``k~`` bins apply: objects pinned on a ``k~`` grid (not drawn from the catalogue)."""
    return not any(r.get("objects") == "drawn" for r in rows)


def regime_summary(rows, paper_bins: bool | None = None) -> dict[str, dict[str, dict[str, float]]]:
    """``{policy: {group: rates}}``, episode-weighted: ``"all"``; the regimes read off the mechanics
    (``"force-controlled"``, ``"position-controlled"``, ``"unreachable"``: those with episodes, from the rows'
    ``by_regime``); with ``paper_bins`` (default: unless the rows are drawn from the catalogue) the paper's ``k~``
    bins ``"soft"`` (``< 1e-4``), ``"intermediate"`` and ``"stiff"`` (``>= 1e-3``); for drawn objects each class.
    An empty group's rates are ``None``."""
    from pneunet_env.physics.regimes import REGIMES

    paper_bins = _paper_bins(rows) if paper_bins is None else paper_bins
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        groups: dict[str, dict[str, Any]] = {}
        for reg in REGIMES:
            counts = [r["by_regime"][reg] for r in rs if reg in r.get("by_regime", {})]
            if counts:
                groups[reg] = _count_rates(counts)
        if paper_bins:
            groups["soft"] = _rates([r for r in rs if r["object_stiffness"] < SOFT_MAX])
            groups["intermediate"] = _rates([r for r in rs if SOFT_MAX <= r["object_stiffness"] < STIFF_MIN])
            groups["stiff"] = _rates([r for r in rs if r["object_stiffness"] >= STIFF_MIN])
        classes = dict.fromkeys(c for r in rs for c in r.get("by_class", {}))
        for c in classes:
            groups[f"class {c}"] = _count_rates([r["by_class"][c] for r in rs if c in r.get("by_class", {})])
        groups["all"] = _rates(rs)
        out[name] = groups
    return out


def object_regimes(stiffness, curvature, config: EnvConfig) -> np.ndarray:
    """Each object's regime code (:data:`pneunet_env.physics.regimes.FORCE`, ``POSITION`` or ``UNREACHABLE``),
    read off the mechanics at ``config``'s maximum pressure, with its actuator and solver settings."""
    from pneunet_env.physics.regimes import regime

    return regime(stiffness, curvature, config.pressure_max, config.actuator_params, config.solver)


def regime_rates(success, stiffness, curvature, config: EnvConfig) -> dict[str, Any]:
    """``{success_rate_force, success_rate_position, objects_force, objects_position}``: success split by the
    objects' regimes (:func:`object_regimes`; NaN for an empty side)."""
    from pneunet_env.physics.regimes import FORCE, POSITION

    ok = np.asarray(success, dtype=bool)
    reg = object_regimes(stiffness, curvature, config)
    rate = lambda m: float(ok[m].mean()) if m.any() else math.nan  # noqa: E731
    return {"success_rate_force": rate(reg == FORCE), "success_rate_position": rate(reg == POSITION),
            "objects_force": int((reg == FORCE).sum()), "objects_position": int((reg == POSITION).sum())}


def use_case_regimes(use_case: str, draws: int = 4000, seed: int = 0) -> dict[str, Any]:
    """What a catalogue use case draws, read off the mechanics (docs/env.md's table of use cases).

    ``draws`` objects from :func:`pneunet_env.task.sample_object` (``default_rng(seed)``), each classed by
    :func:`pneunet_env.physics.regimes.regime` at the config's maximum pressure. Returns the shares
    ``{"force", "position", "unreachable"}``, the largest ``k~`` drawn, and ``modulus_span_decades``:
    ``log10`` of the largest over the smallest Young's modulus of the classes with weight (their catalogue
    ranges, not the draws).
    """
    from pneunet_env.catalogue import load_catalogue, use_case_weights
    from pneunet_env.physics.regimes import FORCE, POSITION, UNREACHABLE
    from pneunet_env.task import sample_object

    cfg = load_config(use_case=use_case)
    obj = sample_object(np.random.default_rng(seed), cfg, size=draws)
    reg = object_regimes(obj.stiffness, obj.curvature, cfg)
    catalogue = load_catalogue()
    moduli = [catalogue[name].youngs_modulus_kpa for name, w in use_case_weights(use_case).items() if w > 0]
    return {"use_case": use_case, "draws": draws, "seed": seed,
            "force": float(np.mean(reg == FORCE)), "position": float(np.mean(reg == POSITION)),
            "unreachable": float(np.mean(reg == UNREACHABLE)), "max_stiffness": float(np.max(obj.stiffness)),
            "modulus_span_decades": math.log10(max(e[1] for e in moduli) / min(e[0] for e in moduli))}


def decade_table(rows, paper_bins: bool | None = None) -> str:
    """Success / damage / slip by stiffness decade, by regime (read off the mechanics), by the paper's ``k~`` bins
    (``paper_bins``, as :func:`regime_summary`) and by class (drawn objects), one block per policy. A group with no
    episode is left out."""
    paper_bins = _paper_bins(rows) if paper_bins is None else paper_bins
    lines = []
    summary = regime_summary(rows, paper_bins)
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        lines.append(f"{name}: {rs[0]['label']}")
        lines.append(f"  {'k~':>19}  {'episodes':>8}  {'success':>7}  {'damaged':>7}  {'slipped':>7}")
        decades = sorted({math.floor(math.log10(r["object_stiffness"]) + 1e-12) for r in rs})
        for d in decades:
            sub = [r for r in rs if math.floor(math.log10(r["object_stiffness"]) + 1e-12) == d]
            lines.append(_line(f"1e{d:+03d} - 1e{d + 1:+03d}", _rates(sub)))
        groups = summary[name]
        labels = {"force-controlled": "force-controlled", "position-controlled": "position-controlled",
                  "unreachable": "unreachable", "soft": "soft (< 1e-4)", "stiff": "stiff (>= 1e-3)"}
        labels.update({g: g.removeprefix("class ").replace("_", " ") for g in groups if g.startswith("class ")})
        for g, label in labels.items():
            if g in groups and groups[g]["episodes"]:
                lines.append(_line(label, groups[g]))
        lines.append(_line("all", groups["all"]))
        lines.append("")
    return "\n".join(lines)


def _line(label: str, r: dict[str, Any]) -> str:
    if r["episodes"] == 0:
        return f"  {label:>19}  no objects"
    return (f"  {label:>19}  {r['episodes']:>8}  {r['success_rate']:7.0%}  {r['damage_rate']:7.0%}  "
            f"{r['slip_rate']:7.0%}")


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def parse_overrides(items) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` -> a dict, each VALUE read as YAML exactly as in a config file
    (:func:`pneunet_env.yamlio.parse_value`: ``30``, ``5e1``, ``[30, 1000]``, ``true``); ``ValueError`` naming the
    item for a bad value. A key set twice takes its last value."""
    from pneunet_env.yamlio import parse_value

    out: dict[str, Any] = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ValueError(f"--set needs KEY=VALUE, got {item!r}")
        out[key.strip()] = parse_value(value, f"--set {item!r}")
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--policy", action="append", default=None, metavar="NAME_OR_MODEL_PATH",
                        help="a policy (repeatable): ramp, step, best-ramp, oracle, rigid (optionally "
                             "NAME:key=value,...), or an SB3 model .zip. Default: best-ramp, oracle, rigid, and the "
                             "task's PPO model if present (agents/models/ppo_kitchen.zip on the default task, "
                             "ppo_pneunet.zip on the paper's)")
    parser.add_argument("--stiffness-grid", type=checks.integer(1, 10_000, "the stiffness grid size"), default=25,
                        help="log-spaced k~ values (default 25): on the catalogue, bins of drawn objects")
    parser.add_argument("--episodes", type=checks.count, default=2,
                        help="episodes per policy and k~ (default 2): on the catalogue, objects per bin")
    parser.add_argument("--out", type=checks.output_dir, default="evaluation",
                        help="output folder, checked before any episode; files in it are replaced (default "
                             "./evaluation)")
    parser.add_argument("--seed", type=checks.seed, default=0, help="base seed (default 0)")
    parser.add_argument("--k-min", type=checks.positive, default=None,
                        help="smallest k~ (default: the task's objects' range)")
    parser.add_argument("--k-max", type=checks.positive, default=None,
                        help="largest k~ (default: the task's objects' range)")
    parser.add_argument("--schedule-stiffness", type=checks.positive, nargs="+", default=None,
                        help="k~ of the episodes drawn in schedules.png (default: on the paper's ring 1e-5 3e-4 "
                             "1.2e-3 1e-2; on the catalogue four across the grid, each the drawn object nearest it)")
    parser.add_argument("--config", default=None, help="environment config YAML (default: the env's defaults)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key (repeatable; VALUE is YAML); the paper's task: "
                             "--set use_case=null --set damage_rule=crush_fraction")
    parser.add_argument("--objects", type=checks.integer(0, checks.MAX_COUNT), default=0,
                        help="also run N objects drawn from the env's own distribution (held-out seeds) and report "
                             "each policy's overall success rate (default 0: none)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNGs (and matplotlib)")
    add_progress_argument(parser, "--quiet")


PROG = "pneunet-grasp evaluate"


def run(args: argparse.Namespace) -> int:
    from agents.policies import make_policy, tuned_schedules_text, warn_untuned
    from pneunet_env.extras import require_extra

    if args.objects < 0:
        usage_error(PROG, f"--objects must be >= 0, got {args.objects}")
    if args.episodes < 1:
        usage_error(PROG, f"--episodes must be >= 1, got {args.episodes}")
    if args.stiffness_grid * args.episodes > checks.MAX_COUNT:  # every policy's objects are listed up front
        usage_error(PROG, f"--stiffness-grid x --episodes is {args.stiffness_grid * args.episodes}; at most "
                          f"{checks.MAX_COUNT}")
    if args.no_plots and args.schedule_stiffness is not None:
        usage_error(PROG, "--schedule-stiffness sets what schedules.png draws; it does nothing with --no-plots")
    if not args.no_plots:  # before any episode: not a traceback once the work is done
        require_extra("evaluate", "matplotlib", "plot", "the plots", skip="--no-plots")
    try:
        config = load_config(args.config, **parse_overrides(args.overrides))
        model = default_model(config)
        if args.policy is None and model is not None:  # the default policies run the task's PPO model too
            require_extra("evaluate", "stable_baselines3", "rl", f"the default policies' PPO model ({model.name})",
                          skip=" ".join(f"--policy {p}" for p in DEFAULT_POLICIES))
        specs = args.policy or list(DEFAULT_POLICIES) + ([str(model)] if model is not None else [])
        entries = [make_policy(s, config, config_path=args.config) for s in specs]
        warn_untuned(PROG, entries, args.config, args.overrides)
        drawn = config.objects.from_catalogue
        if drawn:
            grid, edges = stiffness_bins(config, args.stiffness_grid, args.k_min, args.k_max)
        else:
            grid, edges = stiffness_grid(config, args.stiffness_grid, args.k_min, args.k_max), None
        if args.schedule_stiffness is not None and min(args.schedule_stiffness) <= 0:
            raise ValueError(f"--schedule-stiffness must be > 0, got {args.schedule_stiffness}")
    except ValueError as exc:
        raise SystemExit(f"{PROG}: {exc}") from None
    names = [e.name for e in entries]
    if len(set(names)) != len(names):
        raise SystemExit(f"{PROG}: a policy is given twice: {names}")
    t0 = time.perf_counter()
    rows = evaluate_policies(entries, config, grid, args.episodes, args.seed, progress=args.progress, edges=edges)
    traces = []
    if not args.no_plots:
        if args.schedule_stiffness is not None:
            sched = list(args.schedule_stiffness)
        elif drawn:  # four across the grid, at 1/8, 3/8, 5/8 and 7/8 of its log range
            sched = list(np.exp(np.log(edges[0]) + np.log(edges[-1] / edges[0]) * np.array([1, 3, 5, 7]) / 8))
        else:
            sched = list(PAPER_SCHEDULE_STIFFNESS)
        seeds = nearest_drawn(config, sched, args.seed) if drawn else None
        traces = record_schedules(entries, config, sched, args.seed, seeds=seeds)
    dist = evaluate_distribution(entries, config, args.objects, args.seed, args.progress) if args.objects else None
    elapsed = time.perf_counter() - t0

    n_ep = sum(r["episodes"] for r in rows)
    print(f"{PROG}: {task_description(config)}")
    print(f"  {damage_rule_text(config)}")
    print(f"  {slip_rule_text(config)}")
    print(f"  {regime_text(config)}")
    if tuned := tuned_schedules_text(entries):
        print(f"  {tuned}")
    bins = sorted({r["object_stiffness"] for r in rows})
    if drawn:
        print(f"{len(entries)} policies x {len(bins)} k~ bins from {edges[0]:.2g} to {edges[-1]:.2g} x up to "
              f"{args.episodes} objects drawn by the env into each (nothing pinned; {n_ep // max(1, len(entries))} "
              f"objects, the same for every policy), seed {args.seed}")
        if len(bins) < len(grid):
            print(f"  ({len(grid) - len(bins)} of the {len(grid)} bins drew no object and are left out)")
    else:
        print(f"{len(entries)} policies x {len(grid)} stiffnesses (k~ {grid[0]:.2g} to {grid[-1]:.2g}, pinned) x "
              f"{args.episodes} episodes, seed {args.seed}")
    if drawn:
        print("  (every bin counts alike in 'all', not as the task draws its objects: --objects N gives the task's "
              "own rate)")
    print()
    print(decade_table(rows))
    if dist is not None:
        print(f"on {args.objects} objects from the env's own distribution (held-out seeds):")
        for name, d in dist.items():
            parts = rate_parts([("force-controlled", d["success_rate_force"], d["objects_force"]),
                                ("position-controlled", d["success_rate_position"], d["objects_position"])])
            if "objects_soft" in d:
                parts += "; the paper's k~ bins: " + rate_parts([("soft", d["success_rate_soft"], d["objects_soft"]),
                                                                 ("stiff", d["success_rate_stiff"],
                                                                  d["objects_stiff"])])
            print(f"  {name:>24}: success {d['success_rate']:6.1%} ({parts}), damaged {d['damage_rate']:.1%}, "
                  f"slipped {d['slip_rate']:.1%}")
        print()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "evaluation.json", json.dumps(rows, indent=1, allow_nan=False) + "\n")
    from agents.oracle import feasible_stiffness

    paper_bins = not drawn
    summary = {
        "task": {"objects": task_description(config), "damage_rule": config.task.damage_rule,
                 "damage": damage_rule_text(config), "slip": slip_rule_text(config), "regimes": regime_text(config),
                 "grid": ("objects drawn by the env into log-spaced k~ bins (nothing pinned)" if drawn
                          else "k~ pinned on a log-spaced grid")},
        "policies": {e.name: {"label": e.label, "env_id": e.env_id, "blind": e.blind,
                              **({"tuned_on": e.tuned_on} if e.tuned_on else {})} for e in entries},
        "regimes": regime_summary(rows, paper_bins),
        "regime_bounds": ({"soft": f"k~ < {SOFT_MAX:g}", "stiff": f"k~ >= {STIFF_MIN:g}",
                           "note": "the paper's k~ bins, on its ring"} if paper_bins else None),
        "feasible_stiffness": (feasible_stiffness(config) if paper_bins and config.task.damage_rule == "crush_fraction"
                               else None),
        "distribution": dist,
        "distribution_seeds": f"{HELD_OUT_SEED} + seed * 1000003 + i" if dist else None,
        "stiffness_grid": [float(k) for k in grid],
        "stiffness_bin_edges": None if edges is None else [float(k) for k in edges],
        "episodes": args.episodes,
        "seed": args.seed,
        "episode_seeds": (f"the first objects of {GRID_SEED} + seed * 1000003 + j to fall in each bin" if drawn
                          else "seed * 1000003 + 1000 * grid_index + episode"),
        "config": config.to_dict(),
        "elapsed_s": elapsed,
    }
    atomic_write_text(out / "evaluation_summary.json", json.dumps(summary, indent=1, allow_nan=False) + "\n")
    print(f"wrote {out / 'evaluation.json'}, {out / 'evaluation_summary.json'}")
    if not args.no_plots:
        plot_success(rows, out / "success_vs_stiffness.png", config)
        plot_schedules(traces, out / "schedules.png", config)
        print(f"wrote {out / 'success_vs_stiffness.png'}, {out / 'schedules.png'}")
    n = n_ep + len(traces) + (args.objects * len(entries))
    print(f"{n} episodes in {elapsed:.1f} s")
    return 0
