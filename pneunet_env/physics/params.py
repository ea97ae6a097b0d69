"""Dimensionless actuator parameters, validated.

Every length is scaled by the chamber width ``w``, every modulus and pressure by the elastomer's
small-strain shear modulus ``mu`` (see ``docs/physics.md`` and :mod:`pneunet_env.physics.units` for the
physical-unit edges). The defaults are the paper's (supplement Table 1 and section 2).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["ActuatorParams", "MIN_OBJECT_CURVATURE", "check_finite", "check_object", "check_positive"]


def check_finite(name: str, value: float) -> float:
    """Return ``float(value)``; raise ``ValueError`` naming ``name`` if it is not a finite real number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    except OverflowError:
        raise ValueError(f"{name} must be finite, got {value!r} (too large for a float)") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


def check_positive(name: str, value: float) -> float:
    """Return ``float(value)``; raise ``ValueError`` naming ``name`` unless it is finite and ``> 0``."""
    x = check_finite(name, value)
    if x <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return x


MIN_OBJECT_CURVATURE = 1e-6
"""The flattest object arc ``w kappa_obj`` accepted: the contact terms divide by ``kappa_obj^2``; below 1e-6 (a radius
of a million chamber widths, 5 km at the default actuator) they leave double precision's useful range."""


def check_object(object_stiffness: float, object_curvature: float) -> tuple[float, float]:
    """Validate the dimensionless object ``(k~_obj, w kappa_obj)``; return them as floats.

    ``object_stiffness`` (``k~ = k_obj w / mu``) must be finite and ``>= 0`` (0 means no object).
    ``object_curvature`` (``w kappa_obj``) must be finite and in ``(0, pi)``.
    """
    k = check_finite("object_stiffness", object_stiffness)
    if k < 0.0:
        raise ValueError(f"object_stiffness (k~_obj = k_obj w/mu) must be >= 0, got {object_stiffness!r}")
    c = check_finite("object_curvature", object_curvature)
    if not MIN_OBJECT_CURVATURE <= c < math.pi:
        raise ValueError(f"object_curvature (w kappa_obj) must be in [{MIN_OBJECT_CURVATURE:g}, pi), got "
                         f"{object_curvature!r} (below: a radius over a million chamber widths, flat to double "
                         "precision in the contact terms)")
    return k, c


@dataclass(frozen=True)
class ActuatorParams:
    """Dimensionless geometry and material of one pneu-net chamber (the unit cell).

    All lengths are in units of the chamber width ``w``; moduli in units of the elastomer's shear
    modulus ``mu``. Any field can be overridden by keyword; invalid values raise ``ValueError``
    naming the field.

    Attributes:
        chamber_height: ``d/w``, chamber height, centre-line to centre-line. Default 1.
        base_thickness: ``h_b/w``, thickness of the stiff PDMS base. Default 0.5.
        side_thickness: ``h_s/w``, thickness of the side wall. Default 0.5.
        top_thickness: ``h_m/w``, thickness of the top wall. Default 0.5.
        base_modulus: ``E_b/mu``, Young's modulus of the base. Default 60.
        poisson_ratio: ``nu`` of the base, in ``(-1, 0.5]``. Default 0.5.
        gent_limit: Gent's ``J``, the limit of ``I1 - 3``. Default 20 (the paper's Fig. 2 uses 15).
    """

    chamber_height: float = 1.0
    base_thickness: float = 0.5
    side_thickness: float = 0.5
    top_thickness: float = 0.5
    base_modulus: float = 60.0
    poisson_ratio: float = 0.5
    gent_limit: float = 20.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, check_finite(f.name, getattr(self, f.name)))
        for name in ("chamber_height", "base_thickness", "side_thickness", "top_thickness"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name} must be > 0 (in units of the chamber width w), got {getattr(self, name)!r}")
        if self.base_modulus <= 0.0:
            raise ValueError(f"base_modulus (E_b/mu) must be > 0, got {self.base_modulus!r}")
        if not -1.0 < self.poisson_ratio <= 0.5:
            raise ValueError(f"poisson_ratio must be in (-1, 0.5], got {self.poisson_ratio!r}")
        if self.gent_limit <= 0.0:
            raise ValueError(f"gent_limit (J) must be > 0, got {self.gent_limit!r}")
        if self.side_thickness >= 1.0:
            raise ValueError(
                f"side_thickness (h_s/w) = {self.side_thickness!r} is not thinner than the chamber width "
                "(must be < 1): the cavity would have no width"
            )
        if 0.5 * (self.top_thickness + self.base_thickness) >= self.chamber_height:
            raise ValueError(
                f"top_thickness + base_thickness = {self.top_thickness + self.base_thickness!r} is not thinner "
                f"than twice chamber_height = {2 * self.chamber_height!r}: the cavity would have no height"
            )

    def replace(self, **changes: float) -> ActuatorParams:
        """Return a copy with some fields changed (validated). Unknown names raise ``ValueError``."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise ValueError(f"unknown ActuatorParams field(s) {unknown}; valid: {sorted(names)}")
        return dataclasses.replace(self, **changes)

    def as_tuple(self) -> tuple[float, ...]:
        """The fields in declaration order: ``(d, h_b, h_s, h_m, E_b, nu, J)``."""
        return dataclasses.astuple(self)

    @property
    def bending_stiffness(self) -> float:
        """Small-strain bending stiffness ``(1/t w) d^2U/dkappa^2`` at rest, supplement eq. 18 (units ``mu w^2``)."""
        d, hb, _, hm, eb, nu, _ = self.as_tuple()
        return eb * hb**3 / (12.0 * (1.0 - nu**2)) + 12.0 * d**2 * hm

    @property
    def small_pressure_slope(self) -> float:
        """The leading-order slope ``d kappa~ / d p~`` at rest, supplement eq. 17.

        ``[4 d (d + h_m) + h_m^2 - h_b^2 - 8 d h_m h_s] / (8 B)`` with ``B`` the bending stiffness (eq. 18).
        The seed's garbled eq. 17 is transcribed with ``h_s^2`` where this has ``h_b^2``; differentiating
        the chamber volume (supplement eq. 10) at rest gives ``h_b^2`` (``h_s`` enters the volume only
        through the side-wall correction, whose curvature derivative vanishes at rest). The two agree at
        the paper's defaults (``h_s = h_b``); the full model's slope follows this form (tested).
        """
        d, hb, hs, hm, _, _, _ = self.as_tuple()
        num = 4.0 * d * (d + hm) + (hm**2 - hb**2) - 8.0 * d * hm * hs
        return num / (8.0 * self.bending_stiffness)
