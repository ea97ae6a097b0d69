"""The design space: the sourced bounds, the elastomers, and a design's env config (its pressure scale)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from pneunet_env.config import EnvConfig, load_config

P_TILDE_MAX = 1.2
"""A design's largest pressure over its shear modulus (Table 1: 60 kPa over 50 kPa; the paper's Fig. 3 axis)."""
P_TILDE_STEP = 0.06
"""A design's largest pressure change per step over its modulus (Table 1: 3 kPa over 50 kPa)."""
TARGETS = tuple(round(i / 60, 10) for i in range(1, 61))
"""The candidate blind pressures, fractions of ``max_pressure_kpa``: ``p~ = 0.02 .. 1.2`` in steps of 0.02."""
RAMP_STEPS = 20
"""The blind ramp's duration: any duration that ends inside the squeeze phase gives the same outcomes
(:data:`agents.search.ramp.DURATIONS` says how that was measured)."""
N_ERRORS = 8
"""Perturbed actuators per design for the manufacturing-error score."""
WALL_ERROR = 0.10
"""Wall thicknesses' manufacturing error: uniform within +-10 %."""
MODULUS_ERROR = 0.20
"""The elastomer's modulus error (batch to batch, cure): uniform within +-20 %."""
WINDOW_POINTS = 0.05
"""The pressure window: the blind pressures whose success stays within this of the best."""
WALL_CORNERS = (1.0 - WALL_ERROR, 1.0 + WALL_ERROR)
"""The walls' corners: all three walls thinner, or all thicker, by :data:`WALL_ERROR`."""
MODULUS_CORNERS = (1.0 - MODULUS_ERROR, 1.0 + MODULUS_ERROR)
"""The modulus' corners (batch to batch, cure), crossed with :data:`WALL_CORNERS`."""
PRESSURE_ERROR_KPA = 1.0
"""The regulator's pressure error (kPa) a blind schedule is scored at, both ways: 1 % of a 100 kPa full scale. SMC's
ITVH electro-pneumatic regulators are specified to linearity +-1 % F.S., hysteresis 1 % F.S. and repeatability
+-1 % F.S. (SMC catalogue CAT.ES60-23A); a 0-100 kPa unit is the smallest range of such a regulator, so +-1 kPa is
the least error a design's blind pressure must survive. ``pneunet-grasp design --pressure-error-kpa`` sets it."""
FIT_STRETCH = 3.0
"""The stretch up to which the elastomers' Gent fits were made (``elastomers.yaml``: engineering strain <= 2): a
design whose walls stretch further at its blind pressure is "outside the material data"."""


MIN_DEPTH_MM = 1.0
"""The least cavity depth ``t = b - 2 h_s`` (mm) a finger of width ``b`` may leave: the thinnest cast wall's (1 mm)."""
FINGER_WIDTH_MM = (10.0, 20.0)
FINGER_WIDTH_SOURCE = (
    "the finger's out-of-plane width b = t + 2 h_s. 10 mm: the seed paper's cell (Table 1: t = 5 mm, h_s = 2.5 mm). "
    "20 mm: SOFA's PneuNets gripper (github.com/SofaDefrost/Tutorials, PneuNets-Gripper/SOFA-scene/mesh/"
    "pneunetCut.stl: 20 mm across, its cavity 15 mm, so t = 15, h_s = 2.5; its docs: 'the 2cm of the PneuNet "
    "actuators') and Shintake et al. 2017, arXiv:1703.01423 (a 90 x 20 x 17 mm actuator). Between them: the Soft "
    "Robotics Toolkit's PneuNets mould (15 mm chambers, 2 mm walls: 19 mm). No published pneu-net finger wider than "
    "20 mm was found")
FINGER_LENGTH_RANGE_MM = (83.0, 120.0)
FINGER_LENGTH_SOURCE = (
    "the chambered length along the base. 83 mm: SOFA's PneuNets gripper (pneunetCavityCut.stl: its chambers span "
    "83 mm of a 115 mm part). 120 mm: Sorotoki's PneuNet example (github.com/BJCaasenbrood/SorotokiCode, BdBox "
    "[0,120,0,20] mm, after Mosadegh et al. 2014, Adv. Funct. Mater. 24:2163). Between them: Shintake et al. 2017 "
    "(90 mm, the default) and the Soft Robotics Toolkit's mould (11 chambers of 8 mm, 2 mm apart: 108 mm)")
FINGER_COUNTS = (2, 3)
FINGER_COUNT_SOURCE = (
    "fingers sharing the weight (grip_faces). 2: Shintake et al. 2017 ('two actuators are integrated to form a "
    "gripper'). 3: SOFA's PneuNets gripper ('composed of three pneumatic actuators', at 0, 120 and 240 degrees). "
    "Grippers of 4 and 6 exist (a six-pointed starfish, Ilievski et al. 2011); with three or more, each finger's "
    "contact is still capped at its share of one circumference, 2 pi R / n: conservative for fingers that close "
    "along meridians (docs/env.md, 'The hold rule')")


@dataclass(frozen=True)
class Bound:
    """A design parameter: an ``EnvConfig`` key (the actuator's, or ``grip_faces``), its range and why."""

    key: str
    low: float
    high: float
    unit: str
    source: str
    integer: bool = False
    """An integer parameter (the finger count): every whole number from ``low`` to ``high``."""


@dataclass(frozen=True)
class Elastomer:
    """A casting elastomer: its small-strain shear modulus and Gent limit, from a fit to measured curves, and the
    range its data support: ``gent_limit_range``, J fitted on stretches up to 2 and up to 3.5 (the same data, the
    nominal J's window being 3), and ``datasheet_mu_kpa``, the neo-Hookean ``mu`` of the data sheet's 100 % modulus
    (the crosshead-strain fits may underestimate ``mu`` by up to that factor). ``None``: no data (Table 1's
    material, the paper's own)."""

    name: str
    shear_modulus_kpa: float
    gent_limit: float
    source: str
    gent_limit_range: tuple[float, float] | None = None
    datasheet_mu_kpa: float | None = None

    def corners(self) -> list[tuple[str, float, float]]:
        """``(label, mu, J)`` of the material's range, each against the nominal fit (:meth:`Elastomer` docs)."""
        out: list[tuple[str, float, float]] = []
        if self.gent_limit_range is not None:
            lo, hi = self.gent_limit_range
            out += [(f"J {lo:g} (fit on stretch <= 2)", self.shear_modulus_kpa, lo),
                    (f"J {hi:g} (fit on stretch <= 3.5)", self.shear_modulus_kpa, hi)]
        if self.datasheet_mu_kpa is not None:
            out.append((f"mu {self.datasheet_mu_kpa:g} kPa (data sheet)", self.datasheet_mu_kpa, self.gent_limit))
        return out


@lru_cache(maxsize=1)
def _elastomer_data() -> dict[str, Any]:
    """``pneunet_env/data/elastomers.yaml`` (package data), read by the config's YAML reader (no duplicate keys)."""
    import pneunet_env.data
    from pneunet_env.config import _read_yaml

    path = Path(pneunet_env.data.__file__).resolve().parent / "elastomers.yaml"
    data = _read_yaml(path)
    if not isinstance(data.get("elastomers"), dict):
        raise ValueError(f"{path} must hold a mapping 'elastomers'")
    return data


TABLE1_ELASTOMER = Elastomer("table1", 50.0, 20.0, "the seed paper's supplement Table 1 (mu 50 kPa, J 20)")


def elastomers() -> dict[str, Elastomer]:
    """The elastomers a design may use: every entry of ``elastomers.yaml`` with both ``mu`` and ``J`` sourced,
    and the paper's Table 1 material."""
    out = {TABLE1_ELASTOMER.name: TABLE1_ELASTOMER}
    for name, e in _elastomer_data()["elastomers"].items():
        mu, j = e.get("shear_modulus_kpa"), e.get("gent_limit")
        if mu is None or j is None:
            continue  # no sourced Gent limit: not a design choice
        windows = e.get("gent_limit_by_fit_window") or {}
        j_range = ((float(windows["lambda_le_2"]), float(windows["lambda_le_3_5"]))
                   if "lambda_le_2" in windows and "lambda_le_3_5" in windows else None)
        sheet = e.get("mu_from_datasheet_100pct_kpa")
        out[str(name)] = Elastomer(str(name), float(mu), float(j), str(e.get("source", "")), j_range,
                                   None if sheet is None else float(sheet))
    return out


DESIGN_SPACE: tuple[Bound, ...] = (
    Bound("top_thickness_mm", 1.0, 3.75, "mm",
          "1 mm: the thinnest cast pneu-net wall read (the Soft Robotics Toolkit's PneuNets mould, elastomers.yaml "
          "wall_thickness_mm); 3.75 mm: h/w = 0.75 at w = 5 mm, the top of the seed paper's Fig. 3 (a thicker wall "
          "is no harder to cast)"),
    Bound("side_thickness_mm", 1.0, 3.75, "mm", "as the top wall"),
    Bound("base_thickness_mm", 1.0, 3.75, "mm", "as the top wall (the paper: it changes little)"),
    Bound("chamber_height_mm", 5.0, 15.0, "mm",
          "5 mm: Table 1; 15 mm: the Soft Robotics Toolkit's cast chamber (elastomers.yaml chamber_mm)"),
    Bound("width_mm", 5.0, 15.0, "mm", "as the chamber height"),
    Bound("finger_width_mm", FINGER_WIDTH_MM[0], FINGER_WIDTH_MM[1], "mm", FINGER_WIDTH_SOURCE),
    Bound("length_mm", FINGER_LENGTH_RANGE_MM[0], FINGER_LENGTH_RANGE_MM[1], "mm", FINGER_LENGTH_SOURCE),
    Bound("grip_faces", FINGER_COUNTS[0], FINGER_COUNTS[1], "fingers", FINGER_COUNT_SOURCE, integer=True),
)
"""The design parameters, each a manufacturable range with its source: the cell's walls and chamber (the
mechanics), then the finger in 3D (the grip: its out-of-plane width ``b = t + 2 h_s``, its length and how many
fingers share the weight; the model charges nothing for a wider, longer finger or one more of them, so they move
only the hold rule). The cell's parameters are continuous. A wall of 1 mm in a 15 mm chamber is
``h/w = 0.07``, far below the paper's computed ``h/w = 0.25 .. 0.75`` (the Toolkit's own actuator is at 0.07 ..
0.13): the thin-wall model is defined there, and thin walls are where it is most apt, but the paper did not
compute it, so such designs leave the range the seed paper checked (:func:`validity`)."""


def validity(params: Mapping[str, Any]) -> dict[str, float | bool]:
    """The design's wall-to-width ratios and whether they lie in the seed paper's computed range 0.25 .. 0.75."""
    w = float(params["width_mm"])  # the chamber's pitch (the cell), not the finger's out-of-plane width
    r = {k: float(params[k]) / w for k in ("top_thickness_mm", "side_thickness_mm", "base_thickness_mm")}
    return {**{f"{k.split('_')[0]}_over_width": v for k, v in r.items()},
            "chamber_aspect": float(params["chamber_height_mm"]) / w,
            "in_paper_range": all(0.25 <= v <= 0.75 for v in r.values())}


def parse_bounds(items: Sequence[str]) -> dict[str, tuple[float, float]]:
    """``KEY=LOW:HIGH`` strings -> narrowed bounds (each inside :data:`DESIGN_SPACE`'s, ``LOW < HIGH``; an integer
    parameter's are whole numbers, ``LOW <= HIGH``: ``grip_faces=3:3`` fixes it)."""
    space = {b.key: b for b in DESIGN_SPACE}
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        key, sep, rng = str(item).partition("=")
        lo_s, sep2, hi_s = rng.partition(":")
        if not sep or not sep2:
            raise ValueError(f"--bound must be KEY=LOW:HIGH, got {item!r}")
        if key not in space:
            raise ValueError(f"--bound {item!r}: unknown parameter {key!r}; valid: {', '.join(space)}")
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise ValueError(f"--bound {item!r}: LOW and HIGH must be numbers") from None
        b = space[key]
        if b.integer and not (lo.is_integer() and hi.is_integer() and lo <= hi):
            raise ValueError(f"--bound {item!r}: {key} is a whole number: need whole LOW <= HIGH")
        if not b.integer and (not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi):
            raise ValueError(f"--bound {item!r}: need finite LOW < HIGH")
        if lo < b.low or hi > b.high:
            raise ValueError(f"--bound {item!r}: outside the manufacturable range {b.low:g}..{b.high:g} {b.unit} "
                             f"({b.source})")
        out[key] = (lo, hi)
    return out


def narrowest_object_mm(config: EnvConfig) -> float:
    """The smallest extent (mm) of ``config``'s objects across the finger's width: ``2 R`` of a sphere at the
    smallest radius, a cylinder's or a ring's length (``inf`` where a ring takes the finger's own width). The hold
    rule takes the whole finger's width ``b`` as the contact's, which holds only while ``b`` is no wider than the
    object: a design study caps ``finger_width_mm`` here (``agents.design.study._space``)."""
    import numpy as np

    oc = config.objects
    if oc.from_catalogue:
        tab = oc.table
        ext = np.where(tab.shape == 0, 2.0 * tab.radius_mm[0], np.where(tab.length_mm[0] > 0, tab.length_mm[0], np.inf))
        return float(ext.min())
    if oc.shape == "sphere":
        return 2e3 / max(oc.object_curvature_per_m)
    return math.inf if oc.object_length_mm is None else float(oc.object_length_mm)


def finger_width_range(bounds: Mapping[str, tuple[float, float]], config: EnvConfig) -> tuple[float, float]:
    """The finger widths (mm) a study may try: :data:`DESIGN_SPACE`'s range (narrowed by ``bounds``, ``--bound``'s),
    capped at ``config``'s narrowest object (:func:`narrowest_object_mm`). A ``ValueError`` naming both where even the
    narrowest width is wider than that object: the hold rule would then press more finger on the object than it has,
    and no width in the range is one the model covers (a study is refused, not run at a width its rule misreads)."""
    b = next(b for b in DESIGN_SPACE if b.key == "finger_width_mm")
    lo, hi = bounds.get("finger_width_mm", (b.low, b.high))
    narrowest = narrowest_object_mm(config)
    if narrowest < lo:
        raise ValueError(f"the narrowest object is {narrowest:g} mm across, narrower than the narrowest finger "
                         f"width tried, finger_width_mm = {lo:g} mm (its sourced range is {b.low:g}..{b.high:g} mm): "
                         "the hold rule presses the finger's whole width on the object, so it would overstate the "
                         f"grip. Leave out the objects under {lo:g} mm across (a catalogue's class, or a range's "
                         "smallest radii)")
    return lo, min(hi, narrowest)


def chamber_depth_mm(finger_width_mm: float, side_thickness_mm: float) -> float:
    """The cavity's out-of-plane depth ``t = b - 2 h_s`` (mm) of a finger ``b`` wide with side walls ``h_s``; a
    ``ValueError`` naming both where it leaves less than :data:`MIN_DEPTH_MM` of cavity."""
    t = float(finger_width_mm) - 2.0 * float(side_thickness_mm)
    if not t >= MIN_DEPTH_MM:
        raise ValueError(f"finger_width_mm = {finger_width_mm!r} with side_thickness_mm = {side_thickness_mm!r} leaves "
                         f"a cavity {t:.3g} mm deep (t = b - 2 h_s); need at least {MIN_DEPTH_MM:g} mm")
    return t


def design_config(params: Mapping[str, Any], base: EnvConfig | None = None) -> EnvConfig:
    """The env config of a design: ``params`` (keys of :data:`DESIGN_SPACE`, and ``elastomer``, a name of
    :func:`elastomers`) on ``base``, with the pressure scale following the modulus (:data:`P_TILDE_MAX`). The
    finger's width ``finger_width_mm`` sets the cavity's depth, ``depth_mm = b - 2 h_s`` (:func:`chamber_depth_mm`)."""
    base = EnvConfig() if base is None else base
    p = dict(params)
    if "finger_width_mm" in p:
        p["depth_mm"] = chamber_depth_mm(p.pop("finger_width_mm"),
                                         p.get("side_thickness_mm", base.actuator.side_thickness_mm))
    name = p.pop("elastomer", None)
    if name is not None:
        table = elastomers()
        if name not in table:
            raise ValueError(f"unknown elastomer {name!r}; valid: {', '.join(table)}")
        p["shear_modulus_kpa"] = table[name].shear_modulus_kpa
        p["gent_limit"] = table[name].gent_limit
    mu = float(p.get("shear_modulus_kpa", base.actuator.shear_modulus_kpa))
    p.setdefault("max_pressure_kpa", round(P_TILDE_MAX * mu, 6))
    p.setdefault("max_pressure_step_kpa", round(P_TILDE_STEP * mu, 6))
    return load_config(base, **p)


def table1_design() -> dict[str, Any]:
    """The seed paper's Table 1 actuator as design parameters (its finger 10 mm wide, ``t + 2 h_s``, the default
    length and two fingers: :class:`pneunet_env.physics.units.PhysicalActuator`)."""
    c = EnvConfig()
    return ({b.key: getattr(c.task if b.key == "grip_faces" else c.actuator, b.key) for b in DESIGN_SPACE}
            | {"elastomer": TABLE1_ELASTOMER.name})


def corner_configs(config: EnvConfig, elastomer: str | None) -> list[tuple[str, EnvConfig]]:
    """``(label, config)`` of a design's corners, each run with the nominal design's schedule (kPa): the walls
    (:data:`WALL_CORNERS`, all three together) crossed with the modulus (:data:`MODULUS_CORNERS`), then each corner
    of the elastomer's data range (:meth:`Elastomer.corners`) at nominal walls. Not crossed with each other: the
    material's corners already move ``mu`` by more than the modulus error."""
    out = [(f"walls x{w:g}, modulus x{m:g}", perturbed_config(config, (w, w, w, m)))
           for w in WALL_CORNERS for m in MODULUS_CORNERS]
    table = elastomers()
    if elastomer is not None and elastomer in table:
        for label, mu, j in table[elastomer].corners():
            out.append((label, load_config(config, shear_modulus_kpa=mu, gent_limit=j)))
    return out


def wall_stretch(config: EnvConfig, pressure_kpa: float) -> float:
    """The largest wall stretch (top or side, ``1 + e``) of the free actuator loaded from rest to ``pressure_kpa``:
    the most any wall stretches at that pressure (an object only holds it back)."""
    from pneunet_env.physics.solver import solve_equilibrium

    eq = solve_equilibrium(pressure_kpa / config.actuator.shear_modulus_kpa, 0.0, 0.02, config.actuator_params,
                           options=config.solver)
    return 1.0 + max(float(eq.top_strain), float(eq.side_strain))


def perturbed_config(config: EnvConfig, factors: Sequence[float]) -> EnvConfig:
    """``config``'s actuator made with errors: top, side and base walls and the modulus times ``factors``; the
    pressure scale (the schedule's kPa) is the nominal design's."""
    a = config.actuator
    return load_config(config, top_thickness_mm=a.top_thickness_mm * factors[0],
                       side_thickness_mm=a.side_thickness_mm * factors[1],
                       base_thickness_mm=a.base_thickness_mm * factors[2],
                       shear_modulus_kpa=a.shear_modulus_kpa * factors[3])
