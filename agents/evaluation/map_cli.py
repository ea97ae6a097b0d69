"""``pneunet-grasp map``: where the claim holds, charted over object Young's modulus x radius.

``pneunet-grasp map [--grid NE NR] [--episodes M] [--density RHO ...] [--failure-strain EPS] [--out DIR]
[--config PATH] [--set KEY=VALUE ...]``

Three policies face the same objects, side by side: the **oracle** (knows the object, picks the best constant
pressure; its successes are the *feasible window*), the **best blind schedule** (``best-ramp``: one linear pressure
ramp tuned on the default task) and the **rigid jaw** (``rigid``: a blind position-controlled jaw in
``RigidGrasp-v1``, tuned on the default task). Each cell of the map is one object, pinned through
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
(:func:`agents.policies.registry.tuned_path`). The rigid jaw closes by that task's millimetres (its ``travel_mm`` is
passed) past that task's nominal object (R = 27.5 mm by default, ``--jaw-nominal-mm``; :func:`jaw_config`), so that it
stops where it was tuned to stop: a blind jaw meets every object at the same place. Every policy sees the same seeds
(``seed * 1000003 + 1000 * cell + episode``).

Drawn on every panel: the **regime boundary** ``phi = 1/2`` (:data:`PHI_DEFINITION`: ``phi``,
:func:`pneunet_env.physics.regimes.blocked_fraction` at ``p_max``, is the share of the curl the free finger would
make past the object's surface that the object blocks; force-controlled on the soft side, position-controlled on the
stiff side), the **feasible window** (the cells where the oracle succeeds) and the catalogue classes of the use case
the blind policies were tuned on (``E`` range x radius range; only locators: the map's objects have the thresholds
above, not each class's own). The figure and the printed summary say this in words, and name the damage rule.
Failing cells are marked ``d`` (damaged) or ``s`` (slipped). With more than one ``--density``, a second row charts
``E`` x density at one radius (``--density-radius``, default 25 mm; an error with one density): slip needs friction
to carry the weight (the config's ``hold_rule``).

Writes ``DIR/map.json`` (:func:`success_map`'s result) and ``DIR/map.png`` (:func:`plot_map`; it needs matplotlib,
extra ``plot``, checked before any episode runs; ``--no-plot`` does without); prints a summary: each policy's
success inside the window, on its force-controlled and its position-controlled side.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.map_record import _arr, _pct
from agents.common.words import phi_definition
from agents.evaluation.maps import (
    DENSITY_RADIUS_MM,
    E_RANGE_KPA,
    R_RANGE_MM,
    map_config,
    success_map,
    task_config,
)
from agents.figures.maps import plot_map
from pneunet_env import arguments as checks
from pneunet_env.files import atomic_write_text
from pneunet_env.progress import add_progress_argument

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from agents.common.cli import add_catalogue

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
    add_catalogue(parser)
    parser.add_argument("--no-plot", action="store_true", help="skip map.png (and matplotlib)")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    from agents.common.cli import parse_overrides, usage_error
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
        overrides = parse_overrides(args.overrides, args.catalogue)
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
