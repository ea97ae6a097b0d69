"""What the paper checks share: :class:`CheckResult` (one statement, measured), the thresholds, and the helpers
that read the figure tables (:mod:`pneunet_env.paper.checks` lists every check; see its docstring for the
operational definitions).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from pneunet_env.paper.data import curve_value, loading, unloading
from pneunet_env.paper.tables import Table

__all__ = [
    "CheckResult", "OBJECT_CURVATURE_PER_M", "OBJECT_THICKNESS_MM", "SATURATED", "SOFT_MAX", "STIFF_MIN", "Tables",
    "elasticity", "format_numbers", "format_values", "free_curve", "is_decreasing", "is_increasing", "object_curve",
    "snap_index", "sweep_curves", "unload_snap_pressure",
]

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


def sweep_curves(table: Table, sweep: str) -> list[tuple[float, Table]]:
    """``(value, loading curve)`` for each curve of a sweep, in increasing parameter value."""
    sub = table.where(sweep=sweep)
    values = sorted(set(sub["sweep_value"].tolist()))
    return [(v, loading(sub, sweep_value=v)) for v in values]


def elasticity(curve: Table, column: str, derivative: str, pressure: float) -> float:
    """``d ln X / d ln p`` of ``column`` at ``pressure`` (exact tangent, interpolated on the grid)."""
    x = curve_value(curve, column, pressure)
    dx = curve_value(curve, derivative, pressure)
    return pressure * dx / x if x > 0 else math.inf


def is_increasing(ys: Sequence[float]) -> bool:
    return all(b > a for a, b in zip(ys, ys[1:], strict=False))


def is_decreasing(ys: Sequence[float]) -> bool:
    return all(b < a for a, b in zip(ys, ys[1:], strict=False))


def format_numbers(xs: Sequence[float], fmt: str = ".3f") -> str:
    return ", ".join("inf (snap)" if math.isinf(x) else format(x, fmt) for x in xs)


def format_values(xs: Sequence[float]) -> str:
    return ", ".join(f"{x:g}" for x in xs)


def object_curve(table: Table, k: float) -> Table:
    return loading(table, object_stiffness=k)


def free_curve(table: Table) -> Table:
    return loading(table, object_stiffness=0.0)


def snap_index(curve: Table) -> int | None:
    s = np.flatnonzero(curve["snapped"])
    return int(s[0]) if s.size else None


def unload_snap_pressure(table: Table, **conditions) -> float | None:
    un = unloading(table, **conditions)
    s = np.flatnonzero(un["snapped"])
    return float(un["pressure"][s].max()) if s.size else None
