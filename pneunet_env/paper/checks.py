"""The seed paper's qualitative statements, each measured on the figure data and marked ✓ or ✗.

Every check is a function of the figure tables (:func:`pneunet_env.paper.figures.generate`'s output, or the CSVs
read back with :func:`pneunet_env.paper.figures.load_tables`) that returns a :class:`CheckResult`: the
statement (quoted or paraphrased, with its section), the number(s) this package measures for it, whether
it holds in this model, and whether it is expected to (a statement the model contradicts is kept, marked ✗,
with the reason in its note). :func:`render_markdown` makes the statements table (docs/figures.md).

The statements are split by the paper's sections: :mod:`pneunet_env.paper.checks_grasp` (grasping, main section 3)
and :mod:`pneunet_env.paper.checks_design` (design, section 4 of the main text and of the supplement), with what
they share in :mod:`pneunet_env.paper.checks_common`; this module lists them in the table's order (:data:`CHECKS`),
runs them and renders the table; every check stays importable from here.

Operational definitions (all on the loading branch, exact path tangents from the ``dcurvature_dpressure``
column, pressure grid of the figures):

* **critical pressure** ``p~_c``: where ``d kappa~/dp~`` is largest (refined by a parabola through the grid
  maximum), see :func:`pneunet_env.paper.figures.critical_pressure`; if the path snaps (crosses a fold) it is the
  last pressure before the snap.
* **severity** of the balloon jump: that largest ``d kappa~/dp~``; ``inf`` when the path snaps.
* **saturation curvature**: ``kappa~`` at ``p~ = 1.2``, the end of the paper's axes.
* **initial slope** (the inverse of the actuator's small-pressure stiffness): ``d kappa~/dp~`` at ``p~ = 0``.
* **elasticity** of a quantity ``X``: ``d ln X / d ln p``; ``X`` is "held" (controlled) when it is at most
  :data:`pneunet_env.paper.figures.CONTROL_ELASTICITY`, "saturated" when at most :data:`SATURATED`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from pneunet_env.paper.checks_common import (
    OBJECT_CURVATURE_PER_M,
    OBJECT_THICKNESS_MM,
    SATURATED,
    SOFT_MAX,
    STIFF_MIN,
    CheckResult,
    Tables,
)
from pneunet_env.paper.checks_design import (
    check_base_little_change,
    check_compliance_mu,
    check_compliance_top,
    check_compliance_width,
    check_converged,
    check_linear_validity,
    check_pc_aspect,
    check_pc_mu,
    check_pc_side,
    check_pc_top,
    check_sat_aspect,
    check_sat_gent,
    check_sat_top,
    check_small_pressure_law,
    check_smooth_gent,
    check_smooth_gent_supp,
    check_smooth_side,
    check_smooth_top,
    check_snap_gent,
)
from pneunet_env.paper.checks_grasp import (
    check_after_give_in,
    check_free_balloon,
    check_give_in_pressure,
    check_materials,
    check_modulus_scaling,
    check_slaved_then_gives_in,
    check_snap_hysteresis,
    check_soft_follows_free,
    check_soft_force_saturates,
    check_stiff_force_monotone,
    check_stiff_position,
    check_switch,
)
from pneunet_env.paper.figures import FIGURES

__all__ = [
    "CHECKS", "CheckResult", "SATURATED", "render_markdown", "run_checks",
    # re-exported (importable from here as before the split)
    "OBJECT_CURVATURE_PER_M", "OBJECT_THICKNESS_MM", "SOFT_MAX", "STIFF_MIN", "Tables",
    "check_after_give_in", "check_base_little_change", "check_compliance_mu", "check_compliance_top",
    "check_compliance_width", "check_converged", "check_free_balloon", "check_give_in_pressure",
    "check_linear_validity", "check_materials", "check_modulus_scaling", "check_pc_aspect", "check_pc_mu",
    "check_pc_side", "check_pc_top", "check_sat_aspect", "check_sat_gent", "check_sat_top",
    "check_slaved_then_gives_in", "check_small_pressure_law", "check_smooth_gent", "check_smooth_gent_supp",
    "check_smooth_side", "check_smooth_top", "check_snap_gent", "check_snap_hysteresis", "check_soft_follows_free",
    "check_soft_force_saturates", "check_stiff_force_monotone", "check_stiff_position", "check_switch",
]


CHECKS: tuple[Callable[[Tables], CheckResult], ...] = (
    check_free_balloon,
    check_soft_follows_free,
    check_soft_force_saturates,
    check_stiff_position,
    check_stiff_force_monotone,
    check_slaved_then_gives_in,
    check_snap_hysteresis,
    check_after_give_in,
    check_give_in_pressure,
    check_switch,
    check_modulus_scaling,
    check_materials,
    check_pc_top,
    check_pc_side,
    check_pc_mu,
    check_pc_aspect,
    check_sat_gent,
    check_sat_aspect,
    check_sat_top,
    check_smooth_gent,
    check_snap_gent,
    check_smooth_top,
    check_smooth_side,
    check_smooth_gent_supp,
    check_compliance_top,
    check_compliance_mu,
    check_compliance_width,
    check_small_pressure_law,
    check_linear_validity,
    check_base_little_change,
    check_converged,
)
"""Every check, in the order of the statements table (docs/figures.md)."""


def run_checks(tables: Tables) -> list[CheckResult]:
    """Run :data:`CHECKS` on the figure tables (all of :data:`pneunet_env.paper.figures.FIGURES` are needed)."""
    missing = [n for n in FIGURES if n not in tables]
    if missing:
        raise ValueError(f"the checks need every figure's data; missing {missing}")
    return [check(tables) for check in CHECKS]


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render_markdown(results: Sequence[CheckResult]) -> str:
    """The statements table (docs/figures.md): statement (source), measured numbers, ✓/✗; notes as footnotes."""
    lines = [
        "| # | statement (source) | measured in this package | holds |",
        "|---|---|---|:-:|",
    ]
    notes = []
    for i, r in enumerate(results, 1):
        mark = r.mark
        if r.note:
            notes.append(f"{len(notes) + 1}. (#{i}) {r.note}")
            mark += f" [{len(notes)}]"
        if r.passed != r.expected:
            mark += " (unexpected)"
        lines.append(f"| {i} | {_cell(r.statement)} ({r.source}) | {_cell(r.measured)} | {mark} |")
    lines += ["", "How each row is decided:", ""]
    lines += [f"- #{i}: {r.criterion}" for i, r in enumerate(results, 1) if r.criterion]
    if notes:
        lines.append("")
        lines.append("Notes:")
        lines.append("")
        lines.extend(notes)
    return "\n".join(lines)
