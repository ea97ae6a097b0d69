"""The solver study's charts: speed against accuracy, the stability map and the step-size study, drawn from
``solvers.json``'s records and ``solvers_details.json`` (matplotlib, imported only when a chart is drawn, with the
``Agg`` backend; each PNG written atomically by :func:`pneunet_env.files.save_figure`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pneunet_env.bench.solver_methods import FAILURES, OUTCOMES
from pneunet_env.files import save_figure

__all__ = ["OUTCOME_COLOURS", "plot_speed_accuracy", "plot_stability_map", "plot_step_size"]

OUTCOME_COLOURS = {
    "correct": "#2ca02c",
    "slow": "#98df8a",
    "model error": "#bcbd22",
    "no convergence": "#ff7f0e",
    "wrong branch": "#d62728",
    "saddle/maximum": "#9467bd",
    "left the domain": "#8c564b",
    "NaN": "#111111",
}
"""Each outcome's colour on the stability map."""


def plot_speed_accuracy(records: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(r["method"] for r in records))
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(methods)}
    markers = dict(zip(scenes, "osD^v<>pPX*h", strict=False))
    floor, cap, nan_level = 1e-16, 3.0, 30.0
    fig, ax = plt.subplots(figsize=(9.5, 6.2))
    for r in records:
        err = nan_level if r["error"] is None else min(max(r["error"], floor), cap)
        failed = r["failure"] is not None
        ax.scatter(r["time_s"], err, s=70 if r["default"] else 42, marker=markers[r["scene"]],
                   facecolors="none" if failed else colours[r["method"]], edgecolors=colours[r["method"]],
                   linewidths=1.6, zorder=3)
    ok = [r for r in records if r["failure"] is None and r["error"] is not None]
    front, best = [], math.inf
    for t, e in sorted((r["time_s"], min(max(r["error"], floor), cap)) for r in ok):
        if e < best:  # not dominated: nothing at least as fast is at least as accurate
            front.append((t, e))
            best = e
    if front:
        ts = [t for t, _ in front] + [front[-1][0] * 30]  # the front continues: slower is no better
        es = [e for _, e in front] + [front[-1][1]]
        ax.step(ts, es, where="post", color="k", ls="--", lw=1.0, zorder=2)
    ax.axhspan(nan_level / 2, nan_level * 2, color="0.9", zorder=0)
    ax.text(0.99, nan_level, "NaN ", transform=ax.get_yaxis_transform(), ha="right", va="center", fontsize=8)
    ax.text(0.99, cap, "≥ 3 ", transform=ax.get_yaxis_transform(), ha="right", va="center", fontsize=8)
    ax.axhline(1e-9, color="0.5", lw=0.8, ls=":")
    ax.text(0.99, 1e-9, "1e-9 ", transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=8, color="0.4")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time per solve [s] (this machine, warm-started along the scene)")
    ax.set_ylabel("max error along the scene, max(|Δκ~|, |Δe_s|), vs mpmath reference")
    ax.set_ylim(floor / 3, nan_level * 2)
    from matplotlib.lines import Line2D

    h_m = [Line2D([], [], ls="", marker="o", color=colours[m], label=m) for m in methods]
    h_s = [Line2D([], [], ls="", marker=markers[s], color="0.3", mfc="none", label=s) for s in scenes]
    h_f = [Line2D([], [], ls="", marker="o", mfc="none", mec="0.3", label="hollow: failed somewhere")]
    h_p = [Line2D([], [], ls="--", color="k", label="Pareto front")]
    leg1 = ax.legend(handles=h_m, title="method", loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.add_artist(leg1)
    ax.legend(handles=h_s + h_f + h_p, title="scene", loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8)
    ax.set_title("Speed against accuracy: every method on every scene")
    ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def plot_stability_map(details: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    mp = details["map"]
    ps, ks = np.array(mp["pressures"]), mp["stiffnesses"]
    names = list(mp["outcomes"])
    cmap = ListedColormap([OUTCOME_COLOURS[o] for o in OUTCOMES])
    ncol = 3
    nrow = math.ceil(len(names) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.9 * nrow + 0.8), sharex=True, sharey=True,
                             squeeze=False)
    dp = ps[1] - ps[0]
    xedges = np.concatenate([ps - dp / 2, [ps[-1] + dp / 2]])
    yedges = np.arange(len(ks) + 1) - 0.5
    for ax, name in zip(axes.flat, names, strict=False):
        codes = np.array([[OUTCOMES.index(o) for o in row] for row in mp["outcomes"][name]])
        ax.pcolormesh(xedges, yedges, codes, cmap=cmap, vmin=-0.5, vmax=len(OUTCOMES) - 0.5)
        present = sorted({o for row in mp["outcomes"][name] for o in row}, key=OUTCOMES.index)
        fails = sum(o in FAILURES for row in mp["outcomes"][name] for o in row)
        ax.set_title(f"{name}  ({fails} failed cells)", fontsize=9)
        del present
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    labels = ["0 (free)" if k == 0 else f"{k:.0e}" for k in ks]
    for ax in axes[:, 0]:
        ax.set_yticks(range(len(ks)))
        ax.set_yticklabels(labels, fontsize=7)
        ax.set_ylabel("object k~")
    for ax in axes[-1, :]:
        ax.set_xlabel("pressure p~")
    handles = [Patch(color=OUTCOME_COLOURS[o], label=o) for o in OUTCOMES]
    fig.legend(handles=handles, loc="lower center", ncol=len(OUTCOMES), fontsize=8, frameon=False)
    fig.suptitle(f"Stability map: one solve at each cell, warm-started from the exact equilibrium at p~ - {dp:.2g} "
                 f"(w κ_obj = {mp['object_curvature']}; reference: mpmath)", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    save_figure(fig, path, dpi=110)


def plot_step_size(details: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    st = details["step_size"]
    rows = st["rows"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    steps = sorted({r["increment"] for r in rows})
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(methods)}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2), gridspec_kw={"width_ratios": [1.2, 1]})
    floor, cap, nan_level = 1e-16, 3.0, 30.0
    for m in methods:
        rr = sorted((r for r in rows if r["method"] == m), key=lambda r: r["increment"])
        x = [r["increment"] for r in rr]
        y = [nan_level if r["error"] is None else min(max(r["error"], floor), cap) for r in rr]
        ax1.plot(x, y, "-o", color=colours[m], label=m, ms=4)
    ax1.axhspan(nan_level / 2, nan_level * 2, color="0.9", zorder=0)
    ax1.text(0.01, nan_level, " NaN", transform=ax1.get_yaxis_transform(), ha="left", va="center", fontsize=8)
    ax1.text(0.01, cap, " ≥ 3", transform=ax1.get_yaxis_transform(), ha="left", va="bottom", fontsize=8)
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_ylim(floor / 3, nan_level * 2)
    ax1.set_xticks(steps)
    ax1.set_xticklabels([f"{v:g}" for v in steps])
    ax1.minorticks_off()
    ax1.set_xlabel("pressure increment Δp~ per solve")
    ax1.set_ylabel("max error of the path vs mpmath reference")
    ax1.set_title(f"Quasi-static path, k~ = {st['object_stiffness']:g}: load to {st['p_max']} and unload")
    ax1.legend(fontsize=8, loc="center left")
    ax1.grid(True, alpha=0.3)
    style = {"captured": ("o", "#2ca02c", "captured"), "missed": ("X", "#d62728", "missed (wrong branch)"),
             "unresolved": ("s", "0.75", "no pressure inside the loop")}
    for j, m in enumerate(methods):
        for r in rows:
            if r["method"] != m:
                continue
            mk, col, _ = style[r["loop"]]
            ax2.scatter(steps.index(r["increment"]), j, marker=mk, color=col, s=90)
    ax2.set_yticks(range(len(methods)))
    ax2.set_yticklabels(methods, fontsize=8)
    ax2.set_xticks(range(len(steps)))
    ax2.set_xticklabels([f"{s:g}" for s in steps])
    ax2.set_xlabel("pressure increment Δp~ per solve")
    ax2.invert_yaxis()
    pd_, pu = st["fold_window"]
    ax2.set_title(f"Loop captured? (bistable for {pd_:.3f} < p~ < {pu:.3f}; every grid holds p~ = {st['anchor']:g})",
                  fontsize=10)
    from matplotlib.lines import Line2D

    ax2.legend(handles=[Line2D([], [], ls="", marker=v[0], color=v[1], label=v[2]) for v in style.values()],
               loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8, frameon=False)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
