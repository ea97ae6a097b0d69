"""An experimental anchor: the model against the one published pneu-net measurement with numbers we could read.

**The measurement** (Shintake J., Sonar H., Piskarev E., Paik J., Floreano D. (2017) Soft pneumatic gelatin
actuator for edible robotics, IROS 2017, arXiv:1703.01423, its abstract): a monolithic gelatin-glycerol pneu-net
bending actuator, 90 mm long, 20 mm wide and 17 mm thick, bends by **170.3 degrees** and blocks a force of
**0.34 N** at **25 kPa**; its material's "mechanical characteristics [are] similar to those of silicone elastomers".
Its chamber pitch, wall thicknesses, modulus and strain stiffening are not in what could be read (nor is where the
force was measured).

**So nothing is fitted.** Every unknown is swept over a stated plausible range (:data:`PITCHES_MM`,
:data:`WALLS_MM`, :data:`MODULI_KPA`, :data:`GENT_LIMITS`) and the ratio model / measured is reported over the
sweep: a bracket, not a calibration. The mapping onto :class:`~pneunet_env.physics.units.PhysicalActuator`: all
walls ``h``; the finger's width ``t + 2 h = 20`` mm; its thickness ``h_b/2 + d + h_m/2 = 17`` mm; one material
throughout (``E_b = 3 mu``: the model still takes the base as inextensible); the whole 90 mm bending at one
curvature.

* **Free bending angle** ``theta = kappa L``: the free equilibrium at 25 kPa, loaded from rest.
* **Blocked tip force**: the finger held straight, each cell's actuation moment ``M = mu t w^2 (-dU~/dkappa~)`` at
  ``kappa = 0`` (the side wall's strain relaxed along its loading branch), balanced by a tip force ``M / L`` at the
  root. A linear propped cantilever under the same uniform actuation moment takes ``1.5 M / L`` at its tip: the
  figure is if anything low.

A traction against a rigid arc is not a blocked-force model (it scales as ``(w kappa_obj)^2`` and vanishes against
a flat load cell), so it is not used. ``python -m pneunet_env.paper.anchor`` prints the tables of ``docs/physics.md``
("An experimental anchor").
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
from dataclasses import asdict, dataclass

import numpy as np

from pneunet_env.physics.solver import evaluate_state, params_tuple, solve_equilibrium
from pneunet_env.physics.units import PhysicalActuator

SOURCE = ("Shintake, Sonar, Piskarev, Paik, Floreano (2017), Soft pneumatic gelatin actuator for edible robotics, "
          "IROS 2017, arXiv:1703.01423 (abstract)")
PRESSURE_KPA = 25.0
ANGLE_DEG = 170.3
BLOCKED_FORCE_N = 0.34
LENGTH_MM, WIDTH_MM, THICKNESS_MM = 90.0, 20.0, 17.0
"""The measured actuator and what it did at :data:`PRESSURE_KPA` (:data:`SOURCE`)."""

PITCHES_MM = (5.0, 10.0, 15.0)
"""The chamber pitch ``w``, not given: the seed paper's 5 mm to the Soft Robotics Toolkit's 15 mm chamber."""
WALLS_MM = (1.0, 2.0, 3.0)
"""Every wall ``h``, not given: cast pneu-net walls of 1-2 mm (``elastomers.yaml``) to past the seed's 2.5 mm."""
MODULI_KPA = (10.0, 20.0, 40.0, 80.0, 160.0)
"""The shear modulus ``mu``, not given: ``E = 3 mu`` = 30-480 kPa, the silicones of ``elastomers.yaml`` (mu 15.7 to
215 kPa) that the abstract compares the gelatin to."""
GENT_LIMITS = (10.0, 20.0, 50.0)
"""The Gent limit ``J``, not given: ``elastomers.yaml``'s silicone fits give 15-49."""


def anchor_actuator(pitch_mm: float, wall_mm: float, modulus_kpa: float, gent_limit: float) -> PhysicalActuator:
    """The measured actuator at one point of the sweep (the mapping of the module docstring)."""
    return PhysicalActuator(
        width_mm=pitch_mm, chamber_height_mm=THICKNESS_MM - wall_mm, depth_mm=WIDTH_MM - 2.0 * wall_mm,
        base_thickness_mm=wall_mm, side_thickness_mm=wall_mm, top_thickness_mm=wall_mm,
        shear_modulus_kpa=modulus_kpa, base_modulus_kpa=3.0 * modulus_kpa, poisson_ratio=0.5,
        gent_limit=gent_limit, length_mm=LENGTH_MM)


def _downhill_strain(kappa: float, start: float, pressure: float, prm) -> float | None:
    """The side wall's strain at the local minimum of ``U~(kappa~ fixed, e_s)`` downhill from ``start``: bracketed
    by doubling steps (halved where a step leaves the energy's domain), then bisected on ``dU~/de_s``."""
    g0 = evaluate_state(kappa, start, pressure, prm, 0.0, 1.0)
    if not g0.ok:
        return None
    if g0.g_strain == 0.0:
        return start
    sign = -1.0 if g0.g_strain > 0.0 else 1.0
    lo, step = start, 1e-4
    while True:
        hi = lo + sign * step
        ev = evaluate_state(kappa, hi, pressure, prm, 0.0, 1.0)
        if not ev.ok:
            step *= 0.5
            if step < 1e-15:
                return None
            continue
        if sign * ev.g_strain >= 0.0:  # the slope changed sign: the minimum lies between lo and hi
            break
        lo, step = hi, 2.0 * step
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if sign * evaluate_state(kappa, mid, pressure, prm, 0.0, 1.0).g_strain >= 0.0:
            hi = mid
        else:
            lo = mid
        if abs(hi - lo) < 1e-15:
            break
    return 0.5 * (lo + hi)


def straight_moment(pressure: float, prm, steps: int = 50) -> float:
    """``-dU~/dkappa~`` at ``kappa~ = 0`` (the finger held straight), with the side wall's strain followed from rest
    to ``pressure`` (``p~``) in ``steps`` increments, each to the minimum downhill from the last (a fold makes it
    jump, as the loading path does). NaN where the relaxation fails or ends off a checked minimum."""
    strain = 0.0
    for p in np.linspace(0.0, pressure, steps + 1)[1:]:
        strain = _downhill_strain(0.0, strain, float(p), prm)
        if strain is None:
            return math.nan
    ev = evaluate_state(0.0, strain, pressure, prm, 0.0, 1.0)
    if not (ev.ok and ev.h_ss > 0.0 and abs(ev.g_strain) < 1e-8):
        return math.nan
    return -ev.g_kappa


@dataclass(frozen=True)
class AnchorPoint:
    """One point of the sweep: the unknowns, and the model's angle (degrees) and blocked tip force (N) at
    :data:`PRESSURE_KPA`, each with its ratio to the measurement."""

    pitch_mm: float
    wall_mm: float
    modulus_kpa: float
    gent_limit: float
    converged: bool
    snapped: bool
    angle_deg: float
    tip_force_n: float

    @property
    def angle_ratio(self) -> float:
        return self.angle_deg / ANGLE_DEG

    @property
    def force_ratio(self) -> float:
        return self.tip_force_n / BLOCKED_FORCE_N


def anchor_point(pitch_mm: float, wall_mm: float, modulus_kpa: float, gent_limit: float) -> AnchorPoint:
    """The model's free angle and blocked tip force for the measured actuator at one point of the sweep."""
    act = anchor_actuator(pitch_mm, wall_mm, modulus_kpa, gent_limit)
    params = act.to_dimensionless()
    p = PRESSURE_KPA / modulus_kpa
    free = solve_equilibrium(p, 0.0, 0.02, params)
    angle = math.degrees(free.curvature / pitch_mm * LENGTH_MM)  # kappa = kappa~ / w (1/mm)
    moment_nmm = modulus_kpa * act.depth_mm * pitch_mm ** 2 * straight_moment(p, params_tuple(params)) * 1e-3
    return AnchorPoint(pitch_mm, wall_mm, modulus_kpa, gent_limit, bool(free.converged), bool(free.snapped), angle,
                       moment_nmm / LENGTH_MM)


def sweep() -> list[AnchorPoint]:
    """Every point of the sweep (135: pitch x wall x modulus x Gent limit)."""
    return [anchor_point(*pt) for pt in itertools.product(PITCHES_MM, WALLS_MM, MODULI_KPA, GENT_LIMITS)]


def _spread(values) -> tuple[float, float, float]:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    return (float(v.min()), float(np.median(v)), float(v.max())) if v.size else (math.nan,) * 3


def summary(points: list[AnchorPoint]) -> dict:
    """Min, median and max of each ratio, overall and by modulus; and the force ratio where the angle matches."""
    near = [p for p in points if 0.8 < p.angle_ratio < 1.25]
    return {
        "points": len(points), "converged": sum(p.converged for p in points),
        "snapped": sum(p.snapped for p in points),
        "angle_ratio": _spread(p.angle_ratio for p in points),
        "force_ratio": _spread(p.force_ratio for p in points),
        "by_modulus": {f"{mu:g}": {"angle_ratio": _spread(p.angle_ratio for p in points if p.modulus_kpa == mu),
                                   "force_ratio": _spread(p.force_ratio for p in points if p.modulus_kpa == mu)}
                       for mu in MODULI_KPA},
        "angle_within_0.8_1.25": {"points": len(near), "force_ratio": _spread(p.force_ratio for p in near)},
    }


def render(s: dict) -> str:
    """The summary as the markdown table of ``docs/physics.md``."""
    f = lambda t: " / ".join(f"{x:.3g}" for x in t)  # noqa: E731
    lines = [f"{s['points']} points ({s['converged']} free solves converged, {s['snapped']} crossed the balloon "
             f"fold); model / measured at {PRESSURE_KPA:g} kPa, min / median / max:", "",
             "| modulus mu (kPa) | angle ratio (measured 170.3 deg) | blocked-force ratio (measured 0.34 N) |",
             "|---|---|---|"]
    lines += [f"| {mu} | {f(v['angle_ratio'])} | {f(v['force_ratio'])} |" for mu, v in s["by_modulus"].items()]
    lines.append(f"| **all** | **{f(s['angle_ratio'])}** | **{f(s['force_ratio'])}** |")
    n = s["angle_within_0.8_1.25"]
    lines += ["", f"Where the angle is within 0.8-1.25 of the measured one ({n['points']} points), the blocked-force "
              f"ratio is {f(n['force_ratio'])}."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pneunet_env.paper.anchor", description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="also write every point and the summary as JSON")
    args = parser.parse_args(argv)
    points = sweep()
    s = summary(points)
    print(f"{SOURCE}\n")
    print(render(s))
    if args.json:
        from pneunet_env.files import atomic_write_bytes

        record = {"source": SOURCE, "summary": s, "points": [asdict(p) for p in points]}
        atomic_write_bytes(args.json, json.dumps(record, indent=1).encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
