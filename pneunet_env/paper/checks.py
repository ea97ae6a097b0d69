"""The seed paper's qualitative statements, each measured on the figure data and marked ✓ or ✗.

Every check is a function of the figure tables (:func:`pneunet_env.paper.figures.generate`'s output, or the CSVs
read back with :func:`pneunet_env.paper.figures.load_tables`) that returns a :class:`CheckResult`: the
statement (quoted or paraphrased, with its section), the number(s) this package measures for it, whether
it holds in this model, and whether it is expected to (a statement the model contradicts is kept, marked ✗,
with the reason in its note). :func:`render_markdown` makes the statements table (docs/figures.md).

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

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from pneunet_env.paper.figures import (
    FIG2_STIFFNESSES,
    FIGURES,
    OBJECT_CURVATURE,
    PAPER_PRESSURE_MAX,
    TABLE1_WIDTH_MM,
    Table,
    critical_pressure,
    curve_value,
    loading,
    unloading,
)
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.units import PAPER_MODULUS_PER_STIFFNESS_PA, Scales, object_stiffness_from_material

__all__ = ["CHECKS", "CheckResult", "SATURATED", "render_markdown", "run_checks"]

SATURATED = 0.1
"""A force (or curvature) has saturated when its elasticity ``d ln X / d ln p`` is at most this."""

SOFT_MAX = 1e-5
"""The paper's "very compliant" objects: ``k~ <= 1e-5``."""

STIFF_MIN = 1e-3
"""The paper's "very stiff" objects: ``k~ >= 1e-3``."""

OBJECT_THICKNESS_MM = 10.0
"""Section 3's object thickness ``H`` (1 cm)."""

OBJECT_CURVATURE_PER_M = 4.0
"""Table 1's ``kappa_obj`` (1/m)."""


@dataclass(frozen=True)
class CheckResult:
    """One statement of the paper, measured.

    Attributes:
        key: short identifier.
        source: where the paper says it (``main §3``, ``supp. §4``...).
        statement: the statement, quoted or paraphrased.
        measured: the numbers this package measures, as text.
        passed: whether the statement holds in this model by the stated criterion.
        expected: whether it is expected to hold (``False``: a known disagreement, explained in ``note``).
        criterion: how "holds" is decided.
        note: why it fails, or a caveat.
        values: the measured numbers, by name.
    """

    key: str
    source: str
    statement: str
    measured: str
    passed: bool
    expected: bool = True
    criterion: str = ""
    note: str = ""
    values: dict[str, float] = field(default_factory=dict)

    @property
    def mark(self) -> str:
        return "✓" if self.passed else "✗"


Tables = Mapping[str, Table]


# --------------------------------------------------------------------------------------------- helpers


def _sweep(table: Table, sweep: str) -> list[tuple[float, Table]]:
    """``(value, loading curve)`` for each curve of a sweep, in increasing parameter value."""
    sub = table.where(sweep=sweep)
    values = sorted(set(sub["sweep_value"].tolist()))
    return [(v, loading(sub, sweep_value=v)) for v in values]


def _elasticity(curve: Table, column: str, derivative: str, pressure: float) -> float:
    """``d ln X / d ln p`` of ``column`` at ``pressure`` (exact tangent, interpolated on the grid)."""
    x = curve_value(curve, column, pressure)
    dx = curve_value(curve, derivative, pressure)
    return pressure * dx / x if x > 0 else math.inf


def _increasing(ys: Sequence[float]) -> bool:
    return all(b > a for a, b in zip(ys, ys[1:], strict=False))


def _decreasing(ys: Sequence[float]) -> bool:
    return all(b < a for a, b in zip(ys, ys[1:], strict=False))


def _nums(xs: Sequence[float], fmt: str = ".3f") -> str:
    return ", ".join("inf (snap)" if math.isinf(x) else format(x, fmt) for x in xs)


def _vals(xs: Sequence[float]) -> str:
    return ", ".join(f"{x:g}" for x in xs)


def _object(table: Table, k: float) -> Table:
    return loading(table, object_stiffness=k)


def _free(table: Table) -> Table:
    return loading(table, object_stiffness=0.0)


def _snap_index(curve: Table) -> int | None:
    s = np.flatnonzero(curve["snapped"])
    return int(s[0]) if s.size else None


def _unload_snap_pressure(table: Table, **conditions) -> float | None:
    un = unloading(table, **conditions)
    s = np.flatnonzero(un["snapped"])
    return float(un["pressure"][s].max()) if s.size else None


# --------------------------------------------------------------------------------------------- checks


def check_free_balloon(t: Tables) -> CheckResult:
    rows, ok, vals = [], True, {}
    for label, curve in (("J = 15 (Fig. 2)", _free(t["fig2"])), ("J = 20 (Fig. 3)", loading(t["supp_fig3"]))):
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
    free = _free(fig2)
    scale = float(free["curvature"][-1])
    rows, ok, vals, note = [], True, {}, ""
    for k in [k for k in FIG2_STIFFNESSES if k <= SOFT_MAX]:
        c = _object(fig2, k)
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
    pc, _ = critical_pressure(_free(fig2))
    rows, ok, vals = [], True, {}
    for k in [k for k in FIG2_STIFFNESSES if k <= SOFT_MAX]:
        c = _object(fig2, k)
        F = c["contact_force"]
        rising = bool(np.all(np.diff(F) >= 0.0))
        e_end = _elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
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
    free = _free(fig2)
    rows, ok, vals = [], True, {}
    for k in [k for k in FIG2_STIFFNESSES if k >= STIFF_MIN]:
        c = _object(fig2, k)
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
        c = _object(fig2, k)
        m = c["in_contact"]
        F = c["contact_force"][m]
        dF = c["dforce_dpressure"][m]
        mono = bool(F.size > 1 and np.all(np.diff(F) > 0.0) and np.all(dF > 0.0))
        e_end = _elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
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
    return k, _object(t["fig2"], k)


def check_slaved_then_gives_in(t: Tables) -> CheckResult:
    k, c = _intermediate(t)
    free = _free(t["fig2"])
    i = _snap_index(c)
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
    i = _snap_index(c)
    p_up = float(c["pressure"][i]) if i is not None else None
    p_down = _unload_snap_pressure(t["fig2"], object_stiffness=k)
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
    free = _free(t["fig2"])
    i = _snap_index(c)
    if i is None:
        return CheckResult("after_give_in", "main §3", _AFTER, "no snap", False, criterion=_AFTER_CRIT)
    dev = float(np.max(np.abs(c["curvature"][i:] / free["curvature"][i:] - 1.0)))
    e_end = _elasticity(c, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
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
    pc, _ = critical_pressure(_free(t["fig2"]))
    snaps = []
    for k in sorted(set(rm["object_stiffness"].tolist())):
        c = loading(rm, object_stiffness=k)
        i = _snap_index(c)
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
    s, g = _object(fig2, stiff_k), _object(fig2, soft_k)
    excess = float(np.max(s["curvature"])) / OBJECT_CURVATURE - 1.0
    e_stiff = _elasticity(s, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
    k_soft_end = float(g["curvature"][-1])
    e_soft = _elasticity(g, "contact_force", "dforce_dpressure", PAPER_PRESSURE_MAX)
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


def _monotone_check(t: Tables, key, source, statement, figure, sweep, label, measure, increasing: bool,
                    criterion: str, expected: bool = True, note: str = "", physical: bool = False) -> CheckResult:
    rows = _sweep(t[figure], sweep)
    xs = [x for x, _ in rows]
    ys = [measure(c) for _, c in rows]
    ok = _increasing(ys) if increasing else _decreasing(ys)
    return CheckResult(
        key, source, statement, f"{label} = {_vals(xs)}: {_nums(ys)}", bool(ok), expected=expected,
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
    rows = _sweep(t["supp_fig2cd"], "gent_limit")
    snaps = {j: _snap_index(c) is not None for j, c in rows}
    table = t["supp_fig2cd"]
    jmax = max(snaps)
    top = dict(rows)[jmax]
    i_up = _snap_index(top)
    p_up = float(top["pressure"][i_up]) if i_up is not None else math.nan
    p_down = _unload_snap_pressure(table, sweep="gent_limit", sweep_value=jmax)
    small = [j for j in snaps if j <= 20.0]
    ok = snaps[jmax] and p_down is not None and p_down < p_up and not any(snaps[j] for j in small)
    return CheckResult(
        "snap_gent", "main §4",
        "Increasing J allows larger curvatures, 'but it may snap owing to transient instabilities where the geometric "
        "softening is not counterbalanced by strain stiffening'.",
        f"snap on loading for J = {_vals([j for j, s in snaps.items() if s]) or 'none'}"
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
    curves = [c["curvature"] for _, c in _sweep(t[figure], sweep)]
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
