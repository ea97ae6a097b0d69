"""The figures' data: the paper's parameters, the pressure grids, and the curves computed from them (no plotting).

Every curve is a quasi-static pressure sweep with :func:`pneunet_env.physics.solver.load_path` (loading from rest
to ``p~ = 1.2``, the end of the paper's axes, then unloading back to 0 on the same grid), with the exact tangents
of the path and each state's control regime (:func:`classify_regimes`), as a :class:`~pneunet_env.paper.tables.Table`
(:func:`compute_curve`); supplement Fig. 3's quadratic model is in closed form (:func:`linear_rows`). The
``*_specs`` functions list each figure's curves (:class:`CurveSpec`); :func:`loading`, :func:`unloading`,
:func:`critical_pressure` and :func:`curve_value` summarise a table's curves (for the plots and the checks).

Everything is dimensionless (``p~ = p/mu``, ``kappa~ = w kappa``, ``F~ = F/mu``, ``k~ = k_obj w/mu``) but the
physical-unit columns, at ``mu`` in kPa and ``w`` in mm (Table 1: 50 kPa, 5 mm, unless swept). The functions are
pure: parameters in, :class:`~pneunet_env.paper.tables.Table` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pneunet_env.paper.tables import Table
from pneunet_env.physics import mechanics
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import load_path

__all__ = [
    "ASPECT_RATIOS", "BASE_MODULI", "BASE_THICKNESSES", "CONTROL_ELASTICITY", "CurveSpec", "DEFAULT_PARAMS",
    "FIG2_PARAMS", "FIG2_STIFFNESSES", "FULL", "GENT_LIMITS", "Grid", "HYSTERESIS_TOL", "OBJECT_CURVATURE",
    "PAPER_PRESSURE_MAX", "QUICK", "REGIMES", "SHEAR_MODULI_KPA", "TABLE1_BASE_MODULUS_KPA",
    "TABLE1_SHEAR_MODULUS_KPA", "TABLE1_WIDTH_MM", "WALL_THICKNESSES", "WIDTHS_MM", "classify_regimes",
    "compute_curve", "critical_pressure", "curve_value", "fig2_specs", "fig3_specs", "linear_rows", "loading",
    "pressure_grid", "regime_map_specs", "supp_base_specs", "supp_fig2cd_specs", "supp_fig3_specs",
    "supp_physical_specs", "unloading",
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


# ------------------------------------------------------------------------------------- each figure's curves


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
