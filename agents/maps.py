"""``pneunet-grasp map``: where the claim holds, charted over object Young's modulus x radius.

``pneunet-grasp map [--grid NE NR] [--episodes M] [--density RHO ...] [--failure-strain EPS] [--out DIR]
[--config PATH] [--set KEY=VALUE ...]``

Three policies face the same objects, side by side: the **oracle** (knows the object, picks the best constant
pressure; its successes are the *feasible window*), the **best blind schedule** (``best-ramp``: one linear pressure
ramp tuned on the default task) and the **rigid jaw** (``rigid``: a blind position-controlled jaw in
``RigidGrasp-v0``, tuned on the default task). Each cell of the map is one object, pinned through
``reset(seed=s, options={...})``:

* Young's modulus ``E`` log-spaced over ``--e-range`` (default 0.1 kPa to 5 MPa: up to the catalogue's stiffest
  apple, and down past the feasible window's soft edge, at 0.3 to 1 kPa at 1000 kg/m^3), shear modulus ``E/3``;
* outer radius ``R`` over ``--r-range`` (default 15 to 40 mm), curvature ``1000/R`` per m;
* compliant depth ``H = R/4`` (so ``H kappa_obj = 1/4`` everywhere and ``k~`` scales as ``E/R``);
* density ``--density`` (default 1000 kg/m^3), failure strain ``--failure-strain`` (default 0.3) and, objects
  being drawn from ranges, failure stress ``3 eps_f mu_obj`` (:func:`pneunet_env.task.object_thresholds`).

The environment is the default task's physics and damage rule (``hoop_strain``) with objects from ranges
(:func:`map_config`). ``--config PATH`` and ``--set KEY=VALUE`` (repeatable, VALUE is YAML) change it, e.g. for
another actuator (``--set top_thickness_mm=1.5 --set shear_modulus_kpa=30``): they apply on top of the map's
defaults, except the object keys the map pins (it draws objects from ranges spanning ``--r-range``). The blind
policies are built on the task they were tuned on, the default task, with the same ``--config`` and ``--set``
(:func:`task_config`): so their targets stay fractions of the config's ``max_pressure_kpa``, and a schedule shipped
beside the config file (``DIR/NAME.best_ramp.json``, ``DIR/NAME.best_rigid.json``) replaces the package's
(:func:`agents.policies.tuned_path`). The rigid jaw closes by that task's millimetres (its ``travel_mm`` is passed)
past that task's nominal object (R = 27.5 mm by default, ``--jaw-nominal-mm``; :func:`jaw_config`), so that it stops
where it was tuned to stop: a blind jaw meets every object at the same place. Every policy sees the same seeds
(``seed * 1000003 + 1000 * cell + episode``).

Drawn on every panel: the **regime boundary** ``phi = 1/2`` (:data:`PHI_DEFINITION`: ``phi``,
:func:`pneunet_env.physics.regimes.blocked_fraction` at ``p_max``, is the share of the curl the free finger would
make past the object's surface that the object blocks; force-controlled on the soft side, position-controlled on the
stiff side), the **feasible window** (the cells where the oracle succeeds) and the catalogue classes of the use case
the blind policies were tuned on (``E`` range x radius range; only locators: the map's objects have the thresholds
above, not each class's own). The figure and the printed summary say this in words, and name the damage rule.
Failing cells are marked ``d`` (damaged) or ``s`` (slipped). With more than one ``--density``, a second row charts
``E`` x density at one radius (``--density-radius``, default 25 mm; an error with one density): slip needs friction
to carry the weight ``rho g H``.

Writes ``DIR/map.json`` (:func:`success_map`'s result) and ``DIR/map.png`` (:func:`plot_map`; it needs matplotlib,
extra ``plot``, checked before any episode runs; ``--no-plot`` does without); prints a summary: each policy's
success inside the window, on its force-controlled and its position-controlled side.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from agents.plotting import plot_map  # the figure (re-exported: it lived here)
from pneunet_env import arguments as checks
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.files import atomic_write_text
from pneunet_env.progress import add_progress_argument
from pneunet_env.progress import progress as progress_bar

__all__ = ["ROLES", "map_config", "task_config", "object_options", "make_entries",
           "default_jaw_nominal_mm", "jaw_config", "blocked_fraction_grid", "success_map", "summarize", "plot_map",
           "phi_definition", "PHI_DEFINITION", "add_arguments", "run"]

RIGID_ENV = "RigidGrasp-v0"

ROLES = ("oracle", "best-ramp", "rigid")
"""The three policies of the map, by role (the keys of ``result["policies"]``), in panel order."""

THICKNESS_RATIO = 0.25
"""``H = R/4``: the compliant depth as a fraction of the radius."""

E_RANGE_KPA = (0.1, 5000.0)
DENSITY_RADIUS_MM = 25.0
R_RANGE_MM = (15.0, 40.0)
PHI_FINE = (64, 40)
"""The regime boundary is contoured on a finer grid than the episodes (E points, R points)."""


def phi_definition(pressure_kpa: float) -> str:
    """The regime boundary's terms in words (the figure's footnote, the summary's, ``map.json``'s
    ``regime_boundary``): what ``phi`` is (:func:`pneunet_env.physics.regimes.blocked_fraction`) and which side is
    which."""
    return (f"regime boundary: phi = 1/2, where phi (blocked_fraction) is the share of the curl the free finger would "
            f"make past the object's surface that the object blocks, loaded to {pressure_kpa:g} kPa; "
            "force-controlled on the soft side (phi < 1/2: the object gives way and the finger curls on into it), "
            "position-controlled on the stiff side (phi >= 1/2: the object holds the finger's curvature close to "
            "its own)")


PHI_DEFINITION = phi_definition(60.0)
"""The definition at the default maximum pressure."""


# ---------------------------------------------------------------------------------------------
# Objects, config, policies
# ---------------------------------------------------------------------------------------------


ConfigSource = EnvConfig | str | os.PathLike | None
"""What :func:`map_config` and :func:`task_config` start from: ``None`` (the defaults), a config, a YAML path."""


def map_config(config: ConfigSource = None, overrides: dict[str, Any] | None = None, *,
               radius_range_mm: tuple[float, float] = R_RANGE_MM,
               thickness_ratio: float = THICKNESS_RATIO) -> EnvConfig:
    """The default task's physics and damage rule, objects from ranges (pins override them); the curvature range
    spans the map's radii (default 15 to 40 mm), so that the rigid jaw's nominal object (its middle) is hand-scale,
    and the thickness range their ``H = thickness_ratio R``.

    ``config`` (a YAML path, a config) and then ``overrides`` (flat keys, :func:`load_config`'s) apply on top of the
    defaults: the actuator, the task (``max_pressure_kpa``, the damage rule, ...), the solver. The map's object keys
    stay the map's (``use_case`` and ``class_weights`` null, the curvature and thickness ranges above): every object
    is pinned, and a catalogue class would replace the pinned failure stress. ``ValueError`` names a missing file,
    an unknown key or a bad value.
    """
    r0, r1 = (float(r) for r in radius_range_mm)
    if not 0 < r0 <= r1:
        raise ValueError(f"the radius range needs 0 < LO <= HI, got {r0:g} {r1:g}")
    base = load_config(config, **(overrides or {}))
    return load_config(base, use_case=None, class_weights=None, object_curvature_per_m=[1e3 / r1, 1e3 / r0],
                       object_thickness_mm=[thickness_ratio * r0, thickness_ratio * r1])


def task_config(config: ConfigSource = None, overrides: dict[str, Any] | None = None) -> EnvConfig:
    """The task the blind policies were tuned on: the default task (objects from the catalogue), with ``config`` and
    ``overrides`` on top (as :func:`map_config`'s, here all of them, objects included)."""
    return load_config(config, **(overrides or {}))


def object_options(youngs_modulus_kpa: float, radius_mm: float, density_kg_m3: float = 1000.0,
                   failure_strain: float = 0.3, thickness_ratio: float = THICKNESS_RATIO) -> dict[str, float]:
    """The ``reset`` pins of one object: ``mu = E/3``, ``kappa = 1000/R``, ``H = thickness_ratio R``."""
    return {
        "object_shear_modulus_kpa": float(youngs_modulus_kpa) / 3.0,
        "object_curvature_per_m": 1000.0 / float(radius_mm),
        "object_thickness_mm": thickness_ratio * float(radius_mm),
        "object_density_kg_m3": float(density_kg_m3),
        "object_failure_strain": float(failure_strain),
    }


def make_entries(config: EnvConfig, blind: str = "best-ramp", rigid: str = "rigid",
                 task: EnvConfig | None = None, config_path: str | os.PathLike | None = None) -> dict[str, Any]:
    """``{role: PolicyEntry}``: the oracle on ``config``; the blind ramp and the rigid jaw on ``task``, the task they
    were tuned on (default: the default task, :func:`task_config`), so their targets are fractions of its scales.

    A ``rigid`` spec without ``travel_mm`` gets the task's jaw travel, so that the jaw closes by the same
    millimetres it was tuned to (the map's config would otherwise give another travel); run it on
    :func:`jaw_config`'s env so that it also stops at the same place. ``config_path``: the YAML file the configs
    came from; a schedule shipped beside it wins (:func:`agents.policies.tuned_path`).
    """
    from agents.policies import make_policy, parse_spec
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    task = load_config() if task is None else task
    name, params = parse_spec(rigid)
    if name == "rigid" and "travel_mm" not in params:
        rigid = f"{rigid}{',' if ':' in rigid else ':'}travel_mm={default_jaw_travel_mm(task):g}"
    return {"oracle": make_policy("oracle", config),
            "best-ramp": make_policy(blind, task, config_path=config_path),
            "rigid": make_policy(rigid, task, config_path=config_path)}


def default_jaw_nominal_mm(task: EnvConfig | None = None) -> float:
    """The radius of the nominal object of ``task`` (default: the default task's, 27.5 mm): the surface the tuned
    jaw's closure counts from."""
    from pneunet_env.envs.rigid import _nominal_curvature_per_m

    return 1e3 / _nominal_curvature_per_m(load_config() if task is None else task)


def jaw_config(config: EnvConfig, nominal_radius_mm: float | None = None, task: EnvConfig | None = None) -> EnvConfig:
    """``config`` with its curvature range collapsed onto the jaw's nominal object (default: ``task``'s,
    :func:`default_jaw_nominal_mm`). ``RigidGrasp-v0`` stops the jaw ``c`` mm inside the middle of the config's
    curvature range; the objects themselves are pinned, so the range changes nothing else."""
    r = default_jaw_nominal_mm(task) if nominal_radius_mm is None else float(nominal_radius_mm)
    if not r > 0:
        raise ValueError(f"the jaw's nominal radius must be > 0, got {nominal_radius_mm!r}")
    return load_config(config, object_curvature_per_m=[1e3 / r, 1e3 / r])


def blocked_fraction_grid(youngs_modulus_kpa, radius_mm, config: EnvConfig,
                          thickness_ratio: float = THICKNESS_RATIO) -> np.ndarray:
    """``phi`` (:func:`pneunet_env.physics.regimes.blocked_fraction`, at ``p_max``) on the grid, shape ``(nR, nE)``."""
    from pneunet_env.physics.contact import winkler_stiffness
    from pneunet_env.physics.regimes import blocked_fraction

    a = config.actuator
    E, R = np.meshgrid(np.asarray(youngs_modulus_kpa, float), np.asarray(radius_mm, float))
    kappa = 1000.0 / R
    k = winkler_stiffness(E / 3.0, thickness_ratio * R, kappa, a.width_mm, a.shear_modulus_kpa)
    return blocked_fraction(k, 1e-3 * a.width_mm * kappa, config.pressure_max, config.actuator_params, config.solver)


def _episode_seed(seed: int, cell: int, episode: int) -> int:
    return seed * 1_000_003 + 1000 * cell + episode


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------


def _run_cells(envs, entries, cells, episodes: int, seed: int, cell_offset: int, bar) -> dict[str, dict]:
    """Rates per role over ``cells`` (a list of reset options): ``{role: {success, damage, slip, failures}}``."""
    from agents.evaluate import run_episode

    out = {}
    for role, entry in entries.items():
        env = envs[role]
        rates = np.zeros((3, len(cells)))
        failed = 0
        for c, options in enumerate(cells):
            for e in range(episodes):
                r = run_episode(env, entry.policy, _episode_seed(seed, cell_offset + c, e), options)
                rates[:, c] += (r["success"], r["damaged"], r["dropped"])
                failed += int(r["solver_failed"])
                bar.update()
        rates /= episodes
        out[role] = {"success": rates[0], "damage": rates[1], "slip": rates[2], "solver_failures": failed}
    return out


def _grid_lists(a: np.ndarray) -> list:
    """A float array as nested lists, NaN as ``None`` (valid JSON)."""
    return [[None if not math.isfinite(x) else float(x) for x in row] for row in np.atleast_2d(a)]


def _catalogue_boxes(task: EnvConfig | None = None) -> list[dict[str, Any]]:
    """The class boxes of the catalogue classes ``task`` draws (default: the default use case's); none where its
    objects come from ranges (the paper's 250 mm ring lies off the map)."""
    from pneunet_env.catalogue import load_catalogue, use_case_weights

    if task is not None and not task.objects.from_catalogue:
        return []
    classes = load_catalogue()
    weights = use_case_weights() if task is None else dict(task.objects.class_items)
    return [{"name": n, "weight": w, "youngs_modulus_kpa": list(classes[n].youngs_modulus_kpa),
             "radius_mm": list(classes[n].radius_mm), "thickness_mm": list(classes[n].thickness_mm),
             "density_kg_m3": list(classes[n].density_kg_m3), "failure_strain": list(classes[n].failure_strain)}
            for n, w in weights.items() if w > 0]


def success_map(E_grid, R_grid, density_kg_m3: float = 1000.0, failure_strain: float = 0.3, episodes: int = 1,
                seed: int = 0, progress: bool | None = None, densities=None, density_radius_mm: float = 25.0,
                blind: str = "best-ramp", rigid: str = "rigid", config: EnvConfig | None = None,
                thickness_ratio: float = THICKNESS_RATIO, jaw_nominal_mm: float | None = None,
                task: EnvConfig | None = None, config_path: str | os.PathLike | None = None) -> dict[str, Any]:
    """Grasp success of the oracle, the blind ramp and the rigid jaw over ``E_grid`` (kPa) x ``R_grid`` (mm).

    Args:
        E_grid, R_grid: Young's moduli (kPa) and radii (mm) of the cells.
        density_kg_m3, failure_strain: the objects' (the same everywhere).
        episodes: episodes per policy and cell; seed: the base seed (shared by every policy).
        progress: a bar on stderr (``None``: when stderr is a terminal).
        densities: if given (two or more), also a row over ``E_grid`` x ``densities`` at ``density_radius_mm``.
        blind, rigid: the specs of the blind ramp and the jaw (:func:`agents.policies.make_policy`).
        config: the env's config (default :func:`map_config`).
        jaw_nominal_mm: the radius the rigid jaw's closure counts from (default: ``task``'s nominal object; the
            default task's is 27.5 mm).
        task: the config the blind policies were tuned on (default: the default task; :func:`make_entries`).
        config_path: the YAML file the configs came from: a schedule shipped beside it wins.

    Returns a JSON-able dict: ``youngs_modulus_kpa``, ``radius_mm`` (the grids); ``policies`` ``{role: {spec,
    label, env_id, blind, success, damage, slip, solver_failures}}`` with ``(nR, nE)`` rate arrays as nested lists;
    ``phi`` on the cells, ``phi_fine`` (a finer grid for the contour), ``window`` (the oracle's successes, as 0/1),
    ``summary`` (:func:`summarize`), ``catalogue`` (the class boxes of the task the blind policies were tuned on),
    ``density_row`` (or ``None``), the settings (``damage``, ``regime_boundary`` and ``task`` in words) and the
    config.
    """
    if int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    E = np.asarray(E_grid, dtype=float)
    R = np.asarray(R_grid, dtype=float)
    if E.ndim != 1 or R.ndim != 1 or E.size < 1 or R.size < 1 or (E <= 0).any() or (R <= 0).any():
        raise ValueError("E_grid and R_grid must be non-empty 1-d sequences of positive numbers")
    dens = sorted(float(d) for d in densities) if densities is not None and len(densities) > 1 else None
    config = map_config() if config is None else config
    task_cfg = load_config() if task is None else task
    from agents.evaluate import damage_rule_text, task_description

    t0 = time.perf_counter()
    entries = make_entries(config, blind, rigid, task, config_path)
    rigid_config = jaw_config(config, jaw_nominal_mm, task)
    envs = {role: entry.make_env(rigid_config if entry.env_id == RIGID_ENV else config)
            for role, entry in entries.items()}
    cells = [object_options(e, r, density_kg_m3, failure_strain, thickness_ratio) for r in R for e in E]
    row_cells = [] if dens is None else [object_options(e, density_radius_mm, d, failure_strain, thickness_ratio)
                                         for d in dens for e in E]
    bar = progress_bar(total=len(entries) * (len(cells) + len(row_cells)) * episodes, desc="map", unit="episode",
                       enabled=progress)
    try:
        rates = _run_cells(envs, entries, cells, episodes, seed, 0, bar)
        row_rates = _run_cells(envs, entries, row_cells, episodes, seed, len(cells), bar) if dens else None
    finally:
        bar.close()
        for env in envs.values():
            env.close()
    shape = (R.size, E.size)
    phi = blocked_fraction_grid(E, R, config, thickness_ratio)
    fine_E = np.logspace(math.log10(E.min()), math.log10(E.max()), PHI_FINE[0]) if E.size > 1 else E
    fine_R = np.linspace(R.min(), R.max(), PHI_FINE[1]) if R.size > 1 else R
    phi_fine = blocked_fraction_grid(fine_E, fine_R, config, thickness_ratio)

    def policies(rs, shp):
        return {role: {"spec": entries[role].name, "label": entries[role].label, "env_id": entries[role].env_id,
                       "blind": entries[role].blind, "solver_failures": rs[role]["solver_failures"],
                       **{k: _grid_lists(rs[role][k].reshape(shp)) for k in ("success", "damage", "slip")}}
                for role in entries}

    result: dict[str, Any] = {
        "youngs_modulus_kpa": E.tolist(),
        "radius_mm": R.tolist(),
        "thickness_rule": (f"H = R/{1 / thickness_ratio:g}" if (1 / thickness_ratio).is_integer()
                           else f"H = {thickness_ratio:g} R"),
        "thickness_ratio": float(thickness_ratio),
        "density_kg_m3": float(density_kg_m3),
        "failure_strain": float(failure_strain),
        "failure_stress_rule": "3 eps_f mu_obj (objects from ranges)",
        "damage_rule": config.task.damage_rule,
        "damage": damage_rule_text(config),
        "regime_boundary": phi_definition(config.task.max_pressure_kpa),
        "task": task_description(task_cfg),
        "episodes": int(episodes),
        "seed": int(seed),
        "episode_seeds": "seed * 1000003 + 1000 * cell + episode, cell = i_R * n_E + i_E (density row: after them)",
        "roles": list(entries),
        "policies": policies(rates, shape),
        "phi": _grid_lists(phi),
        "phi_fine": {"youngs_modulus_kpa": fine_E.tolist(), "radius_mm": fine_R.tolist(), "phi": _grid_lists(phi_fine)},
        "regime_pressure_kpa": config.task.max_pressure_kpa,
        "jaw_nominal_radius_mm": 1e3 / rigid_config.objects.object_curvature_per_m[0],
        "window": _grid_lists((rates["oracle"]["success"].reshape(shape) >= 0.5).astype(float)),
        "catalogue": _catalogue_boxes(task_cfg),
        "density_row": None,
    }
    if dens:
        phi_row = blocked_fraction_grid(fine_E, [density_radius_mm], config, thickness_ratio)[0]
        result["density_row"] = {
            "radius_mm": float(density_radius_mm),
            "density_kg_m3": dens,
            "policies": policies(row_rates, (len(dens), E.size)),
            "phi_fine": {"youngs_modulus_kpa": fine_E.tolist(), "phi": [None if not math.isfinite(x) else float(x)
                                                                       for x in phi_row]},
        }
    result["summary"] = summarize(result)
    result["elapsed_s"] = time.perf_counter() - t0
    result["config"] = config.to_dict()
    result["config_path"] = None if config_path is None else str(config_path)
    return result


def _arr(x) -> np.ndarray:
    return np.array([[np.nan if v is None else v for v in row] for row in x], dtype=float)


def summarize(result: dict[str, Any]) -> dict[str, Any]:
    """Per role: success over all cells; inside the window (the oracle's successes), over its force-controlled
    (``phi < 1/2``) and position-controlled sides; failure modes outside the window; per radius, the ``E`` range
    that succeeds. ``grasps_both``: succeeds (rate >= 1/2) on some cell of each side of the boundary."""
    E = np.asarray(result["youngs_modulus_kpa"])
    phi = _arr(result["phi"])
    window = _arr(result["window"]) > 0.5
    force = phi < 0.5
    out: dict[str, Any] = {"cells": int(phi.size), "window_cells": int(window.sum()),
                           "window_force_cells": int((window & force).sum()),
                           "window_position_cells": int((window & ~force).sum())}

    def mean(a, m):
        return float(a[m].mean()) if m.any() else None

    for role in result["roles"]:
        p = result["policies"][role]
        s, d, sl = _arr(p["success"]), _arr(p["damage"]), _arr(p["slip"])
        ok = s >= 0.5
        out[role] = {
            "success": mean(s, np.ones_like(ok)),
            "success_in_window": mean(s, window),
            "success_in_window_force": mean(s, window & force),
            "success_in_window_position": mean(s, window & ~force),
            "success_outside_window": mean(s, ~window),
            "damage_outside_window": mean(d, ~window),
            "slip_outside_window": mean(sl, ~window),
            "grasps_both": bool((ok & force).any() and (ok & ~force).any()),
            "e_range_kpa_by_radius": [[float(E[row].min()), float(E[row].max())] if row.any() else None
                                      for row in ok],
        }
    return out


def _pct(x) -> str:
    return "-" if x is None else f"{x:.0%}"


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=checks.output_dir, default="map",
                        help="output folder: map.json, map.png (default ./map); checked before the first episode, "
                             "files in it are replaced")
    parser.add_argument("--grid", type=checks.integer(1, 1000), nargs=2, default=[19, 11], metavar=("NE", "NR"),
                        help="cells: NE log-spaced moduli x NR radii (default 19 11: about 4 per decade, 2.5 mm)")
    parser.add_argument("--e-range", type=checks.positive, nargs=2, default=list(E_RANGE_KPA), metavar=("LO", "HI"),
                        help="Young's modulus range, kPa (default 0.1 5000)")
    parser.add_argument("--r-range", type=checks.positive, nargs=2, default=list(R_RANGE_MM), metavar=("LO", "HI"),
                        help="radius range, mm (default 15 40); H = R/4")
    parser.add_argument("--episodes", type=checks.count, default=1, help="episodes per policy and cell (default 1)")
    parser.add_argument("--seed", type=checks.seed, default=0, help="base seed, shared by every policy (default 0)")
    parser.add_argument("--density", type=checks.positive, nargs="+", default=[1000.0, 300.0, 30.0], metavar="RHO",
                        help="object density, kg/m^3: the first is the map's; with more, a second row charts "
                             "E x density at --density-radius (default 1000 300 30)")
    parser.add_argument("--density-radius", type=checks.positive, default=None,
                        help=f"radius of the density row, mm (default {DENSITY_RADIUS_MM:g}; needs two or more "
                             "--density)")
    parser.add_argument("--failure-strain", type=checks.positive, default=0.3,
                        help="object failure strain (default 0.3); failure stress 3 eps_f mu_obj")
    parser.add_argument("--blind", default="best-ramp", metavar="SPEC",
                        help="the blind pressure schedule (default best-ramp: agents/best_ramp.json, or the one "
                             "beside --config)")
    parser.add_argument("--rigid", default="rigid", metavar="SPEC",
                        help="the rigid jaw (default rigid: agents/best_rigid.json, or the one beside --config; at "
                             "the task's travel)")
    parser.add_argument("--jaw-nominal-mm", type=checks.positive, default=None, metavar="R",
                        help="radius the rigid jaw's closure counts from (default: the default task's nominal "
                             "object, 27.5 mm)")
    parser.add_argument("--config", default=None, metavar="PATH",
                        help="environment config YAML, on top of the map's defaults (the objects stay the map's); "
                             "best-ramp and rigid load DIR/NAME.best_ramp.json and DIR/NAME.best_rigid.json where "
                             "they lie beside DIR/NAME.yaml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key, on top of --config (repeatable; VALUE is YAML), "
                             "e.g. --set top_thickness_mm=1.5; a schedule beside --config still applies")
    parser.add_argument("--no-plot", action="store_true", help="skip map.png (and matplotlib)")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    from agents.evaluate import parse_overrides, usage_error
    from pneunet_env.extras import require_extra

    if args.density_radius is not None and len(args.density) < 2:
        usage_error("pneunet-grasp map", "--density-radius places the density row, which needs two or more --density "
                                         "values (e.g. --density 1000 300 30)")
    density_radius = DENSITY_RADIUS_MM if args.density_radius is None else args.density_radius
    if not args.no_plot:  # before any episode: not a traceback once the work is done
        require_extra("map", "matplotlib", "plot", "map.png", skip="--no-plot")
    ne, nr = args.grid
    try:
        if ne < 1 or nr < 1:
            raise ValueError(f"--grid needs NE, NR >= 1, got {ne} {nr}")
        if ne * nr * args.episodes > checks.MAX_COUNT:
            raise ValueError(f"--grid {ne} {nr} x --episodes {args.episodes} is {ne * nr * args.episodes} episodes "
                             f"per policy; at most {checks.MAX_COUNT}")
        (e0, e1), (r0, r1) = args.e_range, args.r_range
        if not 0 < e0 <= e1 or not 0 < r0 <= r1:
            raise ValueError("--e-range and --r-range need 0 < LO <= HI")
        if any(d <= 0 for d in args.density) or not args.failure_strain > 0:
            raise ValueError("--density and --failure-strain must be > 0")
        overrides = parse_overrides(args.overrides)
        config = map_config(args.config, overrides, radius_range_mm=(r0, r1))
        task = task_config(args.config, overrides)
        E = np.logspace(math.log10(e0), math.log10(e1), ne) if ne > 1 else np.array([math.sqrt(e0 * e1)])
        R = np.linspace(r0, r1, nr) if nr > 1 else np.array([0.5 * (r0 + r1)])
        result = success_map(E, R, args.density[0], args.failure_strain, args.episodes, args.seed, args.progress,
                             densities=args.density, density_radius_mm=density_radius, blind=args.blind,
                             rigid=args.rigid, config=config, jaw_nominal_mm=args.jaw_nominal_mm, task=task,
                             config_path=args.config)
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp map: {exc}") from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "map.json", json.dumps(result, indent=1, allow_nan=False) + "\n")
    written = [out / "map.json"]
    if not args.no_plot:
        written.append(plot_map(result, out / "map.png"))
    print(_report(result))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _report(result: dict[str, Any]) -> str:
    s = result["summary"]
    E, R = result["youngs_modulus_kpa"], result["radius_mm"]
    n_ep = len(result["roles"]) * s["cells"] * result["episodes"]
    if result["density_row"]:
        n_ep += len(result["roles"]) * len(result["density_row"]["density_kg_m3"]) * len(E) * result["episodes"]
    lines = [f"pneunet-grasp map: E {E[0]:g}-{E[-1]:g} kPa x R {R[0]:g}-{R[-1]:g} mm ({len(E)} x {len(R)} cells, "
             f"{result['thickness_rule']}, rho = {result['density_kg_m3']:g} kg/m^3, "
             f"eps_f = {result['failure_strain']:g}), "
             f"{n_ep} episodes in {result['elapsed_s']:.1f} s",
             f"  {result.get('damage', result['damage_rule'] + ' rule')}",
             f"  blind policies tuned on {result.get('task', 'the default task')}",
             f"  {result.get('regime_boundary') or phi_definition(result['regime_pressure_kpa'])}",
             "  columns: all = every cell; window = the cells where the oracle succeeds; force, position = the "
             "window's cells on the force- and position-controlled sides of the boundary; grasps both = succeeds on "
             "some cell of each side",
             f"feasible window (oracle succeeds): {s['window_cells']} of {s['cells']} cells "
             f"({s['window_force_cells']} force-controlled, {s['window_position_cells']} position-controlled)",
             f"  {'policy':<10} {'all':>5} {'window':>7} {'force':>6} {'position':>8} {'grasps both':>12}  label"]
    for role in result["roles"]:
        r = s[role]
        lines.append(f"  {role:<10} {_pct(r['success']):>5} {_pct(r['success_in_window']):>7} "
                     f"{_pct(r['success_in_window_force']):>6} {_pct(r['success_in_window_position']):>8} "
                     f"{'yes' if r['grasps_both'] else 'no':>12}  {result['policies'][role]['label']}")
    if result["density_row"]:
        row = result["density_row"]
        lines.append(f"density row at R = {row['radius_mm']:g} mm (success over E, per density):")
        for role in result["roles"]:
            rates = _arr(row["policies"][role]["success"])
            lines.append(f"  {role:<10} " + ", ".join(f"{d:g} kg/m^3: {np.nanmean(rates[i]):.0%}"
                                                      for i, d in enumerate(row["density_kg_m3"])))
    return "\n".join(lines)
