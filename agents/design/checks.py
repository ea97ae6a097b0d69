"""The design study's findings, as checked statements beside the paper's (``docs/figures.md``).

The seed paper's §4 says how the walls and the Gent limit shape the pressure-curvature curve
(:mod:`pneunet_env.paper.checks` measures those statements on the figure data). These are the statements one
level up, on blind grasping: each is measured here by controlled sweeps (one parameter changed on Table 1's
actuator, every other fixed) with the batched design evaluation (:func:`agents.design.evaluate_design`) on the
use case's search objects, and marked ✓ or ✗ by the stated criterion. ``pneunet-grasp design --checks`` prints
the table (``--out DIR``: also ``DIR/checks.md`` and ``DIR/checks.json``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig
from pneunet_env.paper.checks import CheckResult, render_markdown

__all__ = ["GENT_SWEEP", "TOP_SWEEP", "run_design_checks", "render_markdown"]

GENT_SWEEP = (6.0, 10.0, 15.0, 20.0, 30.0, 50.0, 80.0)
"""Gent limits swept on Table 1's actuator (``mu`` 50 kPa; a model sweep, not a catalogue of materials)."""
TOP_SWEEP = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5)
"""Top wall thicknesses swept on Table 1's actuator (mm)."""


FINGER_KEYS = ("finger_width_mm", "length_mm", "grip_faces")
"""The finger in 3D: swept one at a time to the ends of their sourced ranges on Table 1's cell."""
_FINGER_LABEL = {"finger_width_mm": "width (mm)", "length_mm": "length (mm)", "grip_faces": "fingers"}


def _t1(**changes: Any) -> dict[str, Any]:
    from agents.design.space import table1_design

    p = table1_design()
    p.pop("elastomer")
    return {**p, "shear_modulus_kpa": 50.0, "gent_limit": 20.0, **changes}


def run_design_checks(n_objects: int = 200, seed: int = 0, base: EnvConfig | None = None) -> list[CheckResult]:
    """Measure every statement on ``n_objects`` search objects of ``base``'s use case (the default task's kitchen)."""
    from agents.design.score import evaluate_design, reference_regimes
    from agents.design.space import DESIGN_SPACE, finger_width_range
    from agents.evaluation.batch import episode_seeds
    from pneunet_env.config import load_config

    # each finger range's ends; the width no wider than the narrowest object, as in a study (refused first, by name)
    ends = {b.key: (b.low, b.high) for b in DESIGN_SPACE if b.key in FINGER_KEYS}
    ends["finger_width_mm"] = finger_width_range({}, load_config() if base is None else base)
    seeds = episode_seeds(n_objects, seed)
    ref = reference_regimes(seeds, base)
    gent = {j: evaluate_design(_t1(gent_limit=j), seeds, ref, base, seed) for j in GENT_SWEEP}
    top = {h: evaluate_design(_t1(top_thickness_mm=h), seeds, ref, base, seed) for h in TOP_SWEEP}
    win = {j: s.window_fraction for j, s in gent.items()}
    step = float(np.mean([s.pressures_kpa[1] - s.pressures_kpa[0] for s in gent.values()]) / gent[20.0].pressure_kpa)
    low = float(np.mean([w for j, w in win.items() if j <= 10]))
    high = float(np.mean([w for j, w in win.items() if j >= 20]))
    force = {j: s.blind["force"] for j, s in gent.items()}
    press = {h: s.pressure_kpa for h, s in top.items()}
    tforce = {h: s.blind["force"] for h, s in top.items()}
    fmt = lambda d, f: ", ".join(f"{k:g}: {f(v)}" for k, v in d.items())  # noqa: E731
    pct = lambda v: f"{v:.0%}"  # noqa: E731
    t1 = _t1()
    finger = {(k, v): evaluate_design({**t1, k: v}, seeds, ref, base, seed) for k, vs in ends.items()
              for v in dict.fromkeys(vs) if v != t1[k]}
    nominal = gent[20.0]  # Table 1's actuator
    slab = evaluate_design(t1, seeds, ref, load_config(base, hold_rule="slab"), seed)
    worst_label = min(nominal.corners, key=lambda k: min(nominal.corners[k]["force"], nominal.corners[k]["position"]))
    worst = nominal.worst_corner
    return [
        CheckResult(
            "design_weight_rule", "this package (0.14: the hold rule carries the object's weight)",
            "Scored by the object's weight in 3D, not a slab of depth H, Table 1's blind ramp holds fewer "
            "force-controlled objects",
            f"blind force-controlled success: {slab.blind['force']:.0%} under the slab rule (at "
            f"{slab.pressure_kpa:.1f} kPa) against {nominal.blind['force']:.0%} under the weight rule (at "
            f"{nominal.pressure_kpa:.1f} kPa); position-controlled {slab.blind['position']:.0%} against "
            f"{nominal.blind['position']:.0%}",
            nominal.blind["force"] < slab.blind["force"] - 0.05,
            criterion="the weight rule's force-controlled success is at least 5 points below the slab rule's",
            values={"force_slab": slab.blind["force"], "force_weight": nominal.blind["force"]}),
        CheckResult(
            "design_finger_3d", "issue: a design a lab could build (the finger's width, length and count)",
            "A wider finger, a longer one and a third finger each hold at least as many objects blind: the hold "
            "rule gains from each and the model charges nothing for them",
            f"Table 1's cell, blind success all / force-controlled (each at its own best blind pressure): nominal "
            f"(10 mm wide, 90 mm long, 2 fingers) {nominal.blind['all']:.0%} / {nominal.blind['force']:.0%}; "
            + "; ".join(f"{_FINGER_LABEL[k]} {v:g}: {s.blind['all']:.0%} / {s.blind['force']:.0%}"
                        for (k, v), s in finger.items()),
            all(s.blind["all"] >= nominal.blind["all"] - 0.01 for (k, v), s in finger.items() if v > t1[k]),
            criterion="every end above Table 1's (wider, longer, three fingers) holds no fewer objects than Table 1 "
            "(within one object in a hundred: the blind pressure is re-chosen on a grid)",
            note="so the model's answer for the finger is the top of each sourced range (what bounds it in a lab, "
                 "the gripper's size and cost, lies outside the model); at the design studies' worst corners, which "
                 "the material sets, it moves the success by at most a few points (docs/design.md)",
            values={f"all_{k}_{v:g}": s.blind["all"] for (k, v), s in finger.items()}),
        CheckResult(
            "design_table1_corners", "issue: a design a lab could build (worst corner >= 80 % in each regime)",
            "Table 1's blind ramp survives its manufacturing corners (walls +-10 %, modulus +-20 %, the "
            f"regulator's +-{nominal.pressure_error_kpa:g} kPa)",
            f"worst corner: force {worst['force']:.0%}, position {worst['position']:.0%} ({worst_label}); every "
            "corner: " + "; ".join(f"{k} {v['force']:.0%}/{v['position']:.0%}" for k, v in nominal.corners.items()),
            min(worst["force"], worst["position"]) >= 0.80,
            criterion="the worst corner holds at least 80 % of the objects in each regime", expected=False,
            note="" if min(worst["force"], worst["position"]) >= 0.80 else
                 f"a finding: at its worst corner ({worst_label}) Table 1's blind ramp holds "
                 f"{worst['all']:.0%} of the objects",
            values={"worst_force": worst["force"], "worst_position": worst["position"]}),
        CheckResult(
            "design_gent_window", "main §4 (a lower J smooths the balloon jump), on blind grasping",
            "A low Gent limit widens the window of blind pressures that hold the objects",
            f"window within 5 points of the best, as a share of the best pressure, by J: {fmt(win, pct)}; "
            f"mean {low:.1%} for J <= 10 against {high:.1%} for J >= 20 (one grid step: {step:.1%})",
            low > high + step, criterion="the mean window of J <= 10 is wider than that of J >= 20 by more than one "
            "step of the pressure grid (1/60 of p_max, over Table 1's best pressure); Table 1's geometry, mu 50 kPa",
            # a known disagreement: read across random designs (0.6), not borne out on Table 1's geometry alone
            expected=False,
            note=("not supported by this sweep: the means differ by less than one grid step; a window is measured "
                  "around the best pressure whatever its success, so the wide window at J = 80 is that of a poor "
                  "best (6 % of the force-controlled objects)") if not low > high + step else
                 "holds here, although the 200-object sweep of 0.6 did not bear it out",
            values={f"window_J{j:g}": w for j, w in win.items()}),
        CheckResult(
            "design_gent_snap", "main §4 (a larger J may snap), on blind grasping",
            "A Gent limit past the snap limit breaks blind grasping of force-controlled objects",
            f"best blind ramp's force-controlled success by J: {fmt(force, pct)}",
            force[80.0] < force[20.0] - 0.10,
            criterion="at J = 80 the best blind ramp holds at least 10 points fewer force-controlled objects than "
            "at J = 20", values={f"force_J{j:g}": v for j, v in force.items()}),
        CheckResult(
            "design_top_pressure", "main §4, Fig. 3a (a thinner top wall lowers the balloon pressure), on blind "
            "grasping", "A thinner top wall lowers the blind pressure that grasps best",
            f"best blind pressure (kPa) by top wall (mm): {fmt(press, lambda v: f'{v:.1f}')}",
            bool(np.all(np.diff(list(press.values())) >= 0)),
            criterion="the best blind pressure does not fall as the top wall thickens",
            values={f"pressure_hm{h:g}": v for h, v in press.items()}),
        CheckResult(
            "design_top_force", "this package (the README's open question)",
            "Table 1's force-controlled limit is the actuator's: a thinner top wall holds more force-controlled "
            "objects blind",
            f"force-controlled success by top wall (mm): {fmt(tforce, pct)}",
            tforce[min(TOP_SWEEP)] > tforce[2.5] + 0.05,
            criterion=f"at h_m = {min(TOP_SWEEP):g} mm the best blind ramp holds at least 5 points more "
            "force-controlled objects than Table 1's 2.5 mm",
            values={f"force_hm{h:g}": v for h, v in tforce.items()}),
    ]
