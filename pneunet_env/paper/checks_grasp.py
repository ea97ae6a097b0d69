"""The paper's statements on grasping (main text section 3): the free actuator's balloon instability, and how
soft, intermediate and stiff objects are held (force control, the give-in and its fold, position control), each
measured on the figure tables (:data:`pneunet_env.paper.checks.CHECKS` lists them in the table's order).
"""

from __future__ import annotations

import math

import numpy as np

from pneunet_env.paper.checks_common import (
    OBJECT_CURVATURE_PER_M,
    OBJECT_THICKNESS_MM,
    SATURATED,
    SOFT_MAX,
    STIFF_MIN,
    CheckResult,
    Tables,
    elasticity,
    free_curve,
    object_curve,
    snap_index,
    unload_snap_pressure,
)
from pneunet_env.paper.data import (
    FIG2_STIFFNESSES,
    OBJECT_CURVATURE,
    PAPER_PRESSURE_MAX,
    TABLE1_WIDTH_MM,
    critical_pressure,
    curve_value,
    loading,
)
from pneunet_env.paper.tables import Table
from pneunet_env.physics.units import PAPER_MODULUS_PER_STIFFNESS_PA, Scales, object_stiffness_from_material

__all__ = [
    "check_after_give_in", "check_free_balloon", "check_give_in_pressure", "check_materials", "check_modulus_scaling",
    "check_slaved_then_gives_in", "check_snap_hysteresis", "check_soft_follows_free", "check_soft_force_saturates",
    "check_stiff_force_monotone", "check_stiff_position", "check_switch",
]

def check_free_balloon(t: Tables) -> CheckResult:
    rows, ok, vals = [], True, {}
    for label, curve in (("J = 15 (Fig. 2)", free_curve(t["fig2"])), ("J = 20 (Fig. 3)", loading(t["supp_fig3"]))):
        s0 = float(curve["dcurvature_dpressure"][0])
        pc, smax = critical_pressure(curve)
        send = curve_value(curve, "dcurvature_dpressure", PAPER_PRESSURE_MAX)
        ok &= smax >= 5 * s0 and send <= 0.25 * smax
        rows.append(f"{label}: slope {s0:.3f} at rest, {smax:.2f} at p~_c = {pc:.3f}, {send:.3f} at p~ = 1.2")
        vals[f"max_slope_{label[:6]}"] = smax
    return CheckResult(
        "free_balloon", "main §2-3",
        "Free actuator: the curvature rises slowly, then steeply at a critical pressure (balloon instability), "
        "then saturates (strain stiffening).",
        "; ".join(rows), bool(ok),
        criterion="peak d kappa/dp >= 5x the slope at rest, and the slope at p~ = 1.2 <= 1/4 of the peak",
        values=vals,
    )


def check_soft_follows_free(t: Tables) -> CheckResult:
    fig2 = t["fig2"]
    free = free_curve(fig2)
    scale = float(free["curvature"][-1])
    rows, ok, vals, note = [], True, {}, ""
    for k in [k for k in FIG2_STIFFNESSES if k <= SOFT_MAX]:
        c = object_curve(fig2, k)
        dev = float(np.max(np.abs(c["curvature"] - free["curvature"]))) / scale
        if k < SOFT_MAX:  # the paper's range is strict: k~ < 1e-5
            ok &= dev <= 0.05
        else:
            m = c["in_contact"]
            ratio = c["curvature"][m] / free["curvature"][m]
            j = int(np.argmin(ratio))
            note = (f"At the boundary k~ = {k:g} the object still holds the actuator back before the balloon (at "
                    f"p~ = {float(c['pressure'][m][j]):.2f} kappa~ is {float(ratio[j]):.2f} of the free value) and "
                    f"the graphs separate by {100 * dev:.1f}%; the paper's range is strictly below 1e-5.")
        rows.append(f"k~ = {k:g}: max |kappa - kappa_free| = {100 * dev:.2f}% of kappa_free(1.2)"
                    + ("" if k < SOFT_MAX else " (boundary, not graded)"))
        vals[f"deviation_{k:g}"] = dev
    return CheckResult(
        "soft_follows_free", "main §3",
        "Very compliant objects (k~ < 1e-5): the pressure-curvature graph is almost coincident with the "
        "object-free actuator's.",
        "; ".join(rows), bool(ok), criterion="for Fig. 2's k~ < 1e-5, deviation <= 5% of the free curvature at "
                                             "p~ = 1.2",
        note=note,
        values=vals,
    )


def check_soft_force_saturates(t: Tables) -> CheckResult:
    fig2 = t["fig2"]
    pc, _ = critical_pressure(free_curve(fig2))
    rows, ok, vals = [], True, {}
    for k in [k for k in FIG2_STIFFNESSES if k <= SOFT_MAX]:
        c = object_curve(fig2, k)
        F = c["contact_force"]
        rising = bool(np.all(np.diff(F) >= 0.0))
        e_end = elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
        f_pc, f_end = curve_value(c, "contact_force", pc), float(F[-1])
        ok &= rising and e_end <= SATURATED
        rows.append(f"k~ = {k:g}: F~ = {f_pc:.3g} at p~_c = {pc:.3f}, {f_end:.3g} at 1.2; d ln F/d ln p = "
                    f"{e_end:.3f} at 1.2" + ("" if rising else " (F decreases somewhere)"))
        vals[f"force_elasticity_{k:g}"] = e_end
    return CheckResult(
        "soft_force_saturates", "main §3",
        "Soft objects: the applied force increases as the balloon instability gets underway, then saturates to a "
        "constant value (the tractions stay bounded).",
        "; ".join(rows), bool(ok),
        criterion=f"F never decreases on loading and d ln F / d ln p <= {SATURATED} at p~ = 1.2", values=vals,
    )


def check_stiff_position(t: Tables) -> CheckResult:
    fig2 = t["fig2"]
    free = free_curve(fig2)
    rows, ok, vals = [], True, {}
    for k in [k for k in FIG2_STIFFNESSES if k >= STIFF_MIN]:
        c = object_curve(fig2, k)
        dev = float(np.max(c["curvature"])) / OBJECT_CURVATURE - 1.0
        ok &= dev <= 0.2
        rows.append(f"k~ = {k:g}: kappa~ <= {float(np.max(c['curvature'])):.4f} ({100 * dev:.1f}% above kappa_obj)")
        vals[f"curvature_excess_{k:g}"] = dev
    rows.append(f"free actuator: {float(free['curvature'][-1]):.3f} at 1.2")
    return CheckResult(
        "stiff_position", "main §3",
        "Very stiff objects (k~ >= 1e-3): the actuator's curvature coincides approximately with the object's "
        "(position control).",
        "; ".join(rows), bool(ok), criterion="kappa~ within 20% of w kappa_obj = 0.02 up to p~ = 1.2", values=vals,
    )


def check_stiff_force_monotone(t: Tables) -> CheckResult:
    fig2 = t["fig2"]
    rows, ok, vals = [], True, {}
    for k in [k for k in FIG2_STIFFNESSES if k >= STIFF_MIN]:
        c = object_curve(fig2, k)
        m = c["in_contact"]
        F = c["contact_force"][m]
        dF = c["dforce_dpressure"][m]
        mono = bool(F.size > 1 and np.all(np.diff(F) > 0.0) and np.all(dF > 0.0))
        e_end = elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
        ok &= mono and e_end > SATURATED
        rows.append(f"k~ = {k:g}: F~ rises from contact at p~ = {float(c['pressure'][m][0]):.3f} to "
                    f"{float(F[-1]):.3g} at 1.2, d ln F/d ln p = {e_end:.2f} at 1.2")
        vals[f"force_elasticity_{k:g}"] = e_end
    return CheckResult(
        "stiff_force_monotone", "main §3",
        "Very stiff objects: the applied force increases monotonically with the pressure (unboundedly).",
        "; ".join(rows), bool(ok),
        criterion=f"F strictly increasing in contact (also dF/dp > 0) and not saturated at 1.2 "
                  f"(d ln F/d ln p > {SATURATED})",
        values=vals,
    )


def _intermediate(t: Tables) -> tuple[float, Table]:
    ks = [k for k in FIG2_STIFFNESSES if SOFT_MAX < k < STIFF_MIN]
    k = ks[0]
    return k, object_curve(t["fig2"], k)


def check_slaved_then_gives_in(t: Tables) -> CheckResult:
    k, c = _intermediate(t)
    free = free_curve(t["fig2"])
    i = snap_index(c)
    if i is None:
        return CheckResult("slaved_then_gives_in", "main §3", _SLAVED, f"k~ = {k:g}: no snap-through up to 1.2",
                           False, criterion=_SLAVED_CRIT)
    m = c["in_contact"][:i]
    held = c["curvature"][:i][m]
    excess_free = free["curvature"][:i][m] - OBJECT_CURVATURE
    ratio = float(np.max((held - OBJECT_CURVATURE) / excess_free)) if held.size else math.nan
    excess = float(held.max()) / OBJECT_CURVATURE - 1.0 if held.size else math.nan
    F = c["contact_force"][:i][m]
    rising = bool(F.size > 1 and np.all(np.diff(F) > 0))
    ps = float(c["pressure"][i])
    before, after = float(c["curvature"][i - 1]), float(c["curvature"][i])
    ok = held.size > 0 and ratio <= 0.1 and rising and after - before >= 5 * OBJECT_CURVATURE
    return CheckResult(
        "slaved_then_gives_in", "main §3", _SLAVED,
        f"k~ = {k:g} (J = 15): in contact from p~ = {float(c['pressure'][:i][m][0]):.3f} to the snap, "
        f"kappa~ - kappa_obj stays <= {100 * ratio:.1f}% of the free actuator's (kappa~ <= {float(held.max()):.4f}, "
        f"{100 * excess:.0f}% above kappa_obj just before the fold) while F~ rises to {float(F[-1]):.3g}; "
        f"gives in at p~ = {ps:.3f}: kappa~ {before:.4f} -> {after:.3f}",
        bool(ok), criterion=_SLAVED_CRIT, values={"snap_pressure": ps, "held_ratio": ratio, "curvature_excess": excess},
    )


_SLAVED = ("Intermediate objects: once in contact the curvature is slaved to the object's while the force increases; "
           "at some pressure the object gives in and the actuator snaps to a large curvature.")
_SLAVED_CRIT = ("before the snap, kappa~ - kappa_obj <= 10% of the free actuator's kappa~_free - kappa_obj at the same "
                "pressure (the object, not the pressure, sets the shape) and F strictly rising; the snap jumps by "
                ">= 5 kappa_obj")


def check_snap_hysteresis(t: Tables) -> CheckResult:
    k, c = _intermediate(t)
    i = snap_index(c)
    p_up = float(c["pressure"][i]) if i is not None else None
    p_down = unload_snap_pressure(t["fig2"], object_stiffness=k)
    ok = p_up is not None and p_down is not None and p_down < p_up
    measured = (f"k~ = {k:g}: snaps up at p~ = {p_up:.3f} on loading, back down at p~ = {p_down:.3f} on unloading "
                f"(window {p_up - p_down:.3f})" if ok else f"k~ = {k:g}: loading snap {p_up}, unloading snap {p_down}")
    return CheckResult(
        "snap_hysteresis", "main §3 (model.md)",
        "The give-in is a fold of the equilibrium path: loading and unloading follow different branches "
        "(hysteresis).",
        measured, bool(ok), criterion="a snap on unloading at a lower pressure than on loading",
        values={"window": (p_up - p_down) if ok else math.nan},
    )


def check_after_give_in(t: Tables) -> CheckResult:
    k, c = _intermediate(t)
    free = free_curve(t["fig2"])
    i = snap_index(c)
    if i is None:
        return CheckResult("after_give_in", "main §3", _AFTER, "no snap", False, criterion=_AFTER_CRIT)
    dev = float(np.max(np.abs(c["curvature"][i:] / free["curvature"][i:] - 1.0)))
    e_end = elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
    ok = dev <= 0.03 and e_end <= SATURATED
    return CheckResult(
        "after_give_in", "main §3", _AFTER,
        f"k~ = {k:g}: after the snap kappa~ is within {100 * dev:.2f}% of the free actuator's; F~ = "
        f"{float(c['contact_force'][-1]):.3g} at 1.2 with d ln F/d ln p = {e_end:.3f}",
        bool(ok), criterion=_AFTER_CRIT, values={"deviation": dev, "force_elasticity": e_end},
    )


_AFTER = ("After the object gives in, the curvature changes as if the actuator were not grasping anything, until the "
          "applied force saturates.")
_AFTER_CRIT = f"post-snap curvature within 3% of the free actuator's; d ln F/d ln p <= {SATURATED} at 1.2"


def check_give_in_pressure(t: Tables) -> CheckResult:
    rm = t["regime_map"]
    pc, _ = critical_pressure(free_curve(t["fig2"]))
    snaps = []
    for k in sorted(set(rm["object_stiffness"].tolist())):
        c = loading(rm, object_stiffness=k)
        i = snap_index(c)
        if i is not None:
            snaps.append((k, float(c["pressure"][i])))
    if not snaps:
        return CheckResult("give_in_pressure", "main §3", _GIVE, "no snap on the regime map", False,
                           criterion=_GIVE_CRIT)
    ps = [p for _, p in snaps]
    far = max(abs(p - pc) for p in ps)
    ok = max(ps) - min(ps) >= 0.2 and far >= 0.2
    return CheckResult(
        "give_in_pressure", "main §3", _GIVE,
        f"snap pressures from {min(ps):.3f} (k~ = {snaps[int(np.argmin(ps))][0]:.2g}) to {max(ps):.3f} "
        f"(k~ = {snaps[int(np.argmax(ps))][0]:.2g}); free p~_c = {pc:.3f}",
        bool(ok), criterion=_GIVE_CRIT, values={"min": min(ps), "max": max(ps), "critical": pc},
    )


_GIVE = "The object gives in at a pressure 'not necessarily related to that of the balloon instability'."
_GIVE_CRIT = "over the regime map's stiffnesses the snap pressure spans >= 0.2 and reaches >= 0.2 away from p~_c"


def check_switch(t: Tables) -> CheckResult:
    rm = t["regime_map"]
    top = rm.where(branch="loading", model="full")
    top = top.take(np.isclose(top["pressure"], PAPER_PRESSURE_MAX))
    order = np.argsort(top["object_stiffness"])
    ks, reg = top["object_stiffness"][order], top["regime"][order]
    force = ks[reg == "force-controlled"]
    pos = ks[reg == "position-controlled"]
    soft_ok = bool(np.all(reg[ks <= SOFT_MAX] == "force-controlled"))
    stiff_ok = bool(np.all(reg[ks >= 1e-2] == "position-controlled"))
    k_force = float(force.max()) if force.size else math.nan
    k_pos = float(pos.min()) if pos.size else math.nan
    ordered = force.size > 0 and pos.size > 0 and k_force < k_pos
    ok = soft_ok and stiff_ok and ordered and SOFT_MAX <= k_force and k_pos <= 1e-2
    between = sorted(set(reg[(ks > k_force) & (ks < k_pos)].tolist())) if ordered else []
    return CheckResult(
        "switch", "main §3 / abstract",
        "The grasper switches automatically from force control (soft objects) to position control (stiff objects); "
        "the transition occurs at intermediate k~.",
        f"at p~ = 1.2: force-controlled up to k~ = {k_force:.3g}, position-controlled from k~ = {k_pos:.3g}"
        + (f" (between: {', '.join(between)})" if between else ""),
        bool(ok),
        criterion="regime map at p~ = 1.2: every k~ <= 1e-5 force-controlled, every k~ >= 1e-2 position-controlled, "
                  "one switch in between",
        values={"force_max": k_force, "position_min": k_pos},
    )


def check_modulus_scaling(t: Tables) -> CheckResult:
    c = PAPER_MODULUS_PER_STIFFNESS_PA
    k15 = object_stiffness_from_material(15.0, OBJECT_THICKNESS_MM, OBJECT_CURVATURE_PER_M, Scales())
    k1 = object_stiffness_from_material(1.5, OBJECT_THICKNESS_MM, OBJECT_CURVATURE_PER_M, Scales())
    ok = abs(c / 1.5e7 - 1.0) <= 0.05
    return CheckResult(
        "modulus_scaling", "main §3, eq. 3.3",
        "mu_obj ~ 1.5e7 k~ Pa (H = 1 cm, mu = 50 kPa, w = 5 mm, w kappa_obj = 0.02).",
        f"mu_obj / k~ = {c:.4g} Pa (eq. 3.2); 15 kPa -> k~ = {k15:.3g}, 1.5 kPa -> k~ = {k1:.3g}",
        bool(ok), criterion="within 5% of 1.5e7 Pa", values={"modulus_per_stiffness_pa": c},
    )


def check_materials(t: Tables) -> CheckResult:
    fig2 = t["fig2"]
    k15 = object_stiffness_from_material(15.0, OBJECT_THICKNESS_MM, OBJECT_CURVATURE_PER_M, Scales())
    k1 = object_stiffness_from_material(1.5, OBJECT_THICKNESS_MM, OBJECT_CURVATURE_PER_M, Scales())
    # Fig. 2's decades nearest to the two materials (within 5%).
    ks = np.array(FIG2_STIFFNESSES)
    stiff_k = float(ks[np.argmin(np.abs(np.log(ks / k15)))])
    soft_k = float(ks[np.argmin(np.abs(np.log(ks / k1)))])
    s, g = object_curve(fig2, stiff_k), object_curve(fig2, soft_k)
    excess = float(np.max(s["curvature"])) / OBJECT_CURVATURE - 1.0
    e_stiff = elasticity(s, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
    k_soft_end = float(g["curvature"][-1])
    e_soft = elasticity(g, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
    delta_mm = float(s["indentation"][-1]) * TABLE1_WIDTH_MM
    ok = (abs(stiff_k / k15 - 1) <= 0.05 and abs(soft_k / k1 - 1) <= 0.05 and excess <= 0.2 and e_stiff > 1.0
          and k_soft_end >= 5 * OBJECT_CURVATURE and e_soft <= SATURATED)
    return CheckResult(
        "materials", "main §3",
        "A 15 kPa elastomer (k~ >= 1e-3) is grasped without being deformed while the traction grows unboundedly; "
        "a gel or foam below 1.5 kPa (k~ < 1e-4) deforms a lot, with bounded traction.",
        f"k~ = {stiff_k:g}: kappa~ within {100 * excess:.1f}% of kappa_obj, d ln F/d ln p = {e_stiff:.2f} at 1.2; "
        f"k~ = {soft_k:g}: kappa~ = {k_soft_end:.3f} = {k_soft_end / OBJECT_CURVATURE:.0f} kappa_obj at 1.2, "
        f"d ln F/d ln p = {e_soft:.3f}",
        bool(ok),
        criterion="stiff: curvature within 20% of kappa_obj and d ln F/d ln p > 1; soft: kappa >= 5 kappa_obj and "
                  f"d ln F/d ln p <= {SATURATED} at p~ = 1.2 (Fig. 2, J = 15)",
        note=(f"'Without being deformed' holds for the curvature only: the Winkler indentation "
              f"delta = 1/kappa_obj - 1/kappa of the 15 kPa object is {delta_mm:.0f} mm at p~ = 1.2 (w = 5 mm), "
              f"{'more' if delta_mm > OBJECT_THICKNESS_MM else 'less'} than its thickness H = "
              f"{OBJECT_THICKNESS_MM:g} mm: a small change of curvature is a large displacement on an object of "
              f"radius 1/kappa_obj = {1e3 / OBJECT_CURVATURE_PER_M:g} mm."),
        values={"stiff_curvature_excess": excess, "indentation_mm": delta_mm},
    )
