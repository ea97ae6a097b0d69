"""The real-object catalogue: hand-scale objects of real material classes, read from ``data/objects.yaml``.

Each class gives literature ranges ``(low, high)`` for the properties eq. 3.2 and the damage/slip thresholds
need (Young's modulus ``E``, from which ``shear_modulus_kpa = E/3`` for an incompressible solid; density;
failure strain and stress; outer radius ``R = 1/kappa_obj``; compliant depth ``H``), whether the class lies
inside eq. 3.2's incompressible-annulus model (with the reason), and its sources. Use cases weight the classes
(the default one is the file's ``use_cases.default``). The criterion and the default use case are stated in
``docs/env.md``, section "Object catalogue".

* :func:`load_catalogue` reads and validates the packaged file (or another path) into
  ``{name: ObjectClass}``; any malformed class raises ``ValueError`` naming the class and the field.
* :func:`use_case_weights` returns a use case's class weights, normalized to sum 1.
* :func:`stiffness_range` gives the dimensionless ``k~ = k_obj w/mu`` range of a class (eq. 3.2 over the
  corners of its modulus, radius and thickness box).

The YAML is package data (``pneunet_env/data/objects.yaml``), read with :mod:`importlib.resources`, so this works
from an installed wheel as long as the wheel ships it.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.physics.contact import winkler_stiffness
from pneunet_env.yamlio import load_yaml, load_yaml_file

__all__ = [
    "ObjectClass",
    "UseCase",
    "load_catalogue",
    "load_use_cases",
    "default_use_case",
    "use_case_weights",
    "stiffness_range",
    "ClassTable",
    "class_table",
    "RANGE_FIELDS",
]

_PACKAGE = "pneunet_env.data"
_FILENAME = "objects.yaml"

RANGE_FIELDS = (
    "youngs_modulus_kpa",
    "density_kg_m3",
    "failure_strain",
    "failure_stress_kpa",
    "radius_mm",
    "thickness_mm",
)
"""The ``[low, high]`` fields every class must give in the YAML (all positive, ``low <= high``)."""

_REQUIRED = ("description", *RANGE_FIELDS, "in_annulus_model", "reason", "sources")

Range = tuple[float, float]


@dataclass(frozen=True)
class ObjectClass:
    """One material class of the catalogue. Ranges are ``(low, high)`` in the units of their names.

    ``shear_modulus_kpa`` is derived, ``E/3`` (incompressible solid); for classes outside the annulus model
    (foams, sponges) that is only the incompressible approximation. ``shape`` is the object's 3D shape, which sets
    its mass (:func:`pneunet_env.objects.object_mass_kg`): ``"sphere"`` (the default) or ``"cylinder"``, whose
    ``length_mm`` range the class must then give (drawn with one more uniform).
    """

    name: str
    description: str
    youngs_modulus_kpa: Range
    shear_modulus_kpa: Range
    density_kg_m3: Range
    failure_strain: Range
    failure_stress_kpa: Range
    radius_mm: Range
    thickness_mm: Range
    in_annulus_model: bool
    reason: str
    sources: tuple[str, ...]  # empty: an unsourced class of a user's catalogue
    shape: str = "sphere"
    length_mm: Range | None = None

    @property
    def curvature_per_m(self) -> Range:
        """The outer curvature ``kappa_obj = 1/R`` range (1/m), ``(1/R_hi, 1/R_lo)``."""
        return (1e3 / self.radius_mm[1], 1e3 / self.radius_mm[0])


@dataclass(frozen=True)
class UseCase:
    """A use case: relative class weights (only classes inside the annulus model) and the classes of the scene
    that fall outside the model (``unreachable``, reported as their own category, never drawn)."""

    name: str
    description: str
    reason: str
    weights: dict[str, float]
    unreachable: tuple[str, ...]


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------


def _load_raw(path: str | Path | None) -> tuple[dict[str, Any], str]:
    """``(mapping, label)`` of the catalogue file (``path``, else the packaged ``objects.yaml``), read by
    :mod:`pneunet_env.yamlio`: a duplicated class, use case or field is refused (naming it and its line), numbers read
    as in every other file, aliases bounded."""
    if path is None:
        label = f"{_PACKAGE}/{_FILENAME}"
        raw = load_yaml(resources.files(_PACKAGE).joinpath(_FILENAME).read_bytes(), label)
    else:
        label = str(Path(path))
        raw = load_yaml_file(path, "catalogue file")
    if not isinstance(raw, dict):
        raise ValueError(f"{label}: the top level must be a mapping with 'classes' and 'use_cases'")
    return raw, label


# ---------------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------------


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _range(name: str, field: str, value: Any) -> Range:
    if value is None:
        raise ValueError(f"object class {name!r}: field {field!r} is missing")
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(_is_number(v) for v in value):
        raise ValueError(
            f"object class {name!r}: field {field!r} must be [low, high] (two finite numbers), got {value!r}"
        )
    low, high = float(value[0]), float(value[1])
    if low <= 0.0 or high <= 0.0:
        raise ValueError(f"object class {name!r}: field {field!r} must be positive, got {value!r}")
    if low > high:
        raise ValueError(f"object class {name!r}: field {field!r} has low > high, got {value!r}")
    return (low, high)


def _text(name: str, field: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"object class {name!r}: field {field!r} must be a non-empty string, got {value!r}")
    return value.strip()


def _object_class(name: Any, entry: Any, sourced: bool = True) -> ObjectClass:
    if not isinstance(name, str) or not name:
        raise ValueError(f"object class name must be a non-empty string, got {name!r}")
    if not isinstance(entry, dict):
        raise ValueError(f"object class {name!r}: must be a mapping of fields, got {type(entry).__name__}")
    for field in _REQUIRED:
        if field not in entry and (sourced or field != "sources"):
            raise ValueError(f"object class {name!r}: field {field!r} is missing")
    ranges = {field: _range(name, field, entry[field]) for field in RANGE_FIELDS}
    in_model = entry["in_annulus_model"]
    if not isinstance(in_model, bool):
        raise ValueError(f"object class {name!r}: field 'in_annulus_model' must be true or false, got {in_model!r}")
    sources = entry.get("sources", [])
    if isinstance(sources, str):
        sources = [sources]
    if not sourced and isinstance(sources, (list, tuple)) and not sources:
        sources = []  # a user's catalogue: a class without sources is read, and reported "unsourced"
    elif not isinstance(sources, (list, tuple)) or not sources:
        raise ValueError(f"object class {name!r}: field 'sources' must list at least one source, got {sources!r}")
    for s in sources:
        if not isinstance(s, str) or not s.strip():
            raise ValueError(f"object class {name!r}: field 'sources' has an empty or non-text entry {s!r}")
    # H kappa_obj < 1 at every corner of the box: the thickest layer must be thinner than the smallest radius.
    h_hi, r_lo = ranges["thickness_mm"][1], ranges["radius_mm"][0]
    if h_hi >= r_lo:
        raise ValueError(
            f"object class {name!r}: field 'thickness_mm' must stay below the radius (H_hi = {h_hi} mm >= "
            f"R_lo = {r_lo} mm gives H kappa_obj >= 1, where eq. 3.2 diverges)"
        )
    shape = entry.get("shape", "sphere")
    if shape not in ("sphere", "cylinder"):
        raise ValueError(f"object class {name!r}: field 'shape' must be 'sphere' or 'cylinder', got {shape!r}")
    length = None
    if shape == "cylinder":
        length = _range(name, "length_mm", entry.get("length_mm"))
    elif "length_mm" in entry:
        raise ValueError(f"object class {name!r}: field 'length_mm' belongs to a cylinder; a {shape} has none")
    e_lo, e_hi = ranges["youngs_modulus_kpa"]
    return ObjectClass(
        name=name,
        description=_text(name, "description", entry["description"]),
        youngs_modulus_kpa=(e_lo, e_hi),
        shear_modulus_kpa=(e_lo / 3.0, e_hi / 3.0),
        density_kg_m3=ranges["density_kg_m3"],
        failure_strain=ranges["failure_strain"],
        failure_stress_kpa=ranges["failure_stress_kpa"],
        radius_mm=ranges["radius_mm"],
        thickness_mm=ranges["thickness_mm"],
        in_annulus_model=in_model,
        reason=_text(name, "reason", entry["reason"]),
        sources=tuple(s.strip() for s in sources),
        shape=shape,
        length_mm=length,
    )


def _classes(raw: dict[str, Any], label: str, sourced: bool = True) -> dict[str, ObjectClass]:
    entries = raw.get("classes")
    if not isinstance(entries, dict) or not entries:
        raise ValueError(f"{label}: 'classes' must be a non-empty mapping of class name -> fields")
    try:
        return {name: _object_class(name, entry, sourced) for name, entry in entries.items()}
    except ValueError as exc:
        raise ValueError(f"{label}: {exc}" if not sourced else str(exc)) from None


def _use_case(name: Any, entry: Any, classes: dict[str, ObjectClass]) -> UseCase:
    if not isinstance(name, str) or not name:
        raise ValueError(f"use case name must be a non-empty string, got {name!r}")
    if not isinstance(entry, dict):
        raise ValueError(f"use case {name!r}: must be a mapping, got {type(entry).__name__}")
    weights = entry.get("weights")
    if not isinstance(weights, dict) or not weights:
        raise ValueError(f"use case {name!r}: field 'weights' must be a non-empty mapping of class -> weight")
    out: dict[str, float] = {}
    for cls, w in weights.items():
        if cls not in classes:
            raise ValueError(f"use case {name!r}: unknown object class {cls!r} in 'weights'")
        if not _is_number(w):
            raise ValueError(f"use case {name!r}: weight of class {cls!r} must be a finite number, got {w!r}")
        if w < 0:
            raise ValueError(f"use case {name!r}: weight of class {cls!r} is negative ({w!r})")
        if w > 0 and not classes[cls].in_annulus_model:
            raise ValueError(
                f"use case {name!r}: class {cls!r} is outside the annulus model; list it under 'unreachable', "
                "not in 'weights'"
            )
        out[cls] = float(w)
    total = sum(out.values())
    if not total > 0.0:
        raise ValueError(f"use case {name!r}: weights must sum to a positive number, got {total!r}")
    if not math.isfinite(total):
        raise ValueError(f"use case {name!r}: the weights sum past the largest float ({out!r}); scale them down")
    unreachable = entry.get("unreachable", [])
    if unreachable is None:
        unreachable = []
    if not isinstance(unreachable, (list, tuple)):
        raise ValueError(f"use case {name!r}: field 'unreachable' must be a list of class names, got {unreachable!r}")
    for cls in unreachable:
        if cls not in classes:
            raise ValueError(f"use case {name!r}: unknown object class {cls!r} in 'unreachable'")
        if classes[cls].in_annulus_model:
            raise ValueError(f"use case {name!r}: class {cls!r} in 'unreachable' is inside the annulus model")
    return UseCase(
        name=name,
        description=str(entry.get("description", "")).strip(),
        reason=str(entry.get("reason", "")).strip(),
        weights=out,
        unreachable=tuple(unreachable),
    )


def _use_cases(raw: dict[str, Any], label: str, classes: dict[str, ObjectClass]) -> tuple[dict[str, UseCase], str]:
    entries = raw.get("use_cases")
    if not isinstance(entries, dict):
        raise ValueError(f"{label}: 'use_cases' must be a mapping with a 'default' and at least one use case")
    entries = dict(entries)
    default = entries.pop("default", None)
    cases = {name: _use_case(name, entry, classes) for name, entry in entries.items()}
    if not isinstance(default, str) or default not in cases:
        raise ValueError(f"{label}: use_cases 'default' must name one of {sorted(cases)}, got {default!r}")
    return cases, default


# ---------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------


def load_catalogue(path: str | Path | None = None) -> dict[str, ObjectClass]:
    """The object classes of the catalogue, ``{name: ObjectClass}``, in file order.

    Reads the packaged ``objects.yaml`` unless ``path`` is given. The whole file is validated (classes and use
    cases); ``ValueError`` names the class (or use case) and the field at fault.
    """
    if path is None:
        return dict(_packaged_catalogue())
    raw, label = _load_raw(path)
    classes = _classes(raw, label, sourced=False)
    _use_cases(raw, label, classes)  # validated with the classes: a bad use case is a bad file
    return classes


def load_use_cases(path: str | Path | None = None) -> dict[str, UseCase]:
    """The catalogue's use cases, ``{name: UseCase}`` (validated against its classes)."""
    if path is None:
        return dict(_packaged_use_cases())
    raw, label = _load_raw(path)
    return _use_cases(raw, label, _classes(raw, label, sourced=False))[0]


@functools.lru_cache(maxsize=1)
def _packaged_use_cases() -> dict[str, UseCase]:
    raw, label = _load_raw(None)
    return _use_cases(raw, label, _classes(raw, label))[0]


def default_use_case(path: str | Path | None = None) -> str:
    """The name of the default use case (``use_cases.default`` in the file)."""
    raw, label = _load_raw(path)
    return _use_cases(raw, label, _classes(raw, label, sourced=path is None))[1]


def use_case_weights(name: str | None = None, path: str | Path | None = None) -> dict[str, float]:
    """The class weights of use case ``name`` (the default use case if ``None``), normalized to sum 1.

    Only classes inside the annulus model carry weight; ``KeyError`` if there is no such use case.
    """
    if path is None:  # the packaged file does not change: read and validate it once
        return dict(_packaged_weights(name))
    raw, label = _load_raw(path)
    cases, default = _use_cases(raw, label, _classes(raw, label, sourced=False))
    key = default if name is None else name
    if key not in cases:
        raise KeyError(f"no use case {key!r} in {label}; known: {sorted(cases)}")
    weights = cases[key].weights
    total = sum(weights.values())
    return {cls: w / total for cls, w in weights.items()}


@functools.lru_cache(maxsize=16)
def _packaged_weights(name: str | None) -> tuple[tuple[str, float], ...]:
    raw, label = _load_raw(None)
    cases, default = _use_cases(raw, label, _classes(raw, label))
    key = default if name is None else name
    if key not in cases:
        raise KeyError(f"no use case {key!r} in {label}; known: {sorted(cases)}")
    total = sum(cases[key].weights.values())
    return tuple((cls, w / total) for cls, w in cases[key].weights.items())


@functools.lru_cache(maxsize=1)
def _packaged_catalogue() -> dict[str, ObjectClass]:
    raw, label = _load_raw(None)
    classes = _classes(raw, label)
    _use_cases(raw, label, classes)
    return classes


def stiffness_range(cls: ObjectClass, width_mm: float = 5.0, scale_modulus_kpa: float = 50.0) -> tuple[float, float]:
    """``(k~_lo, k~_hi)``: eq. 3.2's dimensionless Winkler stiffness ``k~ = k_obj w/mu`` over the class's box.

    ``k~`` grows with the shear modulus and with ``H``, and falls with ``R``; the extremes are taken over the
    eight corners of (shear modulus, radius, thickness). ``width_mm`` and ``scale_modulus_kpa`` are the
    actuator's scales ``w`` and ``mu`` (the paper's 5 mm and 50 kPa by default).
    """
    values = [
        winkler_stiffness(mu, h, 1e3 / r, width_mm, scale_modulus_kpa)
        for mu, r, h in itertools.product(cls.shear_modulus_kpa, cls.radius_mm, cls.thickness_mm)
    ]
    return (min(values), max(values))


@dataclass(frozen=True)
class ClassTable:
    """The classes an env draws from, as arrays for vectorised sampling (built once per config).

    ``names[i]`` is class ``i``; ``cumulative`` the cumulative normalized weights; each ``*_lo``/``*_hi`` an array
    over the classes (shear modulus from ``E/3``, kPa; radius and thickness in mm; density kg/m^3; failure strain;
    failure stress kPa).
    """

    names: tuple[str, ...]
    cumulative: Any
    shear_modulus_kpa: Any
    radius_mm: Any
    thickness_mm: Any
    density_kg_m3: Any
    failure_strain: Any
    failure_stress_kpa: Any
    shape: Any = None
    length_mm: Any = None

    @property
    def has_length(self) -> bool:
        """Some class is a cylinder: its objects take one more uniform draw, for the length."""
        return bool(np.any(self.shape != 0))


def class_table(weights: tuple[tuple[str, float], ...], catalogue: str | None = None) -> ClassTable:
    """A :class:`ClassTable` for ``((class, weight), ...)`` (validated names, positive total weight) of the packaged
    catalogue, or of the user's ``catalogue`` file (a path)."""
    return _class_table(tuple(weights), None if catalogue is None else str(catalogue))


@functools.lru_cache(maxsize=32)
def _class_table(weights: tuple[tuple[str, float], ...], catalogue: str | None = None) -> ClassTable:
    classes = load_catalogue(catalogue)
    for n, w in weights:
        if not isinstance(n, str) or n not in classes:
            raise ValueError(f"unknown object class {n!r}; known: {sorted(classes)}")
        if not classes[n].in_annulus_model:
            raise ValueError(f"object class {n!r} lies outside eq. 3.2's annulus model ({classes[n].reason})")
        if not _is_number(w) or w < 0.0:
            raise ValueError(f"the weight of object class {n!r} must be a finite number >= 0, got {w!r}")
    names = tuple(n for n, w in weights if w > 0.0)
    w = np.array([dict(weights)[n] for n in names], dtype=float)
    if not names:
        raise ValueError(f"object class weights must not all be zero, got {dict(weights)!r}")
    if not math.isfinite(sum(float(x) for x in w)):
        raise ValueError(f"object class weights sum past the largest float ({dict(weights)!r}); scale them down")

    def col(field):
        return np.array([getattr(classes[n], field) for n in names], dtype=float).T  # (2, n_classes)

    shape = np.array([("sphere", "cylinder").index(classes[n].shape) for n in names], dtype=np.int64)
    length = np.array([classes[n].length_mm or (0.0, 0.0) for n in names], dtype=float).T
    return ClassTable(names, np.cumsum(w) / w.sum(), col("shear_modulus_kpa"), col("radius_mm"), col("thickness_mm"),
                      col("density_kg_m3"), col("failure_strain"), col("failure_stress_kpa"), shape, length)
