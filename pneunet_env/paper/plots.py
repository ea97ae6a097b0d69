"""The figures' plots: each figure's :class:`~pneunet_env.paper.tables.Table` drawn as a PNG (matplotlib, imported
only when a plot is drawn, with the ``Agg`` backend).

Loading is drawn solid and, where it differs, unloading dashed; a jump across a fold is a dotted arrow ending in a
triangle. Each ``plot_*`` function writes its PNG atomically (:func:`pneunet_env.files.save_figure`, 130 dpi).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pneunet_env.files import save_figure
from pneunet_env.paper.data import (
    CONTROL_ELASTICITY,
    DEFAULT_PARAMS,
    FIG2_STIFFNESSES,
    HYSTERESIS_TOL,
    OBJECT_CURVATURE,
    PAPER_PRESSURE_MAX,
    REGIMES,
    critical_pressure,
    curve_value,
    loading,
    unloading,
)
from pneunet_env.paper.tables import Table

__all__ = [
    "REGIME_COLORS", "plot_fig2", "plot_fig3", "plot_regime_map", "plot_supp_base", "plot_supp_fig2cd",
    "plot_supp_fig3", "plot_supp_physical",
]

def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _differs(load_c: Table, unload_c: Table) -> np.ndarray:
    """Mask (loading grid order) where unloading differs from loading, grown by one point for continuity."""
    d = np.abs(load_c["curvature"] - unload_c["curvature"]) > HYSTERESIS_TOL
    grown = d.copy()
    grown[1:] |= d[:-1]
    grown[:-1] |= d[1:]
    return grown


def _break_at(x: np.ndarray, y: np.ndarray, cut: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert a gap (NaN) after every index ``i`` with ``cut[i]``: no line segment from ``i`` to ``i + 1``."""
    idx = np.flatnonzero(cut[:-1]) + 1
    return np.insert(x.astype(float), idx, np.nan), np.insert(y.astype(float), idx, np.nan)


def _draw_curves(ax, table: Table, series: Sequence[str], y: str, x: str = "pressure", colors=None,
                 mark_snaps: bool = True, label_snaps: bool = True) -> None:
    """Draw loading (solid) and, where it differs, unloading (dashed) for each series.

    A jump across a fold is not drawn as a line: a dotted arrow goes from the last state before the fold to
    the first after it, ending in a triangle (pointing down: loading, up: unloading).
    """
    plt = _plt()
    if colors is None:
        colors = plt.cm.viridis(np.linspace(0.0, 0.9, len(series)))
    snap_labelled = False
    for s, c in zip(series, colors, strict=True):
        lo, un = loading(table, series=s), unloading(table, series=s)  # both in increasing pressure
        lo_snap = lo["snapped"]
        cut_lo = np.zeros(len(lo), dtype=bool)
        cut_lo[:-1] = lo_snap[1:]
        ax.plot(*_break_at(lo[x], lo[y], cut_lo), color=c, lw=1.6, label=s)
        jumps = [(lo, i - 1, i, "v") for i in np.flatnonzero(lo_snap) if i > 0]
        if len(un) == len(lo):
            un_snap = un["snapped"]
            m = _differs(lo, un)
            if m.any():
                yv = np.where(m, un[y], np.nan)
                ax.plot(*_break_at(un[x], yv, un_snap), color=c, lw=1.4, ls="--", zorder=3)
            jumps += [(un, j + 1, j, "^") for j in np.flatnonzero(un_snap) if j + 1 < len(un)]
        if not mark_snaps:
            continue
        for branch, i0, i1, marker in jumps:
            lab = None
            if label_snaps and not snap_labelled:
                lab = "snap-through (fold)"
                snap_labelled = True
            ax.annotate("", xy=(branch[x][i1], branch[y][i1]), xytext=(branch[x][i0], branch[y][i0]),
                        arrowprops={"arrowstyle": "->", "color": c, "lw": 1.0, "ls": ":"}, zorder=4)
            ax.plot([branch[x][i1]], [branch[y][i1]], marker=marker, color=c, ms=7, mec="k", mew=0.6, ls="none",
                    label=lab, zorder=5)


def _finish(fig, path: Path, note: str = "") -> None:
    if note:
        lines = note.count("\n") + 1
        engine = fig.get_layout_engine()
        if engine is not None and hasattr(engine, "set"):
            engine.set(rect=(0.0, 0.018 * lines + 0.01, 1.0, 1.0 - 0.018 * lines - 0.01))
        fig.text(0.01, 0.005, note, fontsize=7, color="0.35", ha="left", va="bottom")
    save_figure(fig, path, dpi=130)


def plot_fig2(table: Table, path: Path) -> None:
    plt = _plt()
    series = table.unique("series")
    colors = ["k"] + list(plt.cm.viridis(np.linspace(0.0, 0.85, len(series) - 1)))
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    _draw_curves(a, table, series, "curvature", colors=colors)
    a.axhline(OBJECT_CURVATURE, color="0.6", lw=0.8, ls=":")
    a.text(0.01, OBJECT_CURVATURE, " w kappa_obj", color="0.4", fontsize=7, va="bottom")
    a.set(xlabel="pressure  p~ = p/mu", ylabel="curvature  kappa~ = w kappa", xlim=(0, PAPER_PRESSURE_MAX),
          title="(a) curvature")
    a.legend(fontsize=7, loc="upper left")
    obj = [s for s in series if s != "free actuator"]
    _draw_curves(b, table, obj, "contact_force", colors=colors[1:])
    b.set_yscale("log")
    b.set_ylim(1e-7, None)
    b.set(xlabel="pressure  p~ = p/mu", ylabel="contact traction  F~ = F/mu", xlim=(0, PAPER_PRESSURE_MAX),
          title="(b) contact force")
    b.legend(fontsize=7, loc="lower right")
    fig.suptitle("Fig. 2: grasping objects of different stiffness (J = 15, w kappa_obj = 0.02, d = w, h = w/2, "
                 "E_b = 60 mu, nu = 1/2); dashed: unloading where it differs", fontsize=9)
    _finish(fig, path)


def _sweep_panels(table: Table, path: Path, panels: Sequence[tuple[str, str]], suptitle: str, x="pressure",
                  y="curvature", xlabel="pressure  p~ = p/mu", ylabel="curvature  kappa~ = w kappa",
                  markers: Callable | None = None) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.4), constrained_layout=True)
    axes = np.atleast_1d(axes)
    for ax, (sweep, title) in zip(axes, panels, strict=True):
        sub = table.where(sweep=sweep)
        series = sub.unique("series")
        colors = plt.cm.plasma(np.linspace(0.0, 0.85, len(series)))
        _draw_curves(ax, sub, series, y, x=x, colors=colors)
        if markers is not None:
            markers(ax, sub, series, colors)
        else:
            for s, c in zip(series, colors, strict=True):
                lo = loading(sub, series=s)
                pc, _ = critical_pressure(lo)
                ax.plot([pc], [curve_value(lo, y, pc)], "o", color=c, mfc="none", ms=6)
        ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
        ax.set_xlim(0, None)
        ax.set_ylim(0, None)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(suptitle, fontsize=9)
    _finish(fig, path, "open circles: critical pressure (max d kappa/dp on loading); dashed: unloading where it "
                       "differs; triangles: snap-through")


def plot_fig3(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("top_thickness", "(a) top wall h_m/w"), ("side_thickness", "(b) side wall h_s/w")],
                  "Fig. 3: free actuator, J = 20, other walls w/2, d = w, E_b = 60 mu, nu = 1/2")


def plot_supp_fig2cd(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("chamber_height", "(c) aspect ratio d/w"), ("gent_limit", "(d) Gent limit J")],
                  "Supplement Fig. 2c,d: free actuator, h = w/2, E_b = 60 mu, nu = 1/2, J = 20 unless swept")


def plot_supp_base(table: Table, path: Path) -> None:
    _sweep_panels(table, path, [("base_modulus", "base modulus E_b/mu"), ("base_thickness", "base thickness h_b/w")],
                  "Supplement section 4: varying the base, E_b/mu and h_b/w (free actuator, J = 20)")


def plot_supp_physical(table: Table, path: Path) -> None:
    def marks(ax, sub, series, colors):
        for s, c in zip(series, colors, strict=True):
            lo = loading(sub, series=s)
            pc, _ = critical_pressure(lo)
            mu = float(lo["shear_modulus_kpa"][0])
            ax.plot([pc * mu], [curve_value(lo, "curvature_per_m", pc)], "o", color=c, mfc="none", ms=6)

    _sweep_panels(
        table, path,
        [("shear_modulus_kpa", "elastomer shear modulus mu (E_b = 3 MPa fixed)"),
         ("width_mm", "chamber width w (d = 5 mm, walls 2.5 mm fixed)")],
        "Supplement section 4 in physical units (J = 20)", x="pressure_kpa", y="curvature_per_m",
        xlabel="pressure  p (kPa)", ylabel="curvature  kappa (1/m)", markers=marks,
    )


def plot_supp_fig3(table: Table, path: Path) -> None:
    plt = _plt()
    full = loading(table, series="full energy")
    quad = table.where(model="quadratic")
    quad = quad.take(np.argsort(quad["pressure"]))
    pc, _ = critical_pressure(full)
    fig, (a, b) = plt.subplots(2, 1, figsize=(6.4, 6.2), sharex=True, constrained_layout=True,
                               gridspec_kw={"height_ratios": [3, 1.4]})
    a.plot(full["pressure"], full["curvature"], "k", lw=1.8, label="full energy minimisation")
    a.plot(quad["pressure"], quad["curvature"], color="tab:red", lw=1.6, ls="--", label="quadratic energy (eq. 15)")
    slope = DEFAULT_PARAMS.small_pressure_slope
    a.plot(full["pressure"], slope * full["pressure"], color="tab:blue", lw=1.0, ls=":",
           label=f"leading order, eq. 17 (slope {slope:.4f})")
    a.axvline(pc, color="0.5", lw=0.8, ls=":")
    a.text(pc, 0.02, f" p~_c = {pc:.3f}", color="0.3", fontsize=8)
    a.set(ylabel="curvature  kappa~", title="Supplement Fig. 3: full model vs quadratic energy (J = 20, defaults)")
    a.set_ylim(0, None)
    a.legend(fontsize=8, loc="upper left")
    kf = np.interp(quad["pressure"], full["pressure"], full["curvature"])
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.where(kf > 0, quad["curvature"] / kf - 1.0, np.nan)
    b.plot(quad["pressure"], 100 * err, color="tab:red", lw=1.4)
    b.axhline(0, color="0.6", lw=0.6)
    for lvl in (-10, 10):
        b.axhline(lvl, color="0.6", lw=0.6, ls=":")
    b.axvline(pc, color="0.5", lw=0.8, ls=":")
    b.set(xlabel="pressure  p~ = p/mu", ylabel="quadratic / full - 1 (%)", xlim=(0, PAPER_PRESSURE_MAX))
    _finish(fig, path)


REGIME_COLORS = {
    "free": "#dddddd",
    "position-controlled": "#3b6fb6",
    "force-controlled": "#e08a2c",
    "snap-through": "#c0392b",
    "transition": "#9ccf8c",
}


def plot_regime_map(table: Table, path: Path) -> None:
    plt = _plt()
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    lo = table.where(branch="loading")
    ks = np.array(sorted(set(lo["object_stiffness"].tolist())))
    ps = np.array(sorted(set(lo["pressure"].tolist())))
    idx = {r: i for i, r in enumerate(REGIMES)}
    grid = np.full((ps.size, ks.size), np.nan)
    ki = np.searchsorted(ks, lo["object_stiffness"])
    pi = np.searchsorted(ps, lo["pressure"])
    grid[pi, ki] = [idx[r] for r in lo["regime"]]
    lk = np.log10(ks)
    mid = 0.5 * (lk[1:] + lk[:-1])
    edges_k = np.concatenate([[lk[0] - (mid[0] - lk[0])], mid, [lk[-1] + (lk[-1] - mid[-1])]])
    edges_p = np.concatenate([[ps[0]], 0.5 * (ps[1:] + ps[:-1]), [ps[-1]]])
    cmap = ListedColormap([REGIME_COLORS[r] for r in REGIMES])
    fig, ax = plt.subplots(figsize=(8.2, 5.2), constrained_layout=True)
    ax.pcolormesh(10**edges_k, edges_p, grid, cmap=cmap, vmin=-0.5, vmax=len(REGIMES) - 0.5, shading="flat")
    ax.set_xscale("log")
    # Folds: where loading snaps up (solid) and unloading snaps back (dashed).
    for branch, style, lab in (("loading", "k-", "fold crossed on loading"), ("unloading", "k--", "fold on unloading")):
        t = table.where(branch=branch, snapped=True)
        if len(t):
            xs, ys = [], []
            for k in ks:
                m = np.isclose(t["object_stiffness"], k)
                if m.any():
                    xs.append(k)
                    ys.append(t["pressure"][m].min() if branch == "loading" else t["pressure"][m].max())
            ax.plot(xs, ys, style, lw=1.2, label=lab)
    for k in FIG2_STIFFNESSES:
        ax.axvline(k, color="w", lw=0.6, ls=":")
    handles = [Patch(color=REGIME_COLORS[r], label=r) for r in REGIMES]
    h2, l2 = ax.get_legend_handles_labels()
    ax.legend(handles=handles + h2, fontsize=8, loc="upper left", framealpha=0.9)
    ax.set(xlabel="object stiffness  k~ = k_obj w / mu", ylabel="pressure  p~ = p/mu (loading)",
           title="Regime map (Fig. 2's actuator, J = 15, w kappa_obj = 0.02), quasi-static loading")
    _finish(fig, path, f"position-controlled: curvature elasticity d ln kappa / d ln p <= {CONTROL_ELASTICITY}; "
                       f"force-controlled: traction elasticity d ln F / d ln p <= {CONTROL_ELASTICITY};\n"
                       "snap-through: a fold was crossed, or the loading and unloading branches differ (hysteresis); "
                       "transition: in contact, neither held; dotted: Fig. 2's stiffnesses")
