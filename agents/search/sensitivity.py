"""The threshold sensitivity study (``pneunet-grasp search --sensitivity``): for each setting of the thresholds
that decide the soft side (:data:`SENSITIVITY_SETTINGS`), a fresh best-ramp and rigid search, then the
best-ramp, the oracle and the rigid gripper on a stiffness grid (:func:`sensitivity_study`). A study of the
paper's task, not the environment's defaults.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from agents.common.words import _pct, damage_rule_text, task_description
from agents.figures.search import plot_sensitivity
from agents.policies.scripted import LinearRamp
from agents.search.ramp import search_ramp
from pneunet_env import PAPER_TASK
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.files import atomic_write_json, atomic_write_text, deferred_interrupt

__all__ = ["strain_crush_fraction", "SENSITIVITY_SETTINGS", "sensitivity_study", "sensitivity_table"]


def strain_crush_fraction(config: EnvConfig | None = None) -> float:
    """The ``crush_fraction`` that makes ``delta > crush_fraction H`` the hoop-strain rule ``delta kappa_obj > eps_f``.

    Eq. 3.2's object is a thin ring; its indentation is a radial shrink of the whole ring, whose hoop strain is
    ``delta kappa_obj``. At the middle of the config's ranges: ``eps_f / (H kappa_obj)`` (7.5 at the paper's
    object: 0.3 / (10 mm x 4 /m)).
    """
    c = load_config(**PAPER_TASK) if config is None else config  # the paper task's ranges
    mid = lambda r: 0.5 * (r[0] + r[1])  # noqa: E731
    o = c.objects
    return mid(o.object_failure_strain) / (mid(o.object_thickness_mm) * 1e-3 * mid(o.object_curvature_per_m))


_STRAIN = strain_crush_fraction()


SENSITIVITY_SETTINGS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("default", "default: rho 1000 kg/m^3, mu_f 0.5, crushed at delta > H", {}),
    ("rho100", "dense foam: rho 100", {"object_density_kg_m3": 100.0}),
    ("rho30", "light foam: rho 30", {"object_density_kg_m3": 30.0}),
    ("muf1", "dry silicone friction: mu_f 1.0", {"friction_coefficient": 1.0}),
    ("strain", f"hoop-strain crush: delta kappa_obj > 0.3 (crush_fraction {_STRAIN:g})",
     {"crush_fraction": _STRAIN}),
    ("rho100+strain", "rho 100 + hoop-strain crush", {"object_density_kg_m3": 100.0, "crush_fraction": _STRAIN}),
    ("rho30+strain", "rho 30 + hoop-strain crush", {"object_density_kg_m3": 30.0, "crush_fraction": _STRAIN}),
    ("rhomix+strain", "rho 30-1000 (log-uniform) + hoop-strain crush",
     {"object_density_kg_m3": [30.0, 1000.0], "crush_fraction": _STRAIN}),
    ("rho30+strain+size", "rho 30 + hoop-strain crush + object size +-10 % (kappa_obj 3.6-4.4 /m)",
     {"object_density_kg_m3": 30.0, "crush_fraction": _STRAIN, "object_curvature_per_m": [3.6, 4.4]}),
)
"""``(key, description, config overrides)``: the threshold settings of the sensitivity study."""


def sensitivity_study(out: Path, settings=SENSITIVITY_SETTINGS, n_objects: int = 120, grid: int = 25,
                      episodes: int = 1, seed: int = 0, progress: bool | None = None,
                      log: Callable[[str], Any] = print) -> list[dict[str, Any]]:
    """For each setting: search best-ramp and rigid, evaluate them and the oracle on a grid; write the outputs.

    Settings whose object properties are ranges get ``max(episodes, 4)`` episodes per grid point.
    """
    from agents.common.regimes import SOFT_MAX, STIFF_MIN
    from agents.evaluation.evaluate import evaluate_policies
    from agents.evaluation.objects import stiffness_grid
    from agents.evaluation.summaries import regime_summary
    from agents.policies.oracle import Oracle, feasible_stiffness
    from agents.policies.registry import PolicyEntry
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    coarse = tuple(round(0.05 * i, 4) for i in range(1, 21))
    durations = (1, 25, 50)
    results = []
    paper = load_config(None, **PAPER_TASK)
    log(f"the threshold sensitivity study of the paper's task ({task_description(paper)}; by default "
        f"{damage_rule_text(paper)}); success on the paper's k~ bins, soft (k~ < {SOFT_MAX:g}) and stiff "
        f"(k~ >= {STIFF_MIN:g}), per setting:")
    for key, desc, overrides in settings:
        t0 = time.perf_counter()
        config = load_config(None, **{**PAPER_TASK, **overrides})  # a study of the paper's task
        best_p, _ = search_ramp(config, "pneunet", n_objects, seed, coarse, durations, 0.01, progress)
        best_r, _ = search_ramp(config, "rigid", n_objects, seed, coarse, durations, 0.01, progress)
        travel = default_jaw_travel_mm(config)
        entries = [
            PolicyEntry("best-ramp", f"best-ramp ({best_p.target * config.task.max_pressure_kpa:.3g} kPa, "
                        f"{best_p.n_steps} steps)", LinearRamp(best_p.target, best_p.n_steps, config)),
            PolicyEntry("oracle", "oracle", Oracle(config), blind=False),
            PolicyEntry("rigid", f"rigid ({best_r.target * travel:.3g} mm, {best_r.n_steps} steps)",
                        LinearRamp(best_r.target, best_r.n_steps, config), env_id="RigidGrasp-v1", command="jaw"),
        ]
        ranged = any(isinstance(v, list) for v in overrides.values())
        ks = stiffness_grid(config, grid)
        rows = evaluate_policies(entries, config, ks, max(episodes, 4) if ranged else episodes, seed, progress)
        reg = regime_summary(rows)
        res = {
            "key": key, "description": desc, "overrides": overrides,
            "feasible_stiffness": feasible_stiffness(config),
            "best_ramp": {"target_kpa": best_p.target * config.task.max_pressure_kpa, "n_steps": best_p.n_steps,
                          "search_success_rate": best_p.success_rate},
            "rigid": {"target_mm": best_r.target * travel, "n_steps": best_r.n_steps,
                      "search_success_rate": best_r.success_rate, "jaw_travel_mm": travel},
            "regimes": reg, "rows": rows, "elapsed_s": time.perf_counter() - t0,
        }
        results.append(res)
        rate = lambda p, g: _pct(reg[p][g]["success_rate"])  # noqa: E731, B023
        log(f"{key:>18}: best-ramp {res['best_ramp']['target_kpa']:5.1f} kPa soft {rate('best-ramp', 'soft')} stiff "
            f"{rate('best-ramp', 'stiff')} | oracle soft {rate('oracle', 'soft')} stiff {rate('oracle', 'stiff')} | "
            f"rigid {res['rigid']['target_mm']:5.1f} mm soft {rate('rigid', 'soft')} stiff {rate('rigid', 'stiff')}"
            f"  ({res['elapsed_s']:.0f} s)")
    out.mkdir(parents=True, exist_ok=True)
    meta = {"note": "a sensitivity study of the damage/slip thresholds; NOT the environment's defaults",
            "objects_per_search": n_objects, "stiffness_grid": grid, "episodes": episodes, "seed": seed}
    with deferred_interrupt():
        atomic_write_json(out / "sensitivity.json", {"meta": meta, "settings": results})
        atomic_write_text(out / "sensitivity.md", sensitivity_table(results))
    plot_sensitivity(results, out / "sensitivity.png")
    return results


def sensitivity_table(results) -> str:
    """A markdown table: per setting, success on soft / stiff objects for best-ramp, oracle and rigid."""
    lines = [
        "| setting | feasible from k~ | best-ramp | best-ramp soft / stiff | oracle soft / stiff | rigid | "
        "rigid soft / stiff |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        reg = r["regimes"]
        pct = lambda p, g: _pct(reg[p][g]["success_rate"]).strip()  # noqa: E731, B023
        lines.append(
            f"| {r['description']} | {r['feasible_stiffness']:.2g} | {r['best_ramp']['target_kpa']:.3g} kPa, "
            f"{r['best_ramp']['n_steps']} steps | {pct('best-ramp', 'soft')} / {pct('best-ramp', 'stiff')} | "
            f"{pct('oracle', 'soft')} / {pct('oracle', 'stiff')} | {r['rigid']['target_mm']:.3g} mm | "
            f"{pct('rigid', 'soft')} / {pct('rigid', 'stiff')} |"
        )
    return "\n".join(lines) + "\n"
