"""The figures of ``pneunet-grasp search``: the search's success against target (:func:`plot_search`, ``--plot``)
and the threshold study's small multiples (:func:`plot_sensitivity`, ``sensitivity.png``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.common.regimes import SOFT_MAX, STIFF_MIN
from agents.common.words import _pct, task_description
from agents.figures.style import _matplotlib, _style
from pneunet_env.files import deferred_interrupt, save_figure

if TYPE_CHECKING:
    from pneunet_env.config import EnvConfig


__all__ = ["plot_search", "plot_sensitivity"]


def plot_search(cands: Sequence[Any], best: Any, path: Path, config: EnvConfig, gripper: str) -> Path:
    """Success rate vs target, one line per duration; the best marked. ``cands`` and ``best``: the search's
    :class:`agents.search.ramp.Candidate` records (``target``, ``n_steps``, ``success_rate``)."""
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    plt = _matplotlib()
    full, unit = (default_jaw_travel_mm(config), "mm") if gripper == "rigid" else (config.task.max_pressure_kpa, "kPa")
    fig, ax = plt.subplots(figsize=(7, 3.8))
    durations = sorted({c.n_steps for c in cands})
    cmap = plt.get_cmap("viridis")
    for j, n in enumerate(durations):
        cs = sorted((c for c in cands if c.n_steps == n), key=lambda c: c.target)
        ax.plot([c.target * full for c in cs], [c.success_rate for c in cs], color=cmap(j / max(1, len(durations) - 1)),
                lw=1.3, label=f"{n} steps")
    ax.plot(best.target * full, best.success_rate, "*", color="red", ms=14, mec="black", label="best")
    ax.set_xlabel(f"ramp target ({unit})")
    ax.set_ylabel("success rate")
    ax.set_title(f"{'rigid jaw' if gripper == 'rigid' else 'pressure'} ramp search: best {best.target * full:.3g} "
                 f"{unit} over {best.n_steps} steps, success {best.success_rate:.1%}\non "
                 f"{task_description(config).split(' (')[0].split(':')[0]}, {config.task.damage_rule} damage rule",
                 fontsize=9)
    ax.legend(fontsize=7, ncol=2, title="ramp duration", title_fontsize=7)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    with deferred_interrupt():
        return save_figure(fig, path, dpi=120)


def plot_sensitivity(results, path: Path) -> Path:
    """Small multiples: success vs ``k~`` for best-ramp, oracle and rigid, one panel per setting."""

    plt = _matplotlib()
    n = len(results)
    ncol = 3
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.7 * nrow), sharex=True, sharey=True, squeeze=False)
    for ax, res in zip(axes.flat, results, strict=False):
        ks = [r["object_stiffness"] for r in res["rows"]]
        lo, hi = min(ks) / 1.3, max(ks) * 1.3
        ax.axvspan(lo, SOFT_MAX, color="#4c9be8", alpha=0.12, lw=0)
        ax.axvspan(STIFF_MIN, hi, color="#f0a030", alpha=0.14, lw=0)
        ax.axvline(res["feasible_stiffness"], color="#555555", ls=(0, (1, 2)), lw=1.2)
        for name in ("best-ramp", "oracle", "rigid"):
            rs = sorted((r for r in res["rows"] if r["policy"] == name), key=lambda r: r["object_stiffness"])
            st = _style(name)
            st.pop("ms", None)
            st["marker"] = ""
            ax.plot([r["object_stiffness"] for r in rs], [r["success_rate"] for r in rs], label=name, **st)
        ax.set_xscale("log")
        ax.set_xlim(lo, hi)
        ax.set_ylim(-0.05, 1.08)
        ax.grid(True, alpha=0.3)
        reg = res["regimes"]["best-ramp"]
        ax.set_title(f"{res['description']}\nbest-ramp {res['best_ramp']['target_kpa']:.3g} kPa: soft "
                     f"{_pct(reg['soft']['success_rate']).strip()}, stiff {_pct(reg['stiff']['success_rate']).strip()}",
                     fontsize=7.5)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("k~")
    for ax in axes[:, 0]:
        ax.set_ylabel("success rate")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], color="#555555", ls=(0, (1, 2))))
    labels.append("below this k~ no state both holds and spares the object")
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle("Sensitivity of the soft-object result to the thresholds of the paper's task (its 250 mm ring; a "
                 "study, not the env's defaults);\nthe paper's k~ bins shaded: soft (k~ < 1e-4) and stiff "
                 "(k~ >= 1e-3)", fontsize=9)
    fig.tight_layout(rect=(0, 0.04, 1, 0.95))
    with deferred_interrupt():
        return save_figure(fig, path, dpi=110)
