"""The success map's record (``map.json``, :func:`agents.evaluation.maps.success_map`'s result), read: its
cells as arrays and its summary per policy. Used by the map's command and its figure.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["summarize"]


def _arr(x) -> np.ndarray:
    return np.array([[np.nan if v is None else v for v in row] for row in x], dtype=float)


def summarize(result: dict[str, Any]) -> dict[str, Any]:
    """Per role: success over all cells; inside the window (the oracle's successes), over its force-controlled
    (``phi < 1/2``) and position-controlled sides; failure modes outside the window; per radius, the ``E`` range
    that succeeds. ``grasps_both``: succeeds (rate >= 1/2) on some cell of each side of the boundary."""
    E = np.asarray(result["youngs_modulus_kpa"])
    phi = _arr(result["phi"])
    window = _arr(result["window"]) > 0.5
    force = phi < 0.5
    out: dict[str, Any] = {"cells": int(phi.size), "window_cells": int(window.sum()),
                           "window_force_cells": int((window & force).sum()),
                           "window_position_cells": int((window & ~force).sum())}

    def mean(a, m):
        return float(a[m].mean()) if m.any() else None

    for role in result["roles"]:
        p = result["policies"][role]
        s, d, sl = _arr(p["success"]), _arr(p["damage"]), _arr(p["slip"])
        ok = s >= 0.5
        out[role] = {
            "success": mean(s, np.ones_like(ok)),
            "success_in_window": mean(s, window),
            "success_in_window_force": mean(s, window & force),
            "success_in_window_position": mean(s, window & ~force),
            "success_outside_window": mean(s, ~window),
            "damage_outside_window": mean(d, ~window),
            "slip_outside_window": mean(sl, ~window),
            "grasps_both": bool((ok & force).any() and (ok & ~force).any()),
            "e_range_kpa_by_radius": [[float(E[row].min()), float(E[row].max())] if row.any() else None
                                      for row in ok],
        }
    return out


def _pct(x) -> str:
    return "-" if x is None else f"{x:.0%}"
