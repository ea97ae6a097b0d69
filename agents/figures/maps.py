"""The figure of ``pneunet-grasp map``: ``map.png`` (:func:`plot_map`), from the map's record.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.envs import RIGID_ENV
from agents.common.map_record import _arr, _pct, summarize
from agents.common.words import phi_definition
from agents.figures.style import _matplotlib
from pneunet_env.files import save_figure

__all__ = ["plot_map"]


_WINDOW_COLOUR = "#e0007a"


_CLASS_COLOUR = "#1f4fa0"


def _edges(x: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around centres ``x`` (geometric midpoints on a log axis)."""
    v = np.log10(x) if log else np.asarray(x, float)
    if v.size == 1:
        e = np.array([v[0] - 0.5, v[0] + 0.5]) if log else np.array([v[0] * 0.9, v[0] * 1.1])
    else:
        mid = 0.5 * (v[1:] + v[:-1])
        e = np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])
    return 10.0 ** e if log else e


def _outline(ax, mask: np.ndarray, xe: np.ndarray, ye: np.ndarray, **kw) -> None:
    """Draw the boundary of the ``True`` cells of ``mask`` (rows: y, columns: x) along the cell edges."""
    ny, nx = mask.shape
    m = np.pad(mask, 1, constant_values=False)
    segs = []
    for i in range(ny + 1):  # horizontal edges between rows i-1 and i
        for j in range(nx):
            if m[i, j + 1] != m[i + 1, j + 1]:
                segs.append([(xe[j], ye[i]), (xe[j + 1], ye[i])])
    for i in range(ny):  # vertical edges between columns j-1 and j
        for j in range(nx + 1):
            if m[i + 1, j] != m[i + 1, j + 1]:
                segs.append([(xe[j], ye[i]), (xe[j], ye[i + 1])])
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(segs, **kw))


def _marks(ax, E, Y, p) -> None:
    """``d`` (damaged) or ``s`` (slipped) on each cell that mostly fails."""

    s, d, sl = _arr(p["success"]), _arr(p["damage"]), _arr(p["slip"])
    for i, y in enumerate(Y):
        for j, e in enumerate(E):
            if s[i, j] < 0.5:
                ax.text(e, y, "d" if d[i, j] >= sl[i, j] else "s", ha="center", va="center", fontsize=7,
                        color="#5a1010" if d[i, j] >= sl[i, j] else "#6a4a00", zorder=4)


def plot_map(result: dict[str, Any], path: str | Path) -> Path:
    """One PNG: a panel per policy (success rate, shared colour scale), the regime boundary, the feasible window and
    the catalogue's classes on each; with a density row, a second, smaller row of panels (``E`` x density)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle


    plt = _matplotlib()
    E = np.asarray(result["youngs_modulus_kpa"], float)
    R = np.asarray(result["radius_mm"], float)
    roles = result["roles"]
    row = result.get("density_row")
    n = len(roles)
    heights = [3.0, 1.25] if row else [3.0]
    fig = plt.figure(figsize=(5.0 * n + 0.9, 5.6 + (2.4 if row else 0.0)))
    gs = fig.add_gridspec(len(heights), n + 1, height_ratios=heights, width_ratios=[1.0] * n + [0.05],
                          hspace=0.62, wspace=0.22)
    xe, ye = _edges(E, True), _edges(R, False)
    window = _arr(result["window"]) > 0.5
    pf = result["phi_fine"]
    phi_fine = _arr(pf["phi"])
    summary = result.get("summary") or summarize(result)
    cmap = plt.get_cmap("YlGn")
    mesh = None
    for k, role in enumerate(roles):
        p = result["policies"][role]
        ax = fig.add_subplot(gs[0, k])
        mesh = ax.pcolormesh(xe, ye, _arr(p["success"]), cmap=cmap, vmin=0.0, vmax=1.0, shading="flat", zorder=1)
        _marks(ax, E, R, p)
        if len(pf["youngs_modulus_kpa"]) > 1 and len(pf["radius_mm"]) > 1 and np.nanmin(phi_fine) < 0.5 < np.nanmax(
                phi_fine):
            ax.contour(pf["youngs_modulus_kpa"], pf["radius_mm"], phi_fine, levels=[0.5], colors="black",
                       linestyles="--", linewidths=1.6, zorder=5)
            _regime_labels(ax, np.asarray(pf["youngs_modulus_kpa"]), np.asarray(pf["radius_mm"]), phi_fine)
        _outline(ax, window, xe, ye, colors=_WINDOW_COLOUR, linewidths=2.4, zorder=6)
        for box in result.get("catalogue", []):
            (e0, e1), (r0, r1) = box["youngs_modulus_kpa"], box["radius_mm"]
            ax.add_patch(Rectangle((e0, r0), e1 - e0, r1 - r0, fill=False, ec=_CLASS_COLOUR, lw=1.3, ls=":",
                                   zorder=7))
            ax.text(math.sqrt(e0 * e1), r1 - 0.4, box["name"].replace("_", " "), ha="center", va="top", fontsize=7,
                    color=_CLASS_COLOUR, zorder=8, bbox=dict(boxstyle="round,pad=0.12", fc="white", ec="none",
                                                             alpha=0.75))
        ax.set_xscale("log")
        ax.set_xlim(xe[0], xe[-1])
        ax.set_ylim(ye[0], ye[-1])
        ax.set_xlabel("object Young's modulus E (kPa)")
        if k == 0:
            ax.set_ylabel("object radius R (mm)")
        s = summary[role]
        ax.set_title(f"{_title(role, p, result)}\nsuccess {_pct(s['success'])} of cells; in the window "
                     f"{_pct(s['success_in_window'])} (force side {_pct(s['success_in_window_force'])}, position "
                     f"side {_pct(s['success_in_window_position'])})", fontsize=8.5)
    cax = fig.add_subplot(gs[0, n])
    fig.colorbar(mesh, cax=cax).set_label("success rate (held to the end, intact)", fontsize=8)
    if row:
        _density_row(fig, gs, row, E, roles, cmap, result)
    handles, labels = _legend(result, Line2D, Patch)
    inch = 1.0 / fig.get_figheight()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, 0.42 * inch))
    fig.text(0.5, 0.1 * inch, _caption(result), ha="center", va="bottom", fontsize=8, wrap=False)
    fig.suptitle(_suptitle(result), fontsize=9.5)
    fig.subplots_adjust(left=0.05, right=0.955, top=1.0 - 1.25 * inch, bottom=1.45 * inch)
    return save_figure(fig, path, dpi=120)


def _legend(result: dict[str, Any], Line2D, Patch) -> tuple[list, list[str]]:
    """The figure's legend: the boundary, the window, the classes (if any), the failure marks."""
    handles = [Line2D([], [], color="black", ls="--", lw=1.6), Line2D([], [], color=_WINDOW_COLOUR, lw=2.4)]
    labels = [f"regime boundary phi = 1/2 at {result['regime_pressure_kpa']:g} kPa: force-controlled left, "
              "position-controlled right", "feasible window: where the oracle succeeds"]
    if result.get("catalogue"):
        handles.append(Patch(fill=False, ec=_CLASS_COLOUR, ls=":", lw=1.3))
        labels.append(f"catalogue class (E x R box) of {_use_case(result)}")
    handles += [Line2D([], [], ls="", marker="$d$", color="#5a1010", ms=7),
                Line2D([], [], ls="", marker="$s$", color="#6a4a00", ms=7)]
    labels += ["failed: damaged (crushed or overstressed)", "failed: slipped (dropped)"]
    return handles, labels


def _use_case(result: dict[str, Any]) -> str:
    """``"the catalogue's 'kitchen' use case"``: the task's description up to its weights."""
    return str(result.get("task", "the default use case")).split(" (")[0]


def _caption(result: dict[str, Any]) -> str:
    """The footnote under the legend: the regime boundary's terms, in words, on two lines."""

    text = result.get("regime_boundary") or phi_definition(result["regime_pressure_kpa"])
    head, _, sides = text.partition("; ")
    return f"{head};\n{sides}"


def _suptitle(result: dict[str, Any]) -> str:
    damage = result.get("damage") or f"{result['damage_rule']} rule"
    return (f"Grasp success over object modulus x radius: {result['thickness_rule']}, rho = "
            f"{result['density_kg_m3']:g} kg/m^3, failure strain eps_f = {result['failure_strain']:g}, "
            f"{result['episodes']} episode(s) per cell; blind policies tuned on {_use_case(result)}\n{damage}")


def _title(role: str, p: dict[str, Any], result: dict[str, Any]) -> str:

    if role == "oracle":
        return "oracle (knows the object; best constant pressure)"
    if p.get("env_id") == RIGID_ENV and result.get("jaw_nominal_radius_mm"):
        return f"blind: {p['label']},\nclosure past a nominal R = {result['jaw_nominal_radius_mm']:.3g} mm surface"
    return f"blind: {p['label']}"


def _regime_labels(ax, fE, fR, phi) -> None:
    """'force-controlled' left of the boundary and 'position-controlled' right of it, at the lowest radius."""
    j = np.where(phi[0] >= 0.5)[0]
    if j.size == 0:
        return
    e_b = fE[j[0]]
    y = fR[0] + 0.035 * (fR[-1] - fR[0])
    kw = dict(fontsize=7.5, va="bottom", zorder=9, bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none",
                                                             alpha=0.8))
    ax.text(e_b / 1.25, y, "force-\ncontrolled", ha="right", **kw)
    ax.text(e_b * 1.25, y, "position-\ncontrolled", ha="left", **kw)


def _density_row(fig, gs, row, E, roles, cmap, result) -> None:
    import matplotlib.ticker


    D = np.asarray(row["density_kg_m3"], float)
    xe, de = _edges(E, True), _edges(D, True)
    pf = row["phi_fine"]
    fE, fphi = np.asarray(pf["youngs_modulus_kpa"], float), np.array([np.nan if v is None else v for v in pf["phi"]])
    cross = fE[np.where(fphi >= 0.5)[0][0]] if (fphi >= 0.5).any() and (fphi < 0.5).any() else None
    window = _arr(row["policies"]["oracle"]["success"]) >= 0.5
    for k, role in enumerate(roles):
        p = row["policies"][role]
        ax = fig.add_subplot(gs[1, k])
        ax.pcolormesh(xe, de, _arr(p["success"]), cmap=cmap, vmin=0.0, vmax=1.0, shading="flat", zorder=1)
        _marks(ax, E, D, p)
        if cross is not None:
            ax.axvline(cross, color="black", ls="--", lw=1.6, zorder=5)
        _outline(ax, window, xe, de, colors=_WINDOW_COLOUR, linewidths=2.4, zorder=6)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(xe[0], xe[-1])
        ax.set_ylim(de[0], de[-1])
        ax.set_yticks(D)
        ax.set_yticklabels([f"{d:g}" for d in D])
        ax.yaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_xlabel("object Young's modulus E (kPa)")
        if k == 0:
            ax.set_ylabel("density (kg/m^3)")
        s = _arr(p["success"])
        h = row["radius_mm"] * result["thickness_ratio"]
        ax.set_title(f"{role} at R = {row['radius_mm']:g} mm (H = {h:g} mm); success over E by density:\n"
                     + ", ".join(f"{d:g} kg/m^3: {np.nanmean(s[i]):.0%}" for i, d in enumerate(D)), fontsize=8)
