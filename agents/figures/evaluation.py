"""The figures of ``pneunet-grasp evaluate``: ``success_vs_stiffness.png`` (:func:`plot_success`) and
``schedules.png`` (:func:`plot_schedules`), from the rows and traces :mod:`agents.evaluation` computes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from agents.common.regimes import SOFT_MAX, STIFF_MIN, _paper_bins
from agents.common.words import damage_rule_text, slip_rule_text, task_description
from agents.figures.style import _matplotlib, _style
from pneunet_env.files import save_figure

if TYPE_CHECKING:
    from pneunet_env.config import EnvConfig


__all__ = ["plot_success", "plot_schedules"]


def plot_success(rows, path: str | Path, config: EnvConfig, title: str | None = None,
                 feasible_stiffness: float | None = None) -> Path:
    """Success (top) and damage / slip (bottom) vs ``k~`` for every policy, with the regimes: for objects drawn from
    the catalogue, each ``k~`` bin shaded by the regime most of its objects are in (read off the mechanics); on a
    pinned ``k~`` grid, the paper's soft and stiff bins shaded and, given ``feasible_stiffness`` (under the
    crush-fraction rule: :func:`agents.policies.oracle.feasible_stiffness`), the stiffness below which no state holds
    the object and spares it. The title names the task and its damage rule."""
    import textwrap

    from matplotlib.patches import Patch

    from pneunet_env.objects import stiffness_per_modulus

    plt = _matplotlib()
    drawn = not _paper_bins(rows)
    ks = np.array([k for r in rows for k in r.get("k_range", [r["object_stiffness"]])])
    lo, hi = (ks.min(), ks.max()) if drawn else (ks.min() / 1.3, ks.max() * 1.3)
    fig, (ax, ax_d, ax_s) = plt.subplots(3, 1, figsize=(8.6, 7.6), sharex=True,
                                         gridspec_kw=dict(height_ratios=[2.4, 1, 1]))
    force_c, position_c = ("#4c9be8", 0.12), ("#f0a030", 0.14)
    extra_handles, extra_labels = [], []
    for a in (ax, ax_d, ax_s):
        a.set_xscale("log")
        a.set_xlim(lo, hi)
        a.grid(True, which="major", alpha=0.3)
    if drawn:
        first = rows[0]["policy"]
        for r in (r for r in rows if r["policy"] == first):
            n = {g: c["episodes"] for g, c in r["by_regime"].items()}
            c, alpha = force_c if n.get("force-controlled", 0) >= n.get("position-controlled", 0) else position_c
            for a in (ax, ax_d, ax_s):
                a.axvspan(*r["k_range"], color=c, alpha=alpha, lw=0)
        p = config.task.max_pressure_kpa
        extra_handles = [Patch(color=force_c[0], alpha=2 * force_c[1]), Patch(color=position_c[0],
                                                                               alpha=2 * position_c[1])]
        extra_labels = [f"bin of mostly force-controlled objects (at {p:g} kPa, phi < 1/2)",
                        "bin of mostly position-controlled objects (phi >= 1/2)"]
    else:
        for a in (ax, ax_d, ax_s):
            a.axvspan(lo, SOFT_MAX, color=force_c[0], alpha=force_c[1], lw=0)
            a.axvspan(STIFF_MIN, hi, color=position_c[0], alpha=position_c[1], lw=0)
        ax.text(math.sqrt(lo * SOFT_MAX), 1.06, "soft (k~ < 1e-4, the paper's bin)", ha="center", fontsize=8.5,
                color="#1f5fbf")
        ax.text(math.sqrt(STIFF_MIN * hi), 1.06, "stiff (k~ >= 1e-3, the paper's bin)", ha="center", fontsize=8.5,
                color="#b06000")
        if feasible_stiffness is not None:  # the bound assumes delta > crush_fraction H
            k_feas = feasible_stiffness
            for a in (ax, ax_d, ax_s):
                a.axvline(k_feas, color="#555555", ls=(0, (1, 2)), lw=1.4)
            ax.text(k_feas / 1.12, 0.55, f"below k~ = {k_feas:.2g} no state\nholds the object and spares it:\n"
                    "F = k_obj delta >= F_grip would\nneed delta > the crush depth", fontsize=7.5, color="#444444",
                    va="center", ha="right")
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = sorted((r for r in rows if r["policy"] == name), key=lambda r: r["object_stiffness"])
        k = [r["object_stiffness"] for r in rs]
        st = _style(name)
        ax.plot(k, [r["success_rate"] for r in rs], label=rs[0]["label"], **st)
        ax_d.plot(k, [r["damage_rate"] for r in rs], **st)
        ax_s.plot(k, [r["slip_rate"] for r in rs], **st)
    ax.set_ylim(-0.04, 1.13)
    ax.set_ylabel("success rate\n(held to the end, intact)")
    for a, what in ((ax_d, "damaged"), (ax_s, "slipped\n(dropped)")):
        a.set_ylim(-0.07, 1.07)
        a.set_ylabel(what)
    ax_s.set_xlabel("object stiffness k~ = k_obj w / mu" + (" (bin centre; objects drawn by the env)" if drawn
                                                              else ""))
    handles, labels = ax.get_legend_handles_labels()
    ax.legend(handles + extra_handles, labels + extra_labels, loc="lower center",
              bbox_to_anchor=(0.5, 1.08 if drawn else 1.17), ncol=2, fontsize=8, frameon=False)
    if not drawn:  # one object size: k~ is a modulus
        oc = config.objects
        unit = float(stiffness_per_modulus(np.mean(oc.object_thickness_mm), np.mean(oc.object_curvature_per_m),
                                           config.scales))
        top = ax.secondary_xaxis("top", functions=(lambda k: k / unit, lambda m: m * unit))
        top.set_xlabel("object shear modulus mu_obj (kPa)", fontsize=8)
        top.tick_params(labelsize=8)
    if title is None:
        title = "\n".join(textwrap.wrap(f"{task_description(config)}; {damage_rule_text(config)}; "
                                         f"{slip_rule_text(config)}", 130))
    fig.suptitle(title, fontsize=8, y=0.995)
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def plot_schedules(traces, path: str | Path, config: EnvConfig) -> Path:
    """One panel per policy: the command applied at each step, one line per object stiffness, outcome marked."""
    plt = _matplotlib()
    names = list(dict.fromkeys(t["policy"] for t in traces))
    ncol = min(3, len(names))
    nrow = math.ceil(len(names) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(max(4.1 * ncol, 8.2), 3.1 * nrow + 0.6), squeeze=False)
    ks = sorted({t["object_stiffness"] for t in traces if "object_stiffness" in t} | {t["stiffness"] for t in traces})
    cmap = plt.get_cmap("viridis")
    colours = {k: cmap(0.9 * i / max(1, len(ks) - 1)) for i, k in enumerate(ks)}
    n_steps = config.episode_steps
    for ax, name in zip(axes.flat, names, strict=False):
        ts = [t for t in traces if t["policy"] == name]
        ax.axvspan(config.task.squeeze_steps + 0.5, n_steps, color="#dddddd", alpha=0.6, lw=0)
        # longest episode first and widest, so that the schedules, which often coincide, stay visible
        order = sorted(ts, key=lambda t: -len(t["commands"]))
        widths = np.linspace(5.0, 1.4, max(2, len(order)))
        for lw, t in zip(widths, order, strict=False):
            c = t["commands"]
            what = "" if t.get("object_class", "ranges") == "ranges" else t["object_class"].replace("_", " ") + ", "
            ax.plot(range(len(c)), c, color=colours[t["stiffness"]], lw=lw, alpha=0.85, solid_capstyle="butt",
                    label=f"{what}k~ = {t['stiffness']:.2g}")
            if t["success"]:
                m, mc = "o", "#2ca02c"
            elif t["damaged"]:
                m, mc = "X", "#d62728"
            else:
                m, mc = "v", "#ff7f0e"
            ax.plot(len(c) - 1, c[-1], m, color=mc, ms=8, mec="black", mew=0.6, zorder=5)
        ax.set_title(ts[0]["label"], fontsize=8.5)
        ax.set_xlim(0, n_steps + 2)
        ax.set_xlabel("step")
        if ts[0]["command"] == "jaw":
            ax.set_ylabel("jaw closure (mm)")
        else:
            ax.set_ylabel("pressure (kPa)")
            ax.set_ylim(-1, config.task.max_pressure_kpa * 1.05)
        ax.text(0.5 * (config.task.squeeze_steps + n_steps), ax.get_ylim()[1] * 0.03, "hold", ha="center", fontsize=7.5,
                color="#555555")
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles += [plt.Line2D([], [], ls="", marker=m, color=c, mec="black", mew=0.6, ms=7)
                for m, c in (("o", "#2ca02c"), ("X", "#d62728"), ("v", "#ff7f0e"))]
    labels += ["held to the end", "damaged", "slipped"]
    ncol_legend = min(len(labels), 4)
    fig.legend(handles, labels, loc="lower center", ncol=ncol_legend, fontsize=8, frameon=False)
    fig.suptitle("the schedules applied (squeeze, then hold: shaded); marker = outcome", fontsize=9)
    legend_rows = math.ceil(len(labels) / ncol_legend)
    fig.tight_layout(rect=(0, min(0.4, 0.06 * legend_rows * 3.7 / fig.get_figheight()), 1, 0.97))
    return save_figure(fig, path, dpi=120)
