"""The grasped object: an incompressible annular sector on a Winkler foundation (eqs. 2.9, 3.1, 3.2).

The object is an arc of outer curvature ``kappa_obj`` and thickness ``H``, of an incompressible solid
with shear modulus ``mu_obj``, density ``rho`` and failure strain ``eps_f``. Its Winkler stiffness (the
traction per unit normal displacement of its surface) follows from eq. 3.2,

    k_obj = 2 mu_obj kappa_obj (1/(1 - H kappa_obj)^2 - 1),

computed by :func:`pneunet_env.physics.units.object_stiffness_from_material`. :class:`GraspObject` holds the
properties in physical units (what is sampled and reported) and their dimensionless counterparts (what
the solver needs): ``k~ = k_obj w/mu``, ``w kappa_obj``, ``H/w``. Fields are floats for one object or
numpy arrays of one shape for a batch.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pneunet_env.physics.units import Scales, object_modulus_from_stiffness, object_stiffness_from_material

__all__ = ["GraspObject", "stiffness_per_modulus", "DEFAULT_SCALES", "SHAPES", "object_mass_kg"]

DEFAULT_SCALES = Scales()
"""The paper's scales: ``w = 5 mm``, ``mu = 50 kPa``."""


def _vectorised(fn):
    vec = np.vectorize(fn, otypes=[float])

    def call(*args, **kwargs):
        if all(np.ndim(a) == 0 for a in args):
            return fn(*(float(a) for a in args), **kwargs)
        return vec(*args, **kwargs)

    return call


@_vectorised
def _k_from_mu(shear_modulus_kpa, thickness_mm, curvature_per_m, scales=DEFAULT_SCALES):
    return object_stiffness_from_material(shear_modulus_kpa, thickness_mm, curvature_per_m, scales)


@_vectorised
def _mu_from_k(stiffness, thickness_mm, curvature_per_m, scales=DEFAULT_SCALES):
    return object_modulus_from_stiffness(stiffness, thickness_mm, curvature_per_m, scales)


SHAPES = ("sphere", "cylinder", "ring")
"""The 3D shapes an object's mass is computed for (:func:`object_mass_kg`), by code (0, 1, 2)."""


def object_mass_kg(shape, radius_mm, density_kg_m3, thickness_mm=0.0, length_mm=0.0):
    """The mass (kg) of an object of outer radius ``R`` (mm) and density ``rho`` (kg/m^3), by its 3D ``shape``:

    * ``"sphere"`` (code 0): a solid ball, ``4/3 pi R^3 rho``;
    * ``"cylinder"`` (1): a solid cylinder of length ``L`` (``length_mm``) whose circular section the finger wraps
      (its axis out of the finger's plane), ``pi R^2 L rho``;
    * ``"ring"`` (2): eq. 3.2's annulus itself, of thickness ``H`` (``thickness_mm``) and height ``L``,
      ``pi (R^2 - (R - H)^2) L rho`` (the paper's 250 mm ring).

    ``shape`` is a name or a code, or an integer array of codes (a batch); the others broadcast against it. The
    compliant depth ``H`` enters only the ring's mass: a solid object's ``H`` is the layer that deforms, not its
    size."""
    if type(shape) in _SCALAR_CODES and all(type(a) in _SCALARS for a in (radius_mm, density_kg_m3, thickness_mm,
                                                                         length_mm)):
        return _mass_one(SHAPES.index(shape) if type(shape) is str else int(shape), float(radius_mm),
                         float(density_kg_m3), float(thickness_mm), float(length_mm))
    code = SHAPES.index(shape) if isinstance(shape, str) else np.asarray(shape)
    R, rho = np.asarray(radius_mm, dtype=float) * 1e-3, np.asarray(density_kg_m3, dtype=float)
    L, H = np.asarray(length_mm, dtype=float) * 1e-3, np.asarray(thickness_mm, dtype=float) * 1e-3
    volume = np.where(code == 0, 4.0 / 3.0 * np.pi * R * R * R,
                      np.where(code == 1, np.pi * R * R * L, np.pi * (R * R - (R - H) * (R - H)) * L))
    return _as(volume * rho)


_SCALARS = (float, int, np.float64)
"""The types of one object's numbers that take the scalar path (:func:`_material_fields`, :func:`_mass_one`)."""
_SCALAR_CODES = (str, int, np.int64)


def _mass_one(code: int, radius_mm: float, density_kg_m3: float, thickness_mm: float, length_mm: float) -> float:
    """:func:`object_mass_kg` (kg) of one object, in float arithmetic: the same operations in the same order as the
    array path (so the same bits: IEEE ``+ - * /`` round alike on floats and in numpy's loops), only the shape's
    own branch computed."""
    R = radius_mm * 1e-3
    if code == 0:
        volume = 4.0 / 3.0 * math.pi * R * R * R
    elif code == 1:
        volume = math.pi * R * R * (length_mm * 1e-3)
    else:
        H = thickness_mm * 1e-3
        volume = math.pi * (R * R - (R - H) * (R - H)) * (length_mm * 1e-3)
    return volume * density_kg_m3


def stiffness_per_modulus(thickness_mm, curvature_per_m, scales: Scales = DEFAULT_SCALES):
    """``k~`` per kPa of object shear modulus (eq. 3.2 is linear in ``mu_obj``); broadcasts."""
    return _k_from_mu(1.0, thickness_mm, curvature_per_m, scales=scales)


def _as(x):
    """A float for a 0-d input, else a float array."""
    a = np.asarray(x, dtype=float)
    return float(a) if a.ndim == 0 else a


@dataclass(frozen=True)
class GraspObject:
    """One object (float fields) or a batch (array fields of one shape).

    Physical attributes (sampled, reported):
        shear_modulus_kpa: ``mu_obj`` (kPa).
        thickness_mm: ``H`` (mm).
        curvature_per_m: outer curvature ``kappa_obj`` (1/m).
        density_kg_m3: ``rho`` (kg/m^3).
        failure_strain: ``eps_f``: the object fails at a stress ``eps_f E_obj = 3 eps_f mu_obj``.

    Damage (the task's ``damage_rule``): ``failure_stress_kpa`` (``sigma_f``, kPa; a catalogue class's own, else
    ``3 eps_f mu_obj``), and ``class_id``: the index of its catalogue class in the env's class table (``-1`` for an
    object drawn from ranges or built by hand).

    Weight (the task's hold rule): ``mass_kg``, from the object's 3D shape (:func:`object_mass_kg`; a solid sphere
    of radius ``1/kappa_obj`` unless its catalogue class or the config's ``objects.shape`` says otherwise).

    Dimensionless attributes (derived):
        stiffness: ``k~ = k_obj w/mu`` (eq. 3.2).
        curvature: ``w kappa_obj``.
        thickness: ``H/w``.
    """

    shear_modulus_kpa: float | np.ndarray
    thickness_mm: float | np.ndarray
    curvature_per_m: float | np.ndarray
    density_kg_m3: float | np.ndarray
    failure_strain: float | np.ndarray
    stiffness: float | np.ndarray
    curvature: float | np.ndarray
    thickness: float | np.ndarray
    failure_stress_kpa: float | np.ndarray = float("nan")
    class_id: int | np.ndarray = -1
    mass_kg: float | np.ndarray = float("nan")

    @classmethod
    def from_material(
        cls,
        shear_modulus_kpa,
        thickness_mm,
        curvature_per_m,
        density_kg_m3=1000.0,
        failure_strain=0.3,
        scales: Scales = DEFAULT_SCALES,
        mass_kg=None,
    ) -> GraspObject:
        """The object of a given material and shape; validates (``ValueError`` naming the bad property). Its mass is
        ``mass_kg``, else a solid sphere's of radius ``1/kappa_obj`` (:func:`object_mass_kg`)."""
        if all(type(a) in _SCALARS for a in (shear_modulus_kpa, thickness_mm, curvature_per_m, density_kg_m3,
                                             failure_strain)) and (mass_kg is None or type(mass_kg) in _SCALARS):
            return cls._of(_material_fields(shear_modulus_kpa, thickness_mm, curvature_per_m, density_kg_m3,
                                            failure_strain, scales, mass_kg))
        _check_positive("density_kg_m3", density_kg_m3)
        _check_positive("failure_strain", failure_strain)
        args = (shear_modulus_kpa, thickness_mm, curvature_per_m, density_kg_m3, failure_strain)
        if any(np.ndim(a) for a in args):
            shear_modulus_kpa, thickness_mm, curvature_per_m, density_kg_m3, failure_strain = np.broadcast_arrays(
                *(np.asarray(a, dtype=float) for a in args)
            )
        with np.errstate(over="ignore"):
            k = _k_from_mu(shear_modulus_kpa, thickness_mm, curvature_per_m, scales=scales)
            failure_stress = 3.0 * np.asarray(failure_strain, float) * np.asarray(shear_modulus_kpa, float)
        if not (np.all(np.isfinite(k)) and np.all(np.isfinite(failure_stress))):
            raise ValueError(f"object_shear_modulus_kpa={shear_modulus_kpa!r} with object_failure_strain="
                             f"{failure_strain!r}: the object's stiffness or failure stress (3 eps_f mu_obj) is not a "
                             "finite number")
        c = np.asarray(curvature_per_m, dtype=float) * scales.width_mm * 1e-3
        if np.any(c >= np.pi):
            raise ValueError(f"object curvature_per_m={curvature_per_m!r} gives w kappa_obj >= pi")
        if mass_kg is None:
            mass_kg = object_mass_kg("sphere", 1e3 / np.asarray(curvature_per_m, dtype=float), density_kg_m3)
        else:
            _check_positive("mass_kg", mass_kg)
        return cls(
            shear_modulus_kpa=_as(shear_modulus_kpa),
            thickness_mm=_as(thickness_mm),
            curvature_per_m=_as(curvature_per_m),
            density_kg_m3=_as(density_kg_m3),
            failure_strain=_as(failure_strain),
            stiffness=_as(k),
            curvature=_as(c),
            thickness=_as(np.asarray(thickness_mm, dtype=float) / scales.width_mm),
            failure_stress_kpa=_as(failure_stress),
            mass_kg=_as(np.broadcast_to(np.asarray(mass_kg, dtype=float), np.shape(k))),
        )

    @classmethod
    def _of(cls, fields: dict[str, Any]) -> GraspObject:
        """The object of ``fields`` (every field, by name, already checked: :func:`_material_fields`), without the
        frozen dataclass's ``__init__``, which sets each field through ``object.__setattr__`` (about 2 us of a reset
        for eleven fields); the same object (``GraspObject`` has no ``__post_init__``)."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    @classmethod
    def from_stiffness(
        cls,
        stiffness,
        thickness_mm=10.0,
        curvature_per_m=4.0,
        density_kg_m3=1000.0,
        failure_strain=0.3,
        scales: Scales = DEFAULT_SCALES,
        mass_kg=None,
    ) -> GraspObject:
        """The object of a given dimensionless stiffness ``k~`` (its shear modulus from eq. 3.2 inverted)."""
        mu = _mu_from_k(stiffness, thickness_mm, curvature_per_m, scales=scales)
        obj = cls.from_material(mu, thickness_mm, curvature_per_m, density_kg_m3, failure_strain, scales, mass_kg)
        # Keep the requested k~ exactly (the round trip through mu_obj may differ in the last bit).
        k = np.broadcast_to(np.asarray(stiffness, dtype=float), np.shape(obj.stiffness))
        return dataclasses.replace(obj, stiffness=_as(k.copy()))


def _material_fields(shear_modulus_kpa, thickness_mm, curvature_per_m, density_kg_m3, failure_strain, scales,
                     mass_kg=None) -> dict[str, float]:
    """The fields of :meth:`GraspObject.from_material` for one object of Python (or numpy scalar) numbers: the same
    checks in the same order, with the same messages, and the same bits, in float arithmetic (eq. 3.2 is
    :func:`~pneunet_env.physics.units.object_stiffness_from_material` on floats in both paths; the rest is ``+ - * /``,
    which rounds alike on floats and in numpy). The scalar path of ``from_material``: about 3 us, not 100."""
    _check_positive_one("density_kg_m3", density_kg_m3)
    _check_positive_one("failure_strain", failure_strain)
    mu, H, kap = float(shear_modulus_kpa), float(thickness_mm), float(curvature_per_m)
    rho, eps = float(density_kg_m3), float(failure_strain)
    k = object_stiffness_from_material(mu, H, kap, scales)
    failure_stress = 3.0 * eps * mu  # a float product overflows to inf, as numpy's does under errstate(over="ignore")
    if not (math.isfinite(k) and math.isfinite(failure_stress)):
        raise ValueError(f"object_shear_modulus_kpa={shear_modulus_kpa!r} with object_failure_strain="
                         f"{failure_strain!r}: the object's stiffness or failure stress (3 eps_f mu_obj) is not a "
                         "finite number")
    c = kap * scales.width_mm * 1e-3
    if c >= math.pi:
        raise ValueError(f"object curvature_per_m={curvature_per_m!r} gives w kappa_obj >= pi")
    if mass_kg is None:
        mass = _mass_one(0, 1e3 / kap, rho, 0.0, 0.0)
    else:
        _check_positive_one("mass_kg", mass_kg)
        mass = float(mass_kg)
    return dict(shear_modulus_kpa=mu, thickness_mm=H, curvature_per_m=kap, density_kg_m3=rho, failure_strain=eps,
                stiffness=k, curvature=c, thickness=H / scales.width_mm, failure_stress_kpa=failure_stress,
                class_id=-1, mass_kg=mass)


def _check_positive_one(name, value):
    """:func:`_check_positive` for one number (a float, an int or a numpy scalar)."""
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"object {name} must be finite and > 0, got {value!r}")


def _check_positive(name, value):
    a = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise ValueError(f"object {name} must be finite and > 0, got {value!r}")
