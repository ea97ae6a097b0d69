"""The paper's statements on design (main text section 4, the supplement's section 4 and eq. 17): how the walls,
the chamber, the Gent limit, the elastomer and the base move the balloon instability, the saturation curvature
and the small-pressure compliance; the quadratic model's range; and that every state drawn is a converged minimum.
Each is measured on the figure tables (:data:`pneunet_env.paper.checks.CHECKS` lists them in the table's order).
"""

from __future__ import annotations

import math

import numpy as np

from pneunet_env.paper.checks_common import (
    CheckResult,
    Tables,
    format_numbers,
    format_values,
    is_decreasing,
    is_increasing,
    snap_index,
    sweep_curves,
    unload_snap_pressure,
)
from pneunet_env.paper.data import PAPER_PRESSURE_MAX, critical_pressure, curve_value, loading
from pneunet_env.paper.tables import Table
from pneunet_env.physics.params import ActuatorParams

__all__ = [
    "check_base_little_change", "check_compliance_mu", "check_compliance_top", "check_compliance_width",
    "check_converged", "check_linear_validity", "check_pc_aspect", "check_pc_mu", "check_pc_side", "check_pc_top",
    "check_sat_aspect", "check_sat_gent", "check_sat_top", "check_small_pressure_law", "check_smooth_gent",
    "check_smooth_gent_supp", "check_smooth_side", "check_smooth_top", "check_snap_gent",
]

def _monotone_check(t: Tables, key, source, statement, figure, sweep, label, measure, increasing: bool,
                    criterion: str, expected: bool = True, note: str = "", physical: bool = False) -> CheckResult:
    rows = sweep_curves(t[figure], sweep)
    xs = [x for x, _ in rows]
    ys = [measure(c) for _, c in rows]
    ok = is_increasing(ys) if increasing else is_decreasing(ys)
    return CheckResult(
        key, source, statement, f"{label} = {format_values(xs)}: {format_numbers(ys)}", bool(ok), expected=expected,
        criterion=criterion, note=note, values={f"{x:g}": y for x, y in zip(xs, ys, strict=True)},
    )


def _pc(c: Table) -> float:
    return critical_pressure(c)[0]


def _pc_kpa(c: Table) -> float:
    return critical_pressure(c)[0] * float(c["shear_modulus_kpa"][0])


def _severity(c: Table) -> float:
    return critical_pressure(c)[1]


def _ksat(c: Table) -> float:
    return curve_value(c, "curvature", PAPER_PRESSURE_MAX)


def _slope0(c: Table) -> float:
    return float(c["dcurvature_dpressure"][0])


def _compliance_physical(c: Table) -> float:
    """Initial ``d kappa/dp`` in (1/m)/kPa."""
    return _slope0(c) / (float(c["width_mm"][0]) * 1e-3 * float(c["shear_modulus_kpa"][0]))


_PC = "p~_c increases with {x} (critical pressure = max d kappa/dp on loading)"


def check_pc_top(t):
    return _monotone_check(t, "pc_top_wall", "main §4, supp. §4",
                           "The balloon instability occurs at a lower pressure when the top wall h_m is thinner.",
                           "fig3", "top_thickness", "p~_c for h_m/w", _pc, True, _PC.format(x="h_m"))


def check_pc_side(t):
    return _monotone_check(t, "pc_side_wall", "main §4, supp. §4",
                           "The balloon instability occurs at a lower pressure when the side wall h_s is thinner.",
                           "fig3", "side_thickness", "p~_c for h_s/w", _pc, True, _PC.format(x="h_s"))


def check_pc_mu(t):
    return _monotone_check(
        t, "pc_shear_modulus", "main §4, supp. §4",
        "The balloon instability occurs at a lower pressure when the elastomer's shear modulus mu is lower.",
        "supp_physical", "shear_modulus_kpa", "p_c (kPa) for mu (kPa)", _pc_kpa, True,
        "physical p_c = mu p~_c(E_b/mu) increases with mu, the PDMS base fixed at E_b = 3 MPa",
        note="Tested in physical units: at fixed E_b/mu the dimensionless curve is unchanged and p_c = mu p~_c is "
             "trivially proportional to mu; here the base stays 3 MPa PDMS, so a softer elastomer also raises E_b/mu.",
    )


def check_pc_aspect(t):
    return _monotone_check(t, "pc_aspect_ratio", "supp. §4",
                           "The instability occurs at a lower pressure for a taller chamber (larger d/w).",
                           "supp_fig2cd", "chamber_height", "p~_c for d/w", _pc, False,
                           "p~_c decreases as d/w increases")


_SAT = "kappa~(p~ = 1.2) {d} with {x}"


def check_sat_gent(t):
    return _monotone_check(t, "saturation_gent", "supp. §4, main §4",
                           "The saturation curvature increases with the Gent limit J.",
                           "supp_fig2cd", "gent_limit", "kappa~(1.2) for J", _ksat, True,
                           _SAT.format(d="increases", x="J"))


def check_sat_aspect(t):
    return _monotone_check(t, "saturation_aspect_ratio", "supp. §4",
                           "The saturation curvature increases for a chamber wider than tall (lower d/w).",
                           "supp_fig2cd", "chamber_height", "kappa~(1.2) for d/w", _ksat, False,
                           _SAT.format(d="decreases", x="d/w"))


def check_sat_top(t):
    return _monotone_check(t, "saturation_top_wall", "supp. §4",
                           "The saturation curvature increases for a weaker (thinner) top wall.",
                           "fig3", "top_thickness", "kappa~(1.2) for h_m/w", _ksat, False,
                           _SAT.format(d="decreases", x="h_m"))


_SEV = "the peak d kappa~/dp~ on loading (inf if it snaps) {d} with {x}"


def check_smooth_gent(t):
    return _monotone_check(t, "smooth_gent", "main §4",
                           "Lowering the Gent parameter J smooths the curvature jump.",
                           "supp_fig2cd", "gent_limit", "peak d kappa~/dp~ for J", _severity, True,
                           _SEV.format(d="increases", x="J"))


def check_smooth_gent_supp(t):
    return _monotone_check(
        t, "smooth_gent_supp", "supp. §4",
        "'The jump may be mollified by stiffening the top wall (by increasing h_m or J)' -- the J part.",
        "supp_fig2cd", "gent_limit", "peak d kappa~/dp~ for J", _severity, False,
        _SEV.format(d="decreases", x="J"), expected=False,
        note="Contradicts main §4 ('we can smooth this jump by lowering the Gent parameter J', which holds here): "
             "a larger J delays strain stiffening, so the jump grows and, at the largest J, becomes a snap (see the "
             "snap row). The supplement's 'or J' reads as a slip.",
    )


def check_snap_gent(t):
    rows = sweep_curves(t["supp_fig2cd"], "gent_limit")
    snaps = {j: snap_index(c) is not None for j, c in rows}
    table = t["supp_fig2cd"]
    jmax = max(snaps)
    top = dict(rows)[jmax]
    i_up = snap_index(top)
    p_up = float(top["pressure"][i_up]) if i_up is not None else math.nan
    p_down = unload_snap_pressure(table, sweep="gent_limit", sweep_value=jmax)
    small = [j for j in snaps if j <= 20.0]
    ok = snaps[jmax] and p_down is not None and p_down < p_up and not any(snaps[j] for j in small)
    return CheckResult(
        "snap_gent", "main §4",
        "Increasing J allows larger curvatures, 'but it may snap owing to transient instabilities where the geometric "
        "softening is not counterbalanced by strain stiffening'.",
        f"snap on loading for J = {format_values([j for j, s in snaps.items() if s]) or 'none'}"
        + (f"; J = {jmax:g}: snaps up at p~ = {p_up:.3f}, back down at {p_down:.3f} on unloading" if ok else ""),
        bool(ok), criterion="the largest J (40) folds, with hysteresis; J <= 20 does not",
        values={"snapping_J": float(min([j for j, s in snaps.items() if s], default=math.nan))},
    )


def check_smooth_top(t):
    return _monotone_check(t, "smooth_top_wall", "main §4, supp. §4",
                           "The jump is mollified by stiffening the top wall (increasing h_m).",
                           "fig3", "top_thickness", "peak d kappa~/dp~ for h_m/w", _severity, False,
                           _SEV.format(d="decreases", x="h_m"))


def check_smooth_side(t):
    return _monotone_check(t, "smooth_side_wall", "main §4, supp. §4",
                           "The jump is mollified by weakening the side wall (reducing h_s).",
                           "fig3", "side_thickness", "peak d kappa~/dp~ for h_s/w", _severity, True,
                           _SEV.format(d="increases", x="h_s"))


def check_compliance_top(t):
    return _monotone_check(t, "compliance_top_wall", "supp. §4",
                           "The actuator is more compliant at small pressures with a thinner top wall (lower h_m).",
                           "fig3", "top_thickness", "d kappa~/dp~ at rest for h_m/w", _slope0, False,
                           "the slope at rest decreases as h_m increases")


def check_compliance_mu(t):
    return _monotone_check(t, "compliance_shear_modulus", "supp. §4",
                           "The actuator is more compliant at small pressures with a softer elastomer (lower mu).",
                           "supp_physical", "shear_modulus_kpa", "d kappa/dp at rest, (1/m)/kPa, for mu (kPa)",
                           _compliance_physical, False, "the physical slope at rest decreases as mu increases "
                           "(E_b = 3 MPa fixed)")


def check_compliance_width(t):
    return _monotone_check(t, "compliance_width", "supp. §4",
                           "The actuator is more compliant at small pressures with a wider chamber (larger w).",
                           "supp_physical", "width_mm", "d kappa/dp at rest, (1/m)/kPa, for w (mm)",
                           _compliance_physical, True,
                           "the physical slope at rest increases with w (d = 5 mm, walls 2.5 mm fixed)")


def check_small_pressure_law(t: Tables) -> CheckResult:
    errs_tangent, errs_fd, n = [], [], 0
    for name in ("fig3", "supp_fig2cd", "supp_fig3", "supp_base", "supp_physical"):
        tab = t[name]
        full = tab.where(model="full", branch="loading", object_stiffness=0.0)
        for s in full.unique("series"):
            c = loading(full, series=s)
            params = ActuatorParams(
                chamber_height=float(c["chamber_height"][0]), base_thickness=float(c["base_thickness"][0]),
                side_thickness=float(c["side_thickness"][0]), top_thickness=float(c["top_thickness"][0]),
                base_modulus=float(c["base_modulus"][0]), poisson_ratio=float(c["poisson_ratio"][0]),
                gent_limit=float(c["gent_limit"][0]),
            )
            eq17 = params.small_pressure_slope
            p1, p2 = float(c["pressure"][1]), float(c["pressure"][2])
            r1, r2 = float(c["curvature"][1]) / p1, float(c["curvature"][2]) / p2
            richardson = (r1 * p2 - r2 * p1) / (p2 - p1)  # removes the O(p) term of kappa/p
            errs_tangent.append(abs(_slope0(c) / eq17 - 1.0))
            errs_fd.append(abs(richardson / eq17 - 1.0))
            n += 1
    et, ef = max(errs_tangent), max(errs_fd)
    ok = et <= 1e-6 and ef <= 1e-3
    return CheckResult(
        "small_pressure_law", "supp. eq. 17",
        "At small pressure kappa~ ~ p~ [4dw(d+h_m) + (h_m^2 - h_s^2) w - 8 d h_m h_s] / [8w (E_b h_b^3/(12(1-nu^2)) "
        "+ 12 d^2 h_m mu)], with an O(p^2) correction.",
        f"{n} free actuators: the path's tangent at rest matches eq. 17 to {et:.1e} (relative), kappa~/p~ "
        f"extrapolated from the first two grid points to {ef:.1e}; defaults: "
        f"{_slope0(loading(t['supp_fig3'])):.6f} vs eq. 17 {ActuatorParams().small_pressure_slope:.6f}",
        bool(ok), criterion="tangent at p~ = 0 within 1e-6, extrapolated kappa~/p~ within 0.1%",
        values={"tangent_error": et, "extrapolated_error": ef},
    )


def check_linear_validity(t: Tables) -> CheckResult:
    tab = t["supp_fig3"]
    full = loading(tab, series="full energy")
    quad = tab.where(model="quadratic")
    quad = quad.take(np.argsort(quad["pressure"]))
    pc, _ = critical_pressure(full)
    p = quad["pressure"]
    kf = np.interp(p, full["pressure"], full["curvature"])
    m = p > 0
    err = np.abs(quad["curvature"][m] / kf[m] - 1.0)
    pm = p[m]
    early = float(err[pm <= 0.5 * pc].max())
    beyond = np.flatnonzero(err > 0.1)
    p10 = float(pm[beyond[0]]) if beyond.size else math.inf
    at_pc = float(np.interp(pc, pm, err))
    ok = early <= 0.05 and 0.5 * pc <= p10 <= pc and at_pc >= 0.3
    return CheckResult(
        "linear_validity", "supp. §4, Fig. 3",
        "The linearised (quadratic-energy) law is a good assumption until the onset of the balloon instability, "
        "a nonlinear phenomenon.",
        f"quadratic vs full: <= {100 * early:.1f}% off up to p~_c/2 = {0.5 * pc:.3f}; 10% off from p~ = {p10:.3f} "
        f"(= {p10 / pc:.2f} p~_c); {100 * at_pc:.0f}% off at p~_c = {pc:.3f}",
        bool(ok),
        criterion="error <= 5% up to p~_c/2, the 10% error reached between p~_c/2 and p~_c, >= 30% at p~_c",
        values={"early_error": early, "p10": p10, "error_at_pc": at_pc},
    )


def _spread(t: Tables, figure: str, sweep: str) -> float:
    curves = [c["curvature"] for _, c in sweep_curves(t[figure], sweep)]
    stack = np.vstack(curves)
    return float(np.max(stack.max(axis=0) - stack.min(axis=0)))


def check_base_little_change(t: Tables) -> CheckResult:
    ref = _spread(t, "fig3", "top_thickness")
    se = _spread(t, "supp_base", "base_modulus")
    sh = _spread(t, "supp_base", "base_thickness")
    ok = se <= ref / 3 and sh <= ref / 3
    d = ActuatorParams()
    base_term = d.base_modulus * d.base_thickness**3 / (12.0 * (1.0 - d.poisson_ratio**2))
    top_term = 12.0 * d.chamber_height**2 * d.top_thickness
    return CheckResult(
        "base_little_change", "supp. §4",
        "Little change on varying h_b or E_b: the bending stiffness is dominated by stretching of the top wall.",
        f"largest spread of kappa~ between the curves: E_b/mu = 30..120: {se:.3f}; h_b/w = 0.25..0.75: {sh:.3f}; "
        f"h_m/w = 0.25..0.75 (for scale): {ref:.3f}",
        bool(ok), criterion="each spread <= 1/3 of the h_m sweep's",
        note=(f"h_b's effect is {sh / ref:.2f} of h_m's over the same range, E_b's {se / ref:.2f}: "
              + ("close to the 1/3 line. " if abs(sh / ref - 1 / 3) < 0.05 else "")
              + "The base enters the small-pressure stiffness (eq. 18) as E_b h_b^3 / (12 (1 - nu^2)), "
              f"{base_term:.2f} against the top wall's 12 d^2 h_m = {top_term:g} at the defaults."),
        values={"spread_base_modulus": se, "spread_base_thickness": sh, "spread_top_thickness": ref},
    )


def check_converged(t: Tables) -> CheckResult:
    n = bad = 0
    worst_g, worst_l = 0.0, math.inf
    for tab in t.values():
        full = tab.where(model="full")
        n += len(full)
        bad += int((~full["converged"]).sum())
        worst_g = max(worst_g, float(np.max(full["gradient_norm"])))
        worst_l = min(worst_l, float(np.min(full["min_eigenvalue"])))
    ok = bad == 0 and worst_g <= 1e-10 and worst_l > 0.0
    return CheckResult(
        "converged", "this package",
        "Every state in the figures is a converged local minimum (zero gradient, positive-definite Hessian).",
        f"{n} states, {bad} not converged; largest |grad U| = {worst_g:.1e}, smallest Hessian eigenvalue "
        f"{worst_l:.2e}",
        bool(ok), criterion="|grad| <= 1e-10 and lambda_min > 0 everywhere",
        values={"states": float(n), "unconverged": float(bad)},
    )
