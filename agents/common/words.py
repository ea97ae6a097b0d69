"""The active task in words: its objects, its damage and slip rules, how a regime is read, the regime boundary;
and the rate formats the tables and figures share. Pure functions of a config (or of numbers).
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from pneunet_env.config import EnvConfig, ObjectConfig

__all__ = ["is_paper_ring", "task_description", "damage_rule_text", "slip_rule_text", "regime_text", "rate_parts",
           "phi_definition", "PHI_DEFINITION"]


def _fmt_range(r, unit: str = "") -> str:
    u = f" {unit}" if unit else ""
    return f"{r[0]:g}{u}" if r[0] == r[1] else f"{r[0]:g}-{r[1]:g}{u}"


def is_paper_ring(config: EnvConfig) -> bool:
    """Whether ``config``'s objects are the paper's ring: drawn from ranges whose size is the paper's (its defaults,
    ``R = 250 mm``, ``H = 10 mm``)."""
    oc = config.objects
    default = {f.name: f.default for f in fields(ObjectConfig)}
    return (not oc.from_catalogue and oc.object_curvature_per_m == default["object_curvature_per_m"]
            and oc.object_thickness_mm == default["object_thickness_mm"])


def task_description(config: EnvConfig) -> str:
    """The task's objects in words: the catalogue's use case (or classes) with their weights, or the ranges (the
    paper's 250 mm ring by default)."""
    oc = config.objects
    if oc.from_catalogue:
        weights = ", ".join(f"{n.replace('_', ' ')} {w:.0%}" for n, w in _class_weights(config).items())
        where, unsourced = "the catalogue's", ""
        if oc.catalogue is not None:
            from pathlib import Path

            from pneunet_env.catalogue import load_catalogue

            classes = load_catalogue(oc.catalogue)
            bare = [n for n in _class_weights(config) if not classes[n].sources]
            where = f"the catalogue {Path(oc.catalogue).name}'s"
            unsourced = f"; UNSOURCED: {', '.join(bare)} (no source given for their values)" if bare else ""
        if oc.class_weights is not None:
            return f"{where.replace('the ', '', 1)} classes ({weights}{unsourced})"
        return f"{where} {oc.use_case!r} use case ({weights}{unsourced})"
    radius = tuple(1e3 / c for c in oc.object_curvature_per_m[::-1])
    what = "the paper's ring" if is_paper_ring(config) else "objects from ranges"
    return (f"{what}: R = {_fmt_range(np.round(radius, 3), 'mm')}, H = {_fmt_range(oc.object_thickness_mm, 'mm')}, "
            f"mu_obj {_fmt_range(oc.object_shear_modulus_kpa, 'kPa')}, "
            f"rho {_fmt_range(oc.object_density_kg_m3, 'kg/m^3')}, failure strain "
            f"{_fmt_range(oc.object_failure_strain)}")


def _class_weights(config: EnvConfig) -> dict[str, float]:
    """``{class: normalised weight}`` of the classes a catalogue config draws (weight > 0)."""
    items = [(n, float(w)) for n, w in config.objects.class_items if w > 0]
    total = sum(w for _, w in items)
    return {n: w / total for n, w in items}


def damage_rule_text(config: EnvConfig) -> str:
    """The config's damage rule (``damage_rule``, whatever the objects), in words."""
    tc = config.task
    if tc.damage_rule == "hoop_strain":
        stress = "its class's failure stress" if config.objects.from_catalogue else "its failure stress 3 eps_f mu_obj"
        return (f"damaged when the hoop strain delta kappa_obj exceeds the object's failure strain eps_f, or the "
                f"traction F exceeds {stress} (damage_rule hoop_strain)")
    return (f"damaged when the indentation delta exceeds {tc.crush_fraction:g} H (crush_fraction {tc.crush_fraction:g}"
            f"), or the traction F exceeds 3 eps_f mu_obj (damage_rule crush_fraction)")


def slip_rule_text(config: EnvConfig) -> str:
    """The slip rule in words (the hold phase's)."""
    tc, a = config.task, config.actuator
    rho = "" if config.objects.from_catalogue else f", rho = {_fmt_range(config.objects.object_density_kg_m3)} kg/m^3"
    if tc.hold_rule == "slab":
        return (f"slipped (hold phase) when F < rho g H / ({tc.grip_faces} mu_f), mu_f = {tc.friction_coefficient:g}"
                f"{rho}")
    return (f"slipped (hold phase) when friction cannot carry the object's weight, {tc.grip_faces} mu_f F L_c b < m g: "
            f"mu_f = {tc.friction_coefficient:g}, fingers {a.length_mm:g} mm long (L_c at most the object's share of "
            f"wrap) and b = {a.finger_width_mm:g} mm wide, m from the object's 3D shape{rho}")


def regime_text(config: EnvConfig) -> str:
    """How an object's regime is read off the mechanics (:mod:`pneunet_env.physics.regimes`), in words."""
    return (f"regime from the mechanics at {config.task.max_pressure_kpa:g} kPa: force-controlled when the object "
            "blocks less than half of the curl the free finger would make past its surface (it yields; "
            "blocked_fraction phi < 1/2), position-controlled otherwise (it stops the finger)")


def rate_parts(parts) -> str:
    """``"force-controlled 75% of 195, position-controlled 99% of 205"`` from ``(name, rate, n)``; a group of no
    objects is left out, and none at all reads ``"no objects"``."""
    out = [f"{name} {_pct1(rate)} of {n}" for name, rate, n in parts if n]
    return ", ".join(out) if out else "no objects"


def _pct1(x: float) -> str:
    return f"{x:.0%}" if x in (0.0, 1.0) else f"{x:.1%}"


def phi_definition(pressure_kpa: float) -> str:
    """The regime boundary's terms in words (the figure's footnote, the summary's, ``map.json``'s
    ``regime_boundary``): what ``phi`` is (:func:`pneunet_env.physics.regimes.blocked_fraction`) and which side is
    which."""
    return (f"regime boundary: phi = 1/2, where phi (blocked_fraction) is the share of the curl the free finger would "
            f"make past the object's surface that the object blocks, loaded to {pressure_kpa:g} kPa; "
            "force-controlled on the soft side (phi < 1/2: the object gives way and the finger curls on into it), "
            "position-controlled on the stiff side (phi >= 1/2: the object holds the finger's curvature close to "
            "its own)")


PHI_DEFINITION = phi_definition(60.0)
"""The definition at the default maximum pressure."""


def _pct(x: float | None) -> str:
    """A rate as ``" 95%"``, or ``"   -"`` where there were no objects."""
    return "   -" if x is None else f"{x:4.0%}"
