"""Physical units at the edges: mm and kPa in, dimensionless inside, mm and kPa out.

The model is solved in units of the chamber width ``w`` (lengths) and the elastomer's small-strain
shear modulus ``mu`` (stresses, pressure, moduli). :class:`Scales` holds the two (the table below says how
each quantity converts); :class:`PhysicalActuator` is supplement Table 1 in mm and kPa.

| quantity              | dimensionless              | physical                            |
|-----------------------|----------------------------|-------------------------------------|
| length                | ``L~ = L / w``             | mm                                  |
| curvature             | ``kappa~ = w kappa``       | 1/m                                 |
| pressure, stress      | ``p~ = p / mu``            | kPa                                 |
| traction ``F``        | ``F~ = F / mu``            | kPa (force per unit contact area)   |
| Winkler stiffness     | ``k~ = k_obj w / mu``      | kPa/mm (traction per indentation)   |
| energy                | ``U~ = U / (mu t w^2)``    | mJ (needs the depth ``t``)          |
"""

from __future__ import annotations

from dataclasses import dataclass

from pneunet_env.physics.contact import winkler_stiffness
from pneunet_env.physics.params import ActuatorParams, check_finite, check_positive

__all__ = [
    "PAPER_MODULUS_PER_STIFFNESS_PA",
    "Scales",
    "PhysicalActuator",
    "object_stiffness_from_material",
    "object_modulus_from_stiffness",
]


@dataclass(frozen=True)
class Scales:
    """The two scales of the dimensionless model: chamber width ``w`` (mm) and shear modulus ``mu`` (kPa)."""

    width_mm: float = 5.0
    shear_modulus_kpa: float = 50.0

    def __post_init__(self) -> None:
        check_positive("width_mm", self.width_mm)
        check_positive("shear_modulus_kpa", self.shear_modulus_kpa)


def object_stiffness_from_material(
    shear_modulus_kpa: float, thickness_mm: float, curvature_per_m: float, scales: Scales = Scales()
) -> float:
    """Dimensionless Winkler stiffness ``k~`` of an incompressible annular-sector object (eq. 3.2).

    ``k_obj = 2 mu_obj kappa_obj (1/(1 - H kappa_obj)^2 - 1)``, then ``k~ = k_obj w / mu``.

    Args:
        shear_modulus_kpa: the object's shear modulus ``mu_obj`` (kPa), ``>= 0``.
        thickness_mm: the object's thickness ``H`` (mm), with ``0 < H kappa_obj < 1``.
        curvature_per_m: the object's outer curvature ``kappa_obj`` (1/m), ``> 0``.
    """
    mu_obj = check_finite("shear_modulus_kpa", shear_modulus_kpa)
    if mu_obj < 0.0:
        raise ValueError(f"shear_modulus_kpa (object) must be >= 0, got {shear_modulus_kpa!r}")
    H = check_positive("thickness_mm", thickness_mm) * 1e-3
    kap = check_positive("curvature_per_m", curvature_per_m)
    if H * kap >= 1.0:
        raise ValueError(
            f"object thickness H={thickness_mm!r} mm is not below its outer radius 1/kappa_obj="
            f"{1e3 / kap:.4g} mm (need H kappa_obj < 1)"
        )
    return winkler_stiffness(mu_obj, thickness_mm, kap, scales.width_mm, scales.shear_modulus_kpa)


def object_modulus_from_stiffness(
    stiffness: float, thickness_mm: float, curvature_per_m: float, scales: Scales = Scales()
) -> float:
    """Inverse of :func:`object_stiffness_from_material`: the shear modulus (kPa) giving ``k~``."""
    unit = object_stiffness_from_material(1.0, thickness_mm, curvature_per_m, scales)
    if not unit > 0.0:  # so flat an arc (H kappa_obj ~ 1e-16) that eq. 3.2 rounds to no stiffness at all
        raise ValueError(f"curvature_per_m = {curvature_per_m!r} with thickness_mm = {thickness_mm!r} gives an object "
                         "with no stiffness per modulus in double precision (eq. 3.2); use a larger curvature")
    k = check_finite("stiffness", stiffness)
    if k < 0.0:
        raise ValueError(f"stiffness (k~) must be >= 0, got {stiffness!r}")
    return k / unit


_PHYSICAL_NAMES = {
    "chamber_height": "chamber_height_mm", "base_thickness": "base_thickness_mm", "side_thickness": "side_thickness_mm",
    "top_thickness": "top_thickness_mm", "base_modulus": "base_modulus_kpa", "poisson_ratio": "poisson_ratio",
    "gent_limit": "gent_limit",
}
"""The physical key of each :class:`ActuatorParams` field (for error messages)."""


FINGER_LENGTH_MM = 90.0
"""The finger's default length (mm); see ``docs/env.md``, "The hold rule", for its source."""


@dataclass(frozen=True)
class PhysicalActuator:
    """The actuator in physical units (supplement Table 1 defaults): lengths in mm, moduli in kPa.

    The mechanics is the unit cell's (2D, per unit depth: ``depth_mm`` only turns volumes into mm^3). The grip
    needs the finger in 3D: ``length_mm`` is the finger's length along its base (the cells in series, all at the
    cell's curvature), and :attr:`finger_width_mm` its out-of-plane width, the cavity's depth ``t`` and a side wall
    ``h_s`` on either side of it.
    """

    width_mm: float = 5.0
    chamber_height_mm: float = 5.0
    depth_mm: float = 5.0
    base_thickness_mm: float = 2.5
    side_thickness_mm: float = 2.5
    top_thickness_mm: float = 2.5
    shear_modulus_kpa: float = 50.0
    base_modulus_kpa: float = 3000.0
    poisson_ratio: float = 0.5
    gent_limit: float = 20.0
    length_mm: float = FINGER_LENGTH_MM

    def __post_init__(self) -> None:
        for name in ("width_mm", "chamber_height_mm", "depth_mm", "base_thickness_mm", "side_thickness_mm",
                     "top_thickness_mm", "shear_modulus_kpa", "base_modulus_kpa", "gent_limit", "length_mm"):
            check_positive(name, getattr(self, name))
        check_finite("poisson_ratio", self.poisson_ratio)
        try:  # the geometry must leave a cavity: ActuatorParams says why, named here by the physical keys
            self.to_dimensionless()
        except ValueError as exc:
            msg = str(exc)
            named = [phys for dim, phys in _PHYSICAL_NAMES.items() if dim in msg.split(" (")[0] or dim + " " in msg]
            raise ValueError(f"{', '.join(named) or 'actuator'} (relative to width_mm = {self.width_mm:g}, "
                             f"shear_modulus_kpa = {self.shear_modulus_kpa:g}): {msg}") from None

    @property
    def scales(self) -> Scales:
        return Scales(self.width_mm, self.shear_modulus_kpa)

    @property
    def finger_width_mm(self) -> float:
        """The finger's out-of-plane width (mm): the cavity's depth ``t`` and a side wall on either side,
        ``t + 2 h_s`` (10 mm for Table 1); the width the grip's traction acts over."""
        return self.depth_mm + 2.0 * self.side_thickness_mm

    def to_dimensionless(self) -> ActuatorParams:
        """The :class:`ActuatorParams` of this actuator (validated there: a wall thicker than the chamber raises)."""
        w, mu = self.width_mm, self.shear_modulus_kpa
        return ActuatorParams(
            chamber_height=self.chamber_height_mm / w,
            base_thickness=self.base_thickness_mm / w,
            side_thickness=self.side_thickness_mm / w,
            top_thickness=self.top_thickness_mm / w,
            base_modulus=self.base_modulus_kpa / mu,
            poisson_ratio=self.poisson_ratio,
            gent_limit=self.gent_limit,
        )

    @classmethod
    def from_dimensionless(cls, params: ActuatorParams, scales: Scales = Scales(), depth_mm: float = 5.0):
        """The physical actuator of ``params`` at the given scales."""
        w, mu = scales.width_mm, scales.shear_modulus_kpa
        return cls(
            width_mm=w,
            chamber_height_mm=params.chamber_height * w,
            depth_mm=depth_mm,
            base_thickness_mm=params.base_thickness * w,
            side_thickness_mm=params.side_thickness * w,
            top_thickness_mm=params.top_thickness * w,
            shear_modulus_kpa=mu,
            base_modulus_kpa=params.base_modulus * mu,
            poisson_ratio=params.poisson_ratio,
            gent_limit=params.gent_limit,
        )


# The paper's eq. 3.3 constant: mu_obj / k~ in Pa for Table 1 (H = 1 cm, kappa_obj = 4 /m).
PAPER_MODULUS_PER_STIFFNESS_PA = 1e3 * object_modulus_from_stiffness(1.0, 10.0, 4.0)
