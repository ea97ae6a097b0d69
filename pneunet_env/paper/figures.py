"""The seed paper's figures: computed as tables (CSV) and drawn (PNG).

Every figure is computed, not drawn by hand: quasi-static pressure sweeps with
:func:`pneunet_env.physics.solver.load_path` (loading from rest to ``p~ = 1.2``, the end of the paper's axes, then
unloading back to 0 on the same grid), plus the closed-form quadratic model of
:mod:`pneunet_env.physics.linear` for supplement Fig. 3.

=================  ==========================================================================================
file               content
=================  ==========================================================================================
``fig2``           main-text Fig. 2a,b: curvature and contact force against pressure, five object stiffnesses
                   and the free actuator (``J = 15``, ``w kappa_obj = 0.02``, ``d = w``, ``h = w/2``,
                   ``E_b = 60 mu``, ``nu = 1/2``)
``fig3``           main-text Fig. 3a,b (= supplement Fig. 2a,b): ``h_m/w`` and ``h_s/w`` in
                   {0.25, 0.375, 0.5, 0.625, 0.75}, free actuator, ``J = 20``
``supp_fig2cd``    supplement Fig. 2c,d: the chamber aspect ratio ``d/w`` and the Gent limit ``J``
``supp_fig3``      supplement Fig. 3: the full model against the quadratic energy (eqs. 15-17)
``regime_map``     object stiffness x pressure, each state classified (see :func:`classify_regimes`);
                   Fig. 2's actuator. The paper names the switch but does not draw it.
``supp_physical``  supplement section 4's statements in physical units: the shear modulus ``mu`` (kPa,
                   with the PDMS base fixed at ``E_b = 3 MPa``) and the chamber width ``w`` (mm, with the
                   other dimensions fixed in mm)
``supp_base``      supplement section 4: ``E_b/mu`` and ``h_b/w`` (the paper: "little change")
=================  ==========================================================================================

Each figure's data is one table (:class:`Table`, written as ``NAME.csv``) with one row per state and the
columns of :data:`COLUMNS`. The pressure, curvature, force and stiffness columns are dimensionless
(``p~ = p/mu``, ``kappa~ = w kappa``, ``F~ = F/mu``, ``k~ = k_obj w/mu``); ``pressure_kpa``,
``curvature_per_m`` and ``contact_force_kpa`` give them in physical units at the row's ``mu`` and ``w``
(Table 1: 50 kPa, 5 mm, unless swept). Booleans are written as 0/1.

The work is split by concern: :mod:`pneunet_env.paper.data` computes the curves (pure: parameters in,
:class:`Table` out), :mod:`pneunet_env.paper.plots` draws them (matplotlib, imported only when a plot is drawn) and
:mod:`pneunet_env.paper.tables` holds the :class:`Table` and its CSV files. This module is the figures' registry
(:data:`FIGURES`) and driver: :func:`generate` computes, writes and returns every figure; every name of the three
modules above stays importable from here. The ``pneunet-grasp figures`` command (:mod:`pneunet_env.paper.command`)
runs it and then the statements of :mod:`pneunet_env.paper.checks`, which read these tables (this module imports
neither of them).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from pneunet_env.paper.data import (
    ASPECT_RATIOS,
    BASE_MODULI,
    BASE_THICKNESSES,
    CONTROL_ELASTICITY,
    DEFAULT_PARAMS,
    FIG2_PARAMS,
    FIG2_STIFFNESSES,
    FULL,
    GENT_LIMITS,
    HYSTERESIS_TOL,
    OBJECT_CURVATURE,
    PAPER_PRESSURE_MAX,
    QUICK,
    REGIMES,
    SHEAR_MODULI_KPA,
    TABLE1_BASE_MODULUS_KPA,
    TABLE1_SHEAR_MODULUS_KPA,
    TABLE1_WIDTH_MM,
    WALL_THICKNESSES,
    WIDTHS_MM,
    CurveSpec,
    Grid,
    classify_regimes,
    compute_curve,
    critical_pressure,
    curve_value,
    fig2_specs,
    fig3_specs,
    linear_rows,
    loading,
    pressure_grid,
    regime_map_specs,
    supp_base_specs,
    supp_fig2cd_specs,
    supp_fig3_specs,
    supp_physical_specs,
    unloading,
)
from pneunet_env.paper.plots import (
    REGIME_COLORS,
    plot_fig2,
    plot_fig3,
    plot_regime_map,
    plot_supp_base,
    plot_supp_fig2cd,
    plot_supp_fig3,
    plot_supp_physical,
)
from pneunet_env.paper.tables import COLUMNS, Table, read_table, write_table
from pneunet_env.progress import progress as progress_bar

__all__ = [
    "COLUMNS",
    "CurveSpec",
    "FIGURES",
    "FULL",
    "FigureDef",
    "Grid",
    "PAPER_PRESSURE_MAX",
    "QUICK",
    "REGIMES",
    "RunReport",
    "Table",
    "classify_regimes",
    "compute_curve",
    "compute_figures",
    "generate",
    "linear_rows",
    "load_tables",
    "pressure_grid",
    "read_table",
    "write_table",
    # re-exported from pneunet_env.paper.data and .plots (importable from here as before the split)
    "ASPECT_RATIOS", "BASE_MODULI", "BASE_THICKNESSES", "CONTROL_ELASTICITY", "DEFAULT_PARAMS", "FIG2_PARAMS",
    "FIG2_STIFFNESSES", "GENT_LIMITS", "HYSTERESIS_TOL", "OBJECT_CURVATURE", "SHEAR_MODULI_KPA",
    "TABLE1_BASE_MODULUS_KPA", "TABLE1_SHEAR_MODULUS_KPA", "TABLE1_WIDTH_MM", "WALL_THICKNESSES", "WIDTHS_MM",
    "critical_pressure", "curve_value", "fig2_specs", "fig3_specs", "loading", "regime_map_specs",
    "supp_base_specs", "supp_fig2cd_specs", "supp_fig3_specs", "supp_physical_specs", "unloading",
    "REGIME_COLORS", "plot_fig2", "plot_fig3", "plot_regime_map", "plot_supp_base", "plot_supp_fig2cd",
    "plot_supp_fig3", "plot_supp_physical",
]


# --------------------------------------------------------------------------------------------- figures


@dataclass(frozen=True)
class FigureDef:
    """A figure: its curves, its plot, and the paper's description of it."""

    name: str
    title: str
    paper: str
    specs: Callable[[Grid], list[CurveSpec]]
    plot: Callable[[Table, Path], None]
    extra: Callable[[Grid], Table] | None = None


def _supp_fig3_extra(grid: Grid) -> Table:
    return linear_rows(DEFAULT_PARAMS, pressure_grid(grid.pressure_step))


FIGURES: dict[str, FigureDef] = {
    "fig2": FigureDef(
        "fig2", "Fig. 2a,b: grasping objects of different stiffness",
        "Curvature kappa~ = w kappa (a) and applied force (b) against p~ = p/mu for five object stiffnesses "
        "k~ = k_obj w/mu; d = w = h_m = h_s = 2 h_b, E_b = 60 mu, nu = 1/2, J = 15, kappa_obj = (50 w)^-1.",
        lambda g: fig2_specs(), plot_fig2),
    "fig3": FigureDef(
        "fig3", "Fig. 3a,b: wall thicknesses",
        "Pressure-curvature relation changing one parameter: (a) the top wall thickness h_m/w, (b) the side wall "
        "thickness h_s/w; otherwise h_b = h_m = h_s = d/2 = w/2, E_b = 60 mu, nu = 1/2, J = 20, k_obj = 0.",
        lambda g: fig3_specs(), plot_fig3),
    "supp_fig2cd": FigureDef(
        "supp_fig2cd", "Supplement Fig. 2c,d: aspect ratio and Gent limit",
        "Pressure-curvature relation changing (c) the chamber aspect ratio d/w, (d) the Gent parameter J; "
        "otherwise h_b = h_m = h_s = d/2 = w/2, E_b = 60 mu, nu = 1/2, J = 20, k_obj = 0.",
        lambda g: supp_fig2cd_specs(), plot_supp_fig2cd),
    "supp_fig3": FigureDef(
        "supp_fig3", "Supplement Fig. 3: full vs quadratic energy",
        "Pressure-curvature relations for the full energy minimisation and the quadratic energy (15), indicating "
        "the range of validity of the latter; h_b = h_m = h_s = d/2 = w/2, E_b = 60 mu, nu = 1/2, J = 20.",
        lambda g: supp_fig3_specs(), plot_supp_fig3, extra=_supp_fig3_extra),
    "regime_map": FigureDef(
        "regime_map", "Regime map: force control, position control, snap-through",
        "Not drawn in the paper (section 3 names it): 'the grasper automatically switches from position to force "
        "control as the grasped object stiffness changes ... The transition occurs at intermediate values'.",
        regime_map_specs, plot_regime_map),
    "supp_physical": FigureDef(
        "supp_physical", "Supplement section 4 in physical units: mu and w",
        "'The actuator can be made more compliant for small pressures by increasing w, or by decreasing h_m or "
        "mu'; 'the instability could be made to occur at a lower pressure by weakening the walls (lowering mu, "
        "h_s or h_m)'.",
        lambda g: supp_physical_specs(), plot_supp_physical),
    "supp_base": FigureDef(
        "supp_base", "Supplement section 4: the base",
        "'Little change was observed on varying h_b or E_b (as the overall bending stiffness is largely "
        "dominated by stretching in the top wall)'.",
        lambda g: supp_base_specs(), plot_supp_base),
}


# --------------------------------------------------------------------------------------------- driver


@dataclass
class RunReport:
    """What :func:`generate` did."""

    tables: dict[str, Table] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    states: int = 0
    unconverged: int = 0
    seconds: float = 0.0


def compute_figures(grid: Grid, names: Sequence[str] | None = None,
                    progress: Callable[[CurveSpec], None] | None = None) -> dict[str, Table]:
    """Compute the data of the named figures (all if ``None``) at resolution ``grid``; pure apart from ``progress``."""
    names = list(FIGURES) if names is None else list(names)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ValueError(f"unknown figure(s) {unknown}; known: {list(FIGURES)}")
    out: dict[str, Table] = {}
    for name in names:
        f = FIGURES[name]
        parts = []
        for spec in f.specs(grid):
            step = spec.pressure_step if spec.pressure_step is not None else grid.pressure_step
            parts.append(compute_curve(spec, pressure_grid(step)))
            if progress is not None:
                progress(spec)
        if f.extra is not None:
            parts.append(f.extra(grid))
        out[name] = Table.concat(parts)
    return out


def generate(out_dir: str | Path, quick: bool = False, names: Sequence[str] | None = None, csv_files: bool = True,
             png_files: bool = True, show_progress: bool = True) -> RunReport:
    """Compute, write (``NAME.csv``, ``NAME.png``) and return every figure's data.

    Args:
        out_dir: created if missing.
        quick: coarser grids (:data:`QUICK`, for CI) instead of :data:`FULL`.
        names: a subset of :data:`FIGURES` (default: all).
        csv_files, png_files: which files to write.
        show_progress: a progress bar over the curves on stderr (:func:`pneunet_env.progress.progress`;
            drawn if tqdm is installed).
    """
    t0 = time.perf_counter()
    grid = QUICK if quick else FULL
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = list(FIGURES) if names is None else list(names)
    total = sum(len(FIGURES[n].specs(grid)) for n in names if n in FIGURES)
    bar = progress_bar(total=total, desc="figures", unit="curve", enabled=bool(show_progress), leave=True)

    def tick(spec: CurveSpec) -> None:
        bar.set_postfix_str(f"{spec.figure}: {spec.series}", refresh=False)
        bar.update(1)

    try:
        tables = compute_figures(grid, names, tick)
    finally:
        bar.close()
    report = RunReport(tables=tables)
    for name, table in tables.items():
        full_rows = table["model"] == "full"
        report.states += int(full_rows.sum())
        report.unconverged += int((~table["converged"][full_rows]).sum())
        if csv_files:
            p = out / f"{name}.csv"
            write_table(table, p)
            report.files.append(p)
        if png_files:
            p = out / f"{name}.png"
            FIGURES[name].plot(table, p)
            report.files.append(p)
    report.seconds = time.perf_counter() - t0
    return report


def load_tables(directory: str | Path, names: Sequence[str] | None = None) -> dict[str, Table]:
    """Read back the CSVs that :func:`generate` wrote in ``directory``."""
    d = Path(directory)
    names = list(FIGURES) if names is None else list(names)
    missing = [n for n in names if not (d / f"{n}.csv").is_file()]
    if missing:
        raise FileNotFoundError(f"{d}: missing {', '.join(m + '.csv' for m in missing)}; run "
                                f"'pneunet-grasp figures --out {d}' first")
    return {n: read_table(d / f"{n}.csv") for n in names}
