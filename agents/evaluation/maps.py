"""The success map over object Young's modulus x radius (:func:`success_map`): the oracle, the best blind ramp and
the rigid jaw on the same pinned objects, with the regime boundary. The command, and what the map shows, are
described in :mod:`agents.evaluation.map_cli`.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

import numpy as np

from agents.common.map_record import summarize
from agents.common.words import phi_definition
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.progress import progress as progress_bar

__all__ = ["RIGID_ENV", "ROLES", "THICKNESS_RATIO", "E_RANGE_KPA", "DENSITY_RADIUS_MM", "R_RANGE_MM", "PHI_FINE",
           "map_config", "task_config", "object_options", "make_entries", "default_jaw_nominal_mm", "jaw_config",
           "blocked_fraction_grid", "success_map"]


RIGID_ENV = "RigidGrasp-v1"


ROLES = ("oracle", "best-ramp", "rigid")
"""The three policies of the map, by role (the keys of ``result["policies"]``), in panel order."""


THICKNESS_RATIO = 0.25
"""``H = R/4``: the compliant depth as a fraction of the radius."""


E_RANGE_KPA = (0.1, 5000.0)


DENSITY_RADIUS_MM = 25.0


R_RANGE_MM = (15.0, 40.0)


PHI_FINE = (64, 40)
"""The regime boundary is contoured on a finer grid than the episodes (E points, R points)."""


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
    came from; a schedule shipped beside it wins (:func:`agents.policies.registry.tuned_path`).
    """
    from agents.policies.registry import make_policy, parse_spec
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
    :func:`default_jaw_nominal_mm`). ``RigidGrasp-v1`` stops the jaw ``c`` mm inside the middle of the config's
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


def _run_cells(envs, entries, cells, episodes: int, seed: int, cell_offset: int, bar) -> dict[str, dict]:
    """Rates per role over ``cells`` (a list of reset options): ``{role: {success, damage, slip, failures}}``."""
    from agents.evaluation.episodes import run_episode

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
    classes = load_catalogue(None if task is None else task.objects.catalogue)
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
        blind, rigid: the specs of the blind ramp and the jaw (:func:`agents.policies.registry.make_policy`).
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
    from agents.common.words import damage_rule_text, task_description

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
