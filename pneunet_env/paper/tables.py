"""The figure tables: :class:`Table` (named columns of one figure's data) and its CSV files.

Every figure's data is one :class:`Table` with the columns of :data:`COLUMNS`, one row per state, written as
``NAME.csv`` by :func:`write_table` (atomically) and read back by :func:`read_table`. The pressure, curvature,
force and stiffness columns are dimensionless (``p~ = p/mu``, ``kappa~ = w kappa``, ``F~ = F/mu``,
``k~ = k_obj w/mu``); ``pressure_kpa``, ``curvature_per_m`` and ``contact_force_kpa`` give them in physical units
at the row's ``mu`` (kPa) and ``w`` (mm). Booleans are written as 0/1.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from pneunet_env.files import atomic_write_text

__all__ = ["COLUMNS", "Table", "read_table", "write_table"]

COLUMNS = (
    "figure",
    "series",
    "model",
    "sweep",
    "sweep_value",
    "branch",
    "pressure",
    "curvature",
    "side_strain",
    "top_strain",
    "contact_force",
    "indentation",
    "in_contact",
    "dcurvature_dpressure",
    "dforce_dpressure",
    "snapped",
    "converged",
    "gradient_norm",
    "min_eigenvalue",
    "regime",
    "object_stiffness",
    "object_curvature",
    "chamber_height",
    "base_thickness",
    "side_thickness",
    "top_thickness",
    "base_modulus",
    "poisson_ratio",
    "gent_limit",
    "shear_modulus_kpa",
    "width_mm",
    "pressure_kpa",
    "curvature_per_m",
    "contact_force_kpa",
)
"""The columns of every figure table. ``branch`` is ``loading`` or ``unloading``; ``model`` is ``full`` (energy
minimisation) or ``quadratic`` (supplement eq. 15); ``sweep`` names the parameter varied in the figure and
``sweep_value`` its value; ``dcurvature_dpressure`` and ``dforce_dpressure`` are the exact tangents of the
equilibrium path (``dx/dp = H^{-1} dV/dx``), not finite differences; ``regime`` is
:func:`pneunet_env.paper.data.classify_regimes`'s."""

_STRING_COLUMNS = frozenset({"figure", "series", "model", "sweep", "branch", "regime"})
_BOOL_COLUMNS = frozenset({"in_contact", "snapped", "converged"})


class Table:
    """Named columns of equal length (numpy arrays): one figure's data.

    ``table["pressure"]`` is a column; ``table.where(series="free", branch="loading")`` the rows matching
    every condition (equality; a float condition matches to 1e-12 relative).
    """

    def __init__(self, columns: Mapping[str, Sequence | np.ndarray]) -> None:
        self.columns: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in columns.items()}
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"columns differ in length: { {k: len(v) for k, v in self.columns.items()} }")

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; columns: {sorted(self.columns)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def mask(self, **conditions) -> np.ndarray:
        m = np.ones(len(self), dtype=bool)
        for name, value in conditions.items():
            col = self[name]
            if isinstance(value, (float, int)) and not isinstance(value, bool) and col.dtype.kind == "f":
                m &= np.isclose(col, value, rtol=1e-12, atol=0.0)
            else:
                m &= col == value
        return m

    def where(self, **conditions) -> Table:
        return self.take(self.mask(**conditions))

    def take(self, index) -> Table:
        return Table({k: v[index] for k, v in self.columns.items()})

    def unique(self, name: str) -> list:
        """The distinct values of a column, in order of first appearance."""
        col = self[name]
        _, first = np.unique(col, return_index=True)
        return [col[i].item() if hasattr(col[i], "item") else col[i] for i in sorted(first)]

    @staticmethod
    def concat(tables: Iterable[Table]) -> Table:
        tables = [t for t in tables if len(t)]
        if not tables:
            return Table({c: np.array([]) for c in COLUMNS})
        names = list(tables[0].columns)
        return Table({n: np.concatenate([t[n] for t in tables]) for n in names})


def write_table(table: Table, path: str | Path) -> None:
    """Write ``table`` as CSV (header row, floats with 10 significant digits, booleans as 0/1)."""
    names = list(table.columns)
    cols = []
    for n in names:
        c = table[n]
        if n in _BOOL_COLUMNS or c.dtype.kind == "b":
            cols.append([str(int(v)) for v in c])
        elif c.dtype.kind == "f":
            cols.append([format(float(v), ".10g") for v in c])
        else:
            cols.append([str(v) for v in c])
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(names)
    w.writerows(zip(*cols, strict=True))
    atomic_write_text(path, buf.getvalue())


def read_table(path: str | Path) -> Table:
    """Read a CSV written by :func:`write_table` back into a :class:`Table` (types restored by column name)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ValueError(f"{path}: empty file, expected a header row")
    names, body = rows[0], rows[1:]
    data = list(zip(*body, strict=True)) if body else [() for _ in names]
    out: dict[str, np.ndarray] = {}
    for n, col in zip(names, data, strict=True):
        if n in _STRING_COLUMNS:
            out[n] = np.array(col, dtype=object)
        elif n in _BOOL_COLUMNS:
            out[n] = np.array([v == "1" for v in col], dtype=bool)
        else:
            out[n] = np.array([float(v) for v in col], dtype=float)
    return Table(out)
