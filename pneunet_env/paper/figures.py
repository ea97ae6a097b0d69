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

The data functions are pure (parameters in, :class:`Table` out); plotting is separate and imports
matplotlib only when called. :func:`generate` computes, writes and returns every figure; the
``pneunet-grasp figures`` command (:mod:`pneunet_env.paper.command`) runs it and then the statements of
:mod:`pneunet_env.paper.checks`, which read these tables (this module imports neither of them).
"""

from __future__ import annotations

import csv
import math
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pneunet_env.physics import mechanics
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import load_path

__all__ = [
    "COLUMNS",
    "CurveSpec",
    "FIGURES",
    "FULL",
    "Grid",
    "PAPER_PRESSURE_MAX",
    "QUICK",
    "REGIMES",
    "Table",
    "classify_regimes",
    "compute_curve",
    "generate",
    "linear_rows",
    "pressure_grid",
    "read_table",
    "write_table",
]

PAPER_PRESSURE_MAX = 1.2
"""The end of the paper's pressure axes (``p~ = p/mu``)."""

FIG2_PARAMS = ActuatorParams(gent_limit=15.0)
"""Main-text Fig. 2's actuator: ``d = w``, ``h_b = h_s = h_m = w/2``, ``E_b = 60 mu``, ``nu = 1/2``, ``J = 15``."""

DEFAULT_PARAMS = ActuatorParams()
"""Fig. 3 and the supplement's actuator: as :data:`FIG2_PARAMS` but ``J = 20`` (Table 1)."""

OBJECT_CURVATURE = 0.02
"""``w kappa_obj`` of every grasped object (the paper's value)."""

FIG2_STIFFNESSES = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
"""Fig. 2's five object stiffnesses ``k~``: two soft (below 1e-5), one intermediate, two stiff (1e-3 and above)."""

WALL_THICKNESSES = (0.25, 0.375, 0.5, 0.625, 0.75)
"""Fig. 3's ``h_m/w`` and ``h_s/w`` (the paper's legend)."""

ASPECT_RATIOS = (0.75, 1.0, 1.25, 1.5, 2.0)
"""Supplement Fig. 2c's ``d/w`` (the extracted supplement does not list its values; these bracket ``d = w``)."""

GENT_LIMITS = (10.0, 15.0, 20.0, 30.0, 40.0)
"""Supplement Fig. 2d's ``J`` (values not in the extracted text; they bracket the paper's 15 and 20)."""

SHEAR_MODULI_KPA = (25.0, 37.5, 50.0, 62.5, 75.0)
"""``mu`` (kPa) of the physical sweep; the PDMS base keeps ``E_b = 3 MPa``, so ``E_b/mu = 3000/mu``."""

WIDTHS_MM = (4.0, 4.5, 5.0, 6.0, 7.5)
"""``w`` (mm) of the physical sweep; ``d = 5 mm`` and every wall ``2.5 mm`` stay fixed."""

BASE_MODULI = (30.0, 40.0, 60.0, 90.0, 120.0)
"""``E_b/mu`` of the base sweep."""

BASE_THICKNESSES = WALL_THICKNESSES
"""``h_b/w`` of the base sweep (the same range as Fig. 3's walls, so the spreads compare)."""

TABLE1_SHEAR_MODULUS_KPA = 50.0
TABLE1_WIDTH_MM = 5.0
TABLE1_BASE_MODULUS_KPA = 3000.0

HYSTERESIS_TOL = 1e-6
"""Two branches at the same pressure are different states when their curvatures differ by more than this."""

CONTROL_ELASTICITY = 0.2
"""A quantity is "held" when its elasticity ``d ln X / d ln p`` is at most this (:func:`classify_regimes`)."""

REGIMES = ("free", "position-controlled", "force-controlled", "snap-through", "transition")
"""The regime labels of :func:`classify_regimes`, in legend order."""

COLUMNS = (
    "figure",
    "series",
    "model",
    "sweep",
    "sweep_value",
    "branch",
    "pressure",
    "curvature",
    "side_strain",
    "top_strain",
    "contact_force",
    "indentation",
    "in_contact",
    "dcurvature_dpressure",
    "dforce_dpressure",
    "snapped",
    "converged",
    "gradient_norm",
    "min_eigenvalue",
    "regime",
    "object_stiffness",
    "object_curvature",
    "chamber_height",
    "base_thickness",
    "side_thickness",
    "top_thickness",
    "base_modulus",
    "poisson_ratio",
    "gent_limit",
    "shear_modulus_kpa",
    "width_mm",
    "pressure_kpa",
    "curvature_per_m",
    "contact_force_kpa",
)
"""The columns of every figure table. ``branch`` is ``loading`` or ``unloading``; ``model`` is ``full`` (energy
minimisation) or ``quadratic`` (supplement eq. 15); ``sweep`` names the parameter varied in the figure and
``sweep_value`` its value; ``dcurvature_dpressure`` and ``dforce_dpressure`` are the exact tangents of the
equilibrium path (``dx/dp = H^{-1} dV/dx``), not finite differences; ``regime`` is :func:`classify_regimes`'s."""

_STRING_COLUMNS = frozenset({"figure", "series", "model", "sweep", "branch", "regime"})
_BOOL_COLUMNS = frozenset({"in_contact", "snapped", "converged"})


# --------------------------------------------------------------------------------------------- tables


class Table:
    """Named columns of equal length (numpy arrays): one figure's data.

    ``table["pressure"]`` is a column; ``table.where(series="free", branch="loading")`` the rows matching
    every condition (equality; a float condition matches to 1e-12 relative).
    """

    def __init__(self, columns: Mapping[str, Sequence | np.ndarray]) -> None:
        self.columns: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in columns.items()}
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"columns differ in length: { {k: len(v) for k, v in self.columns.items()} }")

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; columns: {sorted(self.columns)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def mask(self, **conditions) -> np.ndarray:
        m = np.ones(len(self), dtype=bool)
        for name, value in conditions.items():
            col = self[name]
            if isinstance(value, (float, int)) and not isinstance(value, bool) and col.dtype.kind == "f":
                m &= np.isclose(col, value, rtol=1e-12, atol=0.0)
            else:
                m &= col == value
        return m

    def where(self, **conditions) -> Table:
        return self.take(self.mask(**conditions))

    def take(self, index) -> Table:
        return Table({k: v[index] for k, v in self.columns.items()})

    def unique(self, name: str) -> list:
        """The distinct values of a column, in order of first appearance."""
        col = self[name]
        _, first = np.unique(col, return_index=True)
        return [col[i].item() if hasattr(col[i], "item") else col[i] for i in sorted(first)]

    @staticmethod
    def concat(tables: Iterable[Table]) -> Table:
        tables = [t for t in tables if len(t)]
        if not tables:
            return Table({c: np.array([]) for c in COLUMNS})
        names = list(tables[0].columns)
        return Table({n: np.concatenate([t[n] for t in tables]) for n in names})


def write_table(table: Table, path: str | Path) -> None:
    """Write ``table`` as CSV (header row, floats with 10 significant digits, booleans as 0/1)."""
    names = list(table.columns)
    cols = []
    for n in names:
        c = table[n]
        if n in _BOOL_COLUMNS or c.dtype.kind == "b":
            cols.append([str(int(v)) for v in c])
        elif c.dtype.kind == "f":
            cols.append([format(float(v), ".10g") for v in c])
        else:
            cols.append([str(v) for v in c])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        w.writerows(zip(*cols, strict=True))


def read_table(path: str | Path) -> Table:
    """Read a CSV written by :func:`write_table` back into a :class:`Table` (types restored by column name)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ValueError(f"{path}: empty file, expected a header row")
    names, body = rows[0], rows[1:]
    data = list(zip(*body, strict=True)) if body else [() for _ in names]
    out: dict[str, np.ndarray] = {}
    for n, col in zip(names, data, strict=True):
        if n in _STRING_COLUMNS:
            out[n] = np.array(col, dtype=object)
        elif n in _BOOL_COLUMNS:
            out[n] = np.array([v == "1" for v in col], dtype=bool)
        else:
            out[n] = np.array([float(v) for v in col], dtype=float)
    return Table(out)


# --------------------------------------------------------------------------------------------- grids


@dataclass(frozen=True)
class Grid:
    """Resolution of a run.

    Attributes:
        pressure_step: ``dp~`` of the figures' pressure grid (0 to :data:`PAPER_PRESSURE_MAX`).
        regime_stiffnesses: number of log-spaced ``k~`` in ``[1e-6, 1]`` on the regime map.
        regime_pressure_step: ``dp~`` of the regime map.
    """

    pressure_step: float
    regime_stiffnesses: int
    regime_pressure_step: float


FULL = Grid(pressure_step=0.0025, regime_stiffnesses=121, regime_pressure_step=0.0025)
QUICK = Grid(pressure_step=0.005, regime_stiffnesses=25, regime_pressure_step=0.01)


def pressure_grid(step: float, p_max: float = PAPER_PRESSURE_MAX) -> np.ndarray:
    """``0, step, 2 step, ..., p_max`` (``p_max`` included)."""
    if not (step > 0.0 and math.isfinite(step)):
        raise ValueError(f"pressure step must be finite and > 0, got {step!r}")
    n = int(round(p_max / step))
    return np.linspace(0.0, n * step, n + 1)


# --------------------------------------------------------------------------------------------- curves


@dataclass(frozen=True)
class CurveSpec:
    """One quasi-static sweep to compute: an actuator, an object, and where it goes in a figure.

    ``shear_modulus_kpa`` and ``width_mm`` only set the physical-unit columns (the solve is dimensionless).
    """

    figure: str
    series: str
    params: ActuatorParams = DEFAULT_PARAMS
    object_stiffness: float = 0.0
    object_curvature: float = OBJECT_CURVATURE
    sweep: str = ""
    sweep_value: float = math.nan
    shear_modulus_kpa: float = TABLE1_SHEAR_MODULUS_KPA
    width_mm: float = TABLE1_WIDTH_MM
    pressure_step: float | None = None  # None: the figure grid's


def _tangents(kappa, side_strain, pressure, params, kobj, kc):
    """Exact ``d kappa~/dp~`` and ``dF~/dp~`` along the equilibrium path: ``H dx/dp = dV/dx``."""
    H = mechanics.hessian(kappa, side_strain, pressure, params, kobj, kc)
    g = mechanics.volume_gradient(kappa, side_strain, params)
    det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        dk = (H[:, 1, 1] * g[:, 0] - H[:, 0, 1] * g[:, 1]) / det
    contact = (kobj > 0.0) & (kappa > kc)
    dF = np.where(contact, kobj * dk / np.maximum(kappa, kc) ** 2, 0.0)
    return dk, dF


def classify_regimes(
    pressure: np.ndarray,
    curvature: np.ndarray,
    contact_force: np.ndarray,
    dcurvature_dpressure: np.ndarray,
    dforce_dpressure: np.ndarray,
    in_contact: np.ndarray,
    snapped: np.ndarray,
    bistable: np.ndarray,
    threshold: float = CONTROL_ELASTICITY,
) -> np.ndarray:
    """Label each state of a grasp with its control regime (one of :data:`REGIMES`).

    In order of precedence:

    * ``free``: not in contact (``kappa <= kappa_obj``, or no object).
    * ``snap-through``: the state was reached by crossing a fold (``snapped``), or its pressure lies in the
      hysteresis window, where the loading and unloading branches are different states (``bistable``).
    * ``position-controlled``: the curvature is held by the object: its elasticity
      ``(p/kappa) d kappa/dp <= threshold`` (a 1% rise in pressure moves the curvature by at most 0.2%).
    * ``force-controlled``: the traction is held (saturated): ``(p/F) dF/dp <= threshold``.
    * ``transition``: in contact, neither held: curvature and force both follow the pressure.

    The derivatives are the exact tangents of the path (columns ``dcurvature_dpressure``, ``dforce_dpressure``).
    Since ``F = k (1/kappa_obj - 1/kappa)``, the two elasticities obey
    ``e_F = e_kappa kappa_obj / (kappa - kappa_obj)``: they cannot both be small near contact.
    """
    p = np.asarray(pressure, dtype=float)
    k = np.asarray(curvature, dtype=float)
    F = np.asarray(contact_force, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        e_k = np.where(k > 0.0, p * np.asarray(dcurvature_dpressure) / k, np.inf)
        e_f = np.where(F > 0.0, p * np.asarray(dforce_dpressure) / F, np.inf)
    out = np.full(p.shape, "transition", dtype=object)
    out[np.abs(e_f) <= threshold] = "force-controlled"
    out[np.abs(e_k) <= threshold] = "position-controlled"
    out[np.asarray(snapped, bool) | np.asarray(bistable, bool)] = "snap-through"
    out[~np.asarray(in_contact, bool)] = "free"
    return out


def compute_curve(spec: CurveSpec, pressures: np.ndarray, unload: bool = True) -> Table:
    """Load ``spec``'s actuator from rest along ``pressures`` (increasing, from 0), then unload on the same grid.

    Returns a :class:`Table`: the loading rows, then (if ``unload``) the unloading rows from the top
    pressure back to 0 (the top state appears on both branches).
    """
    ps = np.asarray(pressures, dtype=float)
    if ps.ndim != 1 or ps.size < 2 or ps[0] != 0.0 or np.any(np.diff(ps) <= 0.0):
        raise ValueError("pressures must be an increasing 1-D grid starting at 0 with at least 2 points")
    n = ps.size
    route = np.concatenate([ps, ps[-2::-1]]) if unload else ps
    path = load_path(route, spec.object_stiffness, spec.object_curvature, spec.params)
    # Rows: the loading states, then the unloading states starting again from the top state.
    rows = np.concatenate([np.arange(n), np.arange(n - 1, route.size)]) if unload else np.arange(n)
    P, K, S = path.pressure[rows], path.curvature[rows], path.side_strain[rows]
    snapped = path.snapped[rows]
    if unload:
        snapped[n] = False  # the top state, repeated: reached on loading, not by a jump on unloading
    kobj, kc = spec.object_stiffness, spec.object_curvature
    in_contact = (kobj > 0.0) & (K > kc)
    dk, dF = _tangents(K, S, P, spec.params, kobj, kc)
    branch = np.array(["loading"] * n + ["unloading"] * (rows.size - n), dtype=object)
    # Loading and unloading states at the same pressure: different states = bistable (hysteresis window).
    bistable = np.zeros(rows.size, dtype=bool)
    if unload:
        diff = np.abs(K[:n] - K[n:][::-1]) > HYSTERESIS_TOL
        bistable[:n] = diff
        bistable[n:] = diff[::-1]
    regime = classify_regimes(P, K, path.contact_force[rows], dk, dF, in_contact, snapped, bistable)
    p = spec.params
    mu, w = spec.shear_modulus_kpa, spec.width_mm
    m = rows.size

    def full(value):
        return np.full(m, value, dtype=object if isinstance(value, str) else float)

    return Table(
        {
            "figure": full(spec.figure),
            "series": full(spec.series),
            "model": full("full"),
            "sweep": full(spec.sweep),
            "sweep_value": full(float(spec.sweep_value)),
            "branch": branch,
            "pressure": P,
            "curvature": K,
            "side_strain": S,
            "top_strain": p.chamber_height * (1.0 + S) * K,
            "contact_force": path.contact_force[rows],
            "indentation": path.indentation[rows],
            "in_contact": in_contact,
            "dcurvature_dpressure": dk,
            "dforce_dpressure": dF,
            "snapped": snapped,
            "converged": path.converged[rows],
            "gradient_norm": path.gradient_norm[rows],
            "min_eigenvalue": path.min_eigenvalue[rows],
            "regime": regime,
            "object_stiffness": full(float(kobj)),
            "object_curvature": full(float(kc)),
            "chamber_height": full(p.chamber_height),
            "base_thickness": full(p.base_thickness),
            "side_thickness": full(p.side_thickness),
            "top_thickness": full(p.top_thickness),
            "base_modulus": full(p.base_modulus),
            "poisson_ratio": full(p.poisson_ratio),
            "gent_limit": full(p.gent_limit),
            "shear_modulus_kpa": full(float(mu)),
            "width_mm": full(float(w)),
            "pressure_kpa": P * mu,
            "curvature_per_m": K / (w * 1e-3),
            "contact_force_kpa": path.contact_force[rows] * mu,
        }
    )


def linear_rows(params: ActuatorParams, pressures: np.ndarray, figure: str = "supp_fig3") -> Table:
    """The quadratic (linearised) energy's closed-form ``kappa~(p~)`` (supplement eqs. 15-16), as table rows.

    Only pressures below :attr:`pneunet_env.physics.linear.LinearModel.valid_until` (where the quadratic energy still
    has a minimum) are kept. ``model`` is ``quadratic``; ``dcurvature_dpressure`` is a central difference
    of the closed form; solver columns (``converged``, ``gradient_norm``...) are not applicable (NaN / 1).
    """
    from pneunet_env.physics.linear import LinearModel

    lin = LinearModel(params)
    ps = np.asarray(pressures, dtype=float)
    ps = ps[ps < lin.valid_until]
    k, s = lin.state(ps)
    h = 1e-6
    dk = (lin.curvature(ps + h) - lin.curvature(np.maximum(ps - h, 0.0))) / (ps + h - np.maximum(ps - h, 0.0))
    m = ps.size
    nan = np.full(m, np.nan)
    zeros = np.zeros(m)

    def full(value):
        return np.full(m, value, dtype=object if isinstance(value, str) else float)

    mu, w = TABLE1_SHEAR_MODULUS_KPA, TABLE1_WIDTH_MM
    return Table(
        {
            "figure": full(figure),
            "series": full("quadratic energy (eq. 15)"),
            "model": full("quadratic"),
            "sweep": full(""),
            "sweep_value": nan,
            "branch": full("loading"),
            "pressure": ps,
            "curvature": k,
            "side_strain": s,
            "top_strain": params.chamber_height * (1.0 + s) * k,
            "contact_force": zeros,
            "indentation": zeros,
            "in_contact": np.zeros(m, dtype=bool),
            "dcurvature_dpressure": dk,
            "dforce_dpressure": zeros,
            "snapped": np.zeros(m, dtype=bool),
            "converged": np.ones(m, dtype=bool),
            "gradient_norm": nan,
            "min_eigenvalue": nan,
            "regime": full("free"),
            "object_stiffness": zeros,
            "object_curvature": full(OBJECT_CURVATURE),
            "chamber_height": full(params.chamber_height),
            "base_thickness": full(params.base_thickness),
            "side_thickness": full(params.side_thickness),
            "top_thickness": full(params.top_thickness),
            "base_modulus": full(params.base_modulus),
            "poisson_ratio": full(params.poisson_ratio),
            "gent_limit": full(params.gent_limit),
            "shear_modulus_kpa": full(mu),
            "width_mm": full(w),
            "pressure_kpa": ps * mu,
            "curvature_per_m": k / (w * 1e-3),
            "contact_force_kpa": zeros,
        }
    )


# --------------------------------------------------------------------------------------------- figures


def _fmt(x: float) -> str:
    return f"{x:g}"


def _stiffness_label(k: float) -> str:
    e = math.floor(math.log10(k))
    m = k / 10**e
    return f"k~ = 1e{e}" if abs(m - 1.0) < 1e-9 else f"k~ = {m:.2g}e{e}"


def fig2_specs() -> list[CurveSpec]:
    """Main-text Fig. 2: the free actuator and :data:`FIG2_STIFFNESSES`, with Fig. 2's actuator (``J = 15``)."""
    specs = [CurveSpec("fig2", "free actuator", FIG2_PARAMS, 0.0, sweep="object_stiffness", sweep_value=0.0)]
    specs += [
        CurveSpec("fig2", _stiffness_label(k), FIG2_PARAMS, k, sweep="object_stiffness", sweep_value=k)
        for k in FIG2_STIFFNESSES
    ]
    return specs


def fig3_specs() -> list[CurveSpec]:
    """Main-text Fig. 3a (``h_m/w``) and 3b (``h_s/w``), free actuator, ``J = 20``."""
    out = [
        CurveSpec("fig3", f"h_m/w = {_fmt(h)}", DEFAULT_PARAMS.replace(top_thickness=h), sweep="top_thickness",
                  sweep_value=h)
        for h in WALL_THICKNESSES
    ]
    out += [
        CurveSpec("fig3", f"h_s/w = {_fmt(h)}", DEFAULT_PARAMS.replace(side_thickness=h), sweep="side_thickness",
                  sweep_value=h)
        for h in WALL_THICKNESSES
    ]
    return out


def supp_fig2cd_specs() -> list[CurveSpec]:
    """Supplement Fig. 2c (``d/w``) and 2d (``J``), free actuator."""
    out = [
        CurveSpec("supp_fig2cd", f"d/w = {_fmt(d)}", DEFAULT_PARAMS.replace(chamber_height=d),
                  sweep="chamber_height", sweep_value=d)
        for d in ASPECT_RATIOS
    ]
    out += [
        CurveSpec("supp_fig2cd", f"J = {_fmt(j)}", DEFAULT_PARAMS.replace(gent_limit=j), sweep="gent_limit",
                  sweep_value=j)
        for j in GENT_LIMITS
    ]
    return out


def supp_fig3_specs() -> list[CurveSpec]:
    """Supplement Fig. 3's full-model curve (defaults, free); the quadratic rows come from :func:`linear_rows`."""
    return [CurveSpec("supp_fig3", "full energy", DEFAULT_PARAMS)]


def supp_physical_specs() -> list[CurveSpec]:
    """The elastomer's ``mu`` (base fixed at 3 MPa) and the chamber width ``w`` (other dimensions fixed in mm)."""
    out = [
        CurveSpec("supp_physical", f"mu = {_fmt(mu)} kPa",
                  DEFAULT_PARAMS.replace(base_modulus=TABLE1_BASE_MODULUS_KPA / mu), sweep="shear_modulus_kpa",
                  sweep_value=mu, shear_modulus_kpa=mu)
        for mu in SHEAR_MODULI_KPA
    ]
    d_mm, h_mm = 5.0, 2.5
    out += [
        CurveSpec("supp_physical", f"w = {_fmt(w)} mm",
                  DEFAULT_PARAMS.replace(chamber_height=d_mm / w, base_thickness=h_mm / w,
                                         side_thickness=h_mm / w, top_thickness=h_mm / w),
                  sweep="width_mm", sweep_value=w, width_mm=w)
        for w in WIDTHS_MM
    ]
    return out


def supp_base_specs() -> list[CurveSpec]:
    """The base's modulus ``E_b/mu`` and thickness ``h_b/w``, free actuator, ``J = 20``."""
    out = [
        CurveSpec("supp_base", f"E_b/mu = {_fmt(e)}", DEFAULT_PARAMS.replace(base_modulus=e), sweep="base_modulus",
                  sweep_value=e)
        for e in BASE_MODULI
    ]
    out += [
        CurveSpec("supp_base", f"h_b/w = {_fmt(h)}", DEFAULT_PARAMS.replace(base_thickness=h),
                  sweep="base_thickness", sweep_value=h)
        for h in BASE_THICKNESSES
    ]
    return out


def regime_map_specs(grid: Grid, params: ActuatorParams = FIG2_PARAMS) -> list[CurveSpec]:
    """One grasp per log-spaced ``k~`` in ``[1e-6, 1]`` (``grid.regime_stiffnesses`` of them)."""
    ks = np.logspace(-6.0, 0.0, grid.regime_stiffnesses)
    return [
        CurveSpec("regime_map", _stiffness_label(float(k)), params, float(k), sweep="object_stiffness",
                  sweep_value=float(k), pressure_step=grid.regime_pressure_step)
        for k in ks
    ]


@dataclass(frozen=True)
class FigureDef:
    """A figure: its curves, its plot, and the paper's description of it."""

    name: str
    title: str
    paper: str
    specs: Callable[[Grid], list[CurveSpec]]
    plot: Callable[[Table, Path], None]
    extra: Callable[[Grid], Table] | None = None


# --------------------------------------------------------------------------------------------- summaries


def loading(table: Table, **conditions) -> Table:
    """The loading rows of one curve (``conditions`` select it), in increasing pressure."""
    t = table.where(branch="loading", model="full", **conditions)
    return t.take(np.argsort(t["pressure"], kind="stable"))


def unloading(table: Table, **conditions) -> Table:
    """The unloading rows of one curve, in increasing pressure (the loading grid's order)."""
    t = table.where(branch="unloading", model="full", **conditions)
    return t.take(np.argsort(t["pressure"], kind="stable"))


def critical_pressure(curve: Table) -> tuple[float, float]:
    """The balloon instability's pressure and severity along a free loading path.

    Definition: the critical pressure is where ``d kappa~/dp~`` (the path's exact tangent) is largest on the
    loading branch; it is refined by a parabola through the grid maximum and its two neighbours. The
    severity is that largest slope. If the path crossed a fold (``snapped``) the curvature jumps: the
    critical pressure is then the last pressure before the first snap, and the severity is ``inf``.

    Returns ``(p_c, max d kappa~/dp~)``.
    """
    p, dk, sn = curve["pressure"], curve["dcurvature_dpressure"], curve["snapped"]
    if sn.any():
        i = int(np.argmax(sn))
        return float(p[max(i - 1, 0)]), math.inf
    i = int(np.nanargmax(dk))
    if 0 < i < len(p) - 1:
        y0, y1, y2 = dk[i - 1], dk[i], dk[i + 1]
        den = y0 - 2.0 * y1 + y2
        h = p[i + 1] - p[i]
        shift = 0.5 * (y0 - y2) / den if den < 0.0 else 0.0
        shift = min(max(shift, -1.0), 1.0)
        return float(p[i] + shift * h), float(y1 - 0.25 * (y0 - y2) * shift)
    return float(p[i]), float(dk[i])


def curve_value(curve: Table, column: str, pressure: float) -> float:
    """``column`` of a (sorted) curve interpolated at ``pressure``."""
    return float(np.interp(pressure, curve["pressure"], curve[column]))


# --------------------------------------------------------------------------------------------- plotting


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _differs(load_c: Table, unload_c: Table) -> np.ndarray:
    """Mask (loading grid order) where unloading differs from loading, grown by one point for continuity."""
    d = np.abs(load_c["curvature"] - unload_c["curvature"]) > HYSTERESIS_TOL
    grown = d.copy()
    grown[1:] |= d[:-1]
    grown[:-1] |= d[1:]
    return grown


def _break_at(x: np.ndarray, y: np.ndarray, cut: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert a gap (NaN) after every index ``i`` with ``cut[i]``: no line segment from ``i`` to ``i + 1``."""
    idx = np.flatnonzero(cut[:-1]) + 1
    return np.insert(x.astype(float), idx, np.nan), np.insert(y.astype(float), idx, np.nan)


def _draw_curves(ax, table: Table, series: Sequence[str], y: str, x: str = "pressure", colors=None,
                 mark_snaps: bool = True, label_snaps: bool = True) -> None:
    """Draw loading (solid) and, where it differs, unloading (dashed) for each series.

    A jump across a fold is not drawn as a line: a dotted arrow goes from the last state before the fold to
    the first after it, ending in a triangle (pointing down: loading, up: unloading).
    """
    plt = _plt()
    if colors is None:
        colors = plt.cm.viridis(np.linspace(0.0, 0.9, len(series)))
    snap_labelled = False
    for s, c in zip(series, colors, strict=True):
        lo, un = loading(table, series=s), unloading(table, series=s)  # both in increasing pressure
        lo_snap = lo["snapped"]
        cut_lo = np.zeros(len(lo), dtype=bool)
        cut_lo[:-1] = lo_snap[1:]
        ax.plot(*_break_at(lo[x], lo[y], cut_lo), color=c, lw=1.6, label=s)
        jumps = [(lo, i - 1, i, "v") for i in np.flatnonzero(lo_snap) if i > 0]
        if len(un) == len(lo):
            un_snap = un["snapped"]
            m = _differs(lo, un)
            if m.any():
                yv = np.where(m, un[y], np.nan)
                ax.plot(*_break_at(un[x], yv, un_snap), color=c, lw=1.4, ls="--", zorder=3)
            jumps += [(un, j + 1, j, "^") for j in np.flatnonzero(un_snap) if j + 1 < len(un)]
        if not mark_snaps:
            continue
        for branch, i0, i1, marker in jumps:
            lab = None
            if label_snaps and not snap_labelled:
                lab = "snap-through (fold)"
                snap_labelled = True
            ax.annotate("", xy=(branch[x][i1], branch[y][i1]), xytext=(branch[x][i0], branch[y][i0]),
                        arrowprops={"arrowstyle": "->", "color": c, "lw": 1.0, "ls": ":"}, zorder=4)
            ax.plot([branch[x][i1]], [branch[y][i1]], marker=marker, color=c, ms=7, mec="k", mew=0.6, ls="none",
                    label=lab, zorder=5)


def _finish(fig, path: Path, note: str = "") -> None:
    if note:
        lines = note.count("\n") + 1
        engine = fig.get_layout_engine()
        if engine is not None and hasattr(engine, "set"):
            engine.set(rect=(0.0, 0.018 * lines + 0.01, 1.0, 1.0 - 0.018 * lines - 0.01))
        fig.text(0.01, 0.005, note, fontsize=7, color="0.35", ha="left", va="bottom")
    fig.savefig(path, dpi=130)
    _plt().close(fig)


def plot_fig2(table: Table, path: Path) -> None:
    plt = _plt()
    series = table.unique("series")
    colors = ["k"] + list(plt.cm.viridis(np.linspace(0.0, 0.85, len(series) - 1)))
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    _draw_curves(a, table, series, "curvature", colors=colors)
    a.axhline(OBJECT_CURVATURE, color="0.6", lw=0.8, ls=":")
    a.text(0.01, OBJECT_CURVATURE, " w kappa_obj", color="0.4", fontsize=7, va="bottom")
    a.set(xlabel="pressure  p~ = p/mu", ylabel="curvature  kappa~ = w kappa", xlim=(0, PAPER_PRESSURE_MAX),
          title="(a) curvature")
    a.legend(fontsize=7, loc="upper left")
    obj = [s for s in series if s != "free actuator"]
    _draw_curves(b, table, obj, "contact_force", colors=colors[1:])
    b.set_yscale("log")
    b.set_ylim(1e-7, None)
    b.set(xlabel="pressure  p~ = p/mu", ylabel="contact traction  F~ = F/mu", xlim=(0, PAPER_PRESSURE_MAX),
          title="(b) contact force")
    b.legend(fontsize=7, loc="lower right")
    fig.suptitle("Fig. 2: grasping objects of different stiffness (J = 15, w kappa_obj = 0.02, d = w, h = w/2, "
                 "E_b = 60 mu, nu = 1/2); dashed: unloading where it differs", fontsize=9)
    _finish(fig, path)


def _sweep_panels(table: Table, path: Path, panels: Sequence[tuple[str, str]], suptitle: str, x="pressure",
                  y="curvature", xlabel="pressure  p~ = p/mu", ylabel="curvature  kappa~ = w kappa",
                  markers: Callable | None = None) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.4), constrained_layout=True)
    axes = np.atleast_1d(axes)
    for ax, (sweep, title) in zip(axes, panels, strict=True):
        sub = table.where(sweep=sweep)
        series = sub.unique("series")
        colors = plt.cm.plasma(np.linspace(0.0, 0.85, len(series)))
        _draw_curves(ax, sub, series, y, x=x, colors=colors)
        if markers is not None:
            markers(ax, sub, series, colors)
        else:
            for s, c in zip(series, colors, strict=True):
                lo = loading(sub, series=s)
                pc, _ = critical_pressure(lo)
                ax.plot([pc], [curve_value(lo, y, pc)], "o", color=c, mfc="none", ms=6)
        ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
        ax.set_xlim(0, None)
        ax.set_ylim(0, None)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(suptitle, fontsize=9)
    _finish(fig, path, "open circles: critical pressure (max d kappa/dp on loading); dashed: unloading where it "
                       "differs; triangles: snap-through")


def plot_fig3(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("top_thickness", "(a) top wall h_m/w"), ("side_thickness", "(b) side wall h_s/w")],
                  "Fig. 3: free actuator, J = 20, other walls w/2, d = w, E_b = 60 mu, nu = 1/2")


def plot_supp_fig2cd(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("chamber_height", "(c) aspect ratio d/w"), ("gent_limit", "(d) Gent limit J")],
                  "Supplement Fig. 2c,d: free actuator, h = w/2, E_b = 60 mu, nu = 1/2, J = 20 unless swept")


def plot_supp_base(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("base_modulus", "base modulus E_b/mu"), ("base_thickness", "base thickness h_b/w")],
                  "Supplement section 4: varying the base, E_b/mu and h_b/w (free actuator, J = 20)")


def plot_supp_physical(table: Table, path: Path) -> None:
    def marks(ax, sub, series, colors):
        for s, c in zip(series, colors, strict=True):
            lo = loading(sub, series=s)
            pc, _ = critical_pressure(lo)
            mu = float(lo["shear_modulus_kpa"][0])
            ax.plot([pc * mu], [curve_value(lo, "curvature_per_m", pc)], "o", color=c, mfc="none", ms=6)

    _sweep_panels(
        table, path,
        [("shear_modulus_kpa", "elastomer shear modulus mu (E_b = 3 MPa fixed)"),
         ("width_mm", "chamber width w (d = 5 mm, walls 2.5 mm fixed)")],
        "Supplement section 4 in physical units (J = 20)", x="pressure_kpa", y="curvature_per_m",
        xlabel="pressure  p (kPa)", ylabel="curvature  kappa (1/m)", markers=marks,
    )


def plot_supp_fig3(table: Table, path: Path) -> None:
    plt = _plt()
    full = loading(table, series="full energy")
    quad = table.where(model="quadratic")
    quad = quad.take(np.argsort(quad["pressure"]))
    pc, _ = critical_pressure(full)
    fig, (a, b) = plt.subplots(2, 1, figsize=(6.4, 6.2), sharex=True, constrained_layout=True,
                               gridspec_kw={"height_ratios": [3, 1.4]})
    a.plot(full["pressure"], full["curvature"], "k", lw=1.8, label="full energy minimisation")
    a.plot(quad["pressure"], quad["curvature"], color="tab:red", lw=1.6, ls="--", label="quadratic energy (eq. 15)")
    slope = DEFAULT_PARAMS.small_pressure_slope
    a.plot(full["pressure"], slope * full["pressure"], color="tab:blue", lw=1.0, ls=":",
           label=f"leading order, eq. 17 (slope {slope:.4f})")
    a.axvline(pc, color="0.5", lw=0.8, ls=":")
    a.text(pc, 0.02, f" p~_c = {pc:.3f}", color="0.3", fontsize=8)
    a.set(ylabel="curvature  kappa~", title="Supplement Fig. 3: full model vs quadratic energy (J = 20, defaults)")
    a.set_ylim(0, None)
    a.legend(fontsize=8, loc="upper left")
    kf = np.interp(quad["pressure"], full["pressure"], full["curvature"])
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.where(kf > 0, quad["curvature"] / kf - 1.0, np.nan)
    b.plot(quad["pressure"], 100 * err, color="tab:red", lw=1.4)
    b.axhline(0, color="0.6", lw=0.6)
    for lvl in (-10, 10):
        b.axhline(lvl, color="0.6", lw=0.6, ls=":")
    b.axvline(pc, color="0.5", lw=0.8, ls=":")
    b.set(xlabel="pressure  p~ = p/mu", ylabel="quadratic / full - 1 (%)", xlim=(0, PAPER_PRESSURE_MAX))
    _finish(fig, path)


REGIME_COLORS = {
    "free": "#dddddd",
    "position-controlled": "#3b6fb6",
    "force-controlled": "#e08a2c",
    "snap-through": "#c0392b",
    "transition": "#9ccf8c",
}


def plot_regime_map(table: Table, path: Path) -> None:
    plt = _plt()
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    lo = table.where(branch="loading")
    ks = np.array(sorted(set(lo["object_stiffness"].tolist())))
    ps = np.array(sorted(set(lo["pressure"].tolist())))
    idx = {r: i for i, r in enumerate(REGIMES)}
    grid = np.full((ps.size, ks.size), np.nan)
    ki = np.searchsorted(ks, lo["object_stiffness"])
    pi = np.searchsorted(ps, lo["pressure"])
    grid[pi, ki] = [idx[r] for r in lo["regime"]]
    lk = np.log10(ks)
    mid = 0.5 * (lk[1:] + lk[:-1])
    edges_k = np.concatenate([[lk[0] - (mid[0] - lk[0])], mid, [lk[-1] + (lk[-1] - mid[-1])]])
    edges_p = np.concatenate([[ps[0]], 0.5 * (ps[1:] + ps[:-1]), [ps[-1]]])
    cmap = ListedColormap([REGIME_COLORS[r] for r in REGIMES])
    fig, ax = plt.subplots(figsize=(8.2, 5.2), constrained_layout=True)
    ax.pcolormesh(10**edges_k, edges_p, grid, cmap=cmap, vmin=-0.5, vmax=len(REGIMES) - 0.5, shading="flat")
    ax.set_xscale("log")
    # Folds: where loading snaps up (solid) and unloading snaps back (dashed).
    for branch, style, lab in (("loading", "k-", "fold crossed on loading"), ("unloading", "k--", "fold on unloading")):
        t = table.where(branch=branch, snapped=True)
        if len(t):
            xs, ys = [], []
            for k in ks:
                m = np.isclose(t["object_stiffness"], k)
                if m.any():
                    xs.append(k)
                    ys.append(t["pressure"][m].min() if branch == "loading" else t["pressure"][m].max())
            ax.plot(xs, ys, style, lw=1.2, label=lab)
    for k in FIG2_STIFFNESSES:
        ax.axvline(k, color="w", lw=0.6, ls=":")
    handles = [Patch(color=REGIME_COLORS[r], label=r) for r in REGIMES]
    h2, l2 = ax.get_legend_handles_labels()
    ax.legend(handles=handles + h2, fontsize=8, loc="upper left", framealpha=0.9)
    ax.set(xlabel="object stiffness  k~ = k_obj w / mu", ylabel="pressure  p~ = p/mu (loading)",
           title="Regime map (Fig. 2's actuator, J = 15, w kappa_obj = 0.02), quasi-static loading")
    _finish(fig, path, f"position-controlled: curvature elasticity d ln kappa / d ln p <= {CONTROL_ELASTICITY}; "
                       f"force-controlled: traction elasticity d ln F / d ln p <= {CONTROL_ELASTICITY};\n"
                       "snap-through: a fold was crossed, or the loading and unloading branches differ (hysteresis); "
                       "transition: in contact, neither held; dotted: Fig. 2's stiffnesses")


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
        show_progress: a tqdm progress bar over the curves (if tqdm is installed).
    """
    t0 = time.perf_counter()
    grid = QUICK if quick else FULL
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = list(FIGURES) if names is None else list(names)
    total = sum(len(FIGURES[n].specs(grid)) for n in names if n in FIGURES)
    bar = None
    if show_progress:
        try:
            from tqdm.auto import tqdm

            bar = tqdm(total=total, desc="figures", unit="curve", file=sys.stderr)
        except ImportError:  # pragma: no cover - tqdm is in the plot extra
            bar = None

    def tick(spec: CurveSpec) -> None:
        if bar is not None:
            bar.set_postfix_str(f"{spec.figure}: {spec.series}", refresh=False)
            bar.update(1)

    try:
        tables = compute_figures(grid, names, tick)
    finally:
        if bar is not None:
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
