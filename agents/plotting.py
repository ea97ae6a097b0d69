"""The figures of ``agents``, one module: matplotlib is imported here, when a plot is drawn, never at import.

:func:`_matplotlib` (``pyplot`` on the Agg backend) is the one way ``agents`` reaches matplotlib (the design study
draws through it too). Every figure is saved atomically through :func:`pneunet_env.files.save_figure`.

==========================  =====================================================================================
``pneunet-grasp evaluate``  :func:`plot_success`, :func:`plot_schedules` (:func:`record_schedules` and
                            :func:`nearest_drawn` run the episodes ``schedules.png`` draws)
``pneunet-grasp train``     :func:`plot_training` (``training.png``)
``train --seeds``           :func:`plot_seeds` (``learning_curves.png``)
``pneunet-grasp search``    :func:`plot_search` (``--plot``), :func:`plot_sensitivity` (``sensitivity.png``)
``pneunet-grasp map``       :func:`plot_map` (``map.png``)
==========================  =====================================================================================

The modules that run those commands (:mod:`agents.evaluate`, :mod:`agents.train`, :mod:`agents.seeds`,
:mod:`agents.search`, :mod:`agents.maps`) re-export their figures' names, as they did when these lived there; the
figures read those modules' data helpers when they draw (imported then, so this module imports none of them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pneunet_env.files import deferred_interrupt, save_figure

if TYPE_CHECKING:
    from agents.search import Candidate
    from pneunet_env.config import EnvConfig

__all__ = ["nearest_drawn", "plot_schedules", "plot_success", "record_schedules", "plot_training", "plot_seeds",
           "plot_search", "plot_sensitivity", "plot_map"]

# Policies often score the same: the widest lines are drawn first (underneath), so that each stays visible.
_STYLES = {
    "rigid": dict(color="#d62728", lw=7.5, alpha=0.35, zorder=2),
    "best-ramp": dict(color="#1f5fbf", lw=2.4, marker="o", ms=3.5, zorder=5),
    "oracle": dict(color="black", lw=1.3, ls="--", zorder=6),
    "ramp": dict(color="#7f7f7f", lw=1.4, ls=":", marker=".", zorder=4),
    "step": dict(color="#a0a0a0", lw=1.4, ls="-.", marker=".", zorder=4),
}
_MODEL_STYLE = dict(color="#2ca02c", lw=4.5, alpha=0.75, zorder=3)


def _style(name: str) -> dict:
    """A policy's line style (a model's ``.zip``: one style for all models)."""
    base = name.split(":")[0]
    if name.endswith(".zip"):
        return dict(_MODEL_STYLE)
    return dict(_STYLES.get(base, dict(lw=1.5, marker=".")))


def _matplotlib():
    """``matplotlib.pyplot`` on the Agg backend (unless one is chosen already): the plots of ``agents`` import
    matplotlib through here only, when they draw."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_success(rows, path: str | Path, config: EnvConfig, title: str | None = None) -> Path:
    """Success (top) and damage / slip (bottom) vs ``k~`` for every policy, with the regimes: for objects drawn from
    the catalogue, each ``k~`` bin shaded by the regime most of its objects are in (read off the mechanics); on a
    pinned ``k~`` grid, the paper's soft and stiff bins shaded and, under the crush-fraction rule, the stiffness
    below which no state holds the object and spares it. The title names the task and its damage rule."""
    import textwrap

    from matplotlib.patches import Patch

    from agents.evaluate import SOFT_MAX, STIFF_MIN, _paper_bins, damage_rule_text, slip_rule_text, task_description
    from agents.oracle import feasible_stiffness
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
        if config.task.damage_rule == "crush_fraction":  # the bound assumes delta > crush_fraction H
            k_feas = feasible_stiffness(config)
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


def record_schedules(entries, config: EnvConfig, stiffnesses, seed: int = 0,
                     seeds=None) -> list[dict[str, Any]]:
    """One recorded episode per policy and stiffness: ``{policy, label, command, object_stiffness, ...outcome}``.

    ``seeds`` (one per stiffness): run those objects as the env draws them, nothing pinned (the catalogue's);
    else each ``k~`` is pinned."""
    from agents.evaluate import episode_seed, run_episode

    out = []
    for entry in entries:
        env = entry.make_env(config)
        for j, k in enumerate(stiffnesses):
            if seeds is None:
                r = run_episode(env, entry.policy, episode_seed(seed, 10_000 + j, 0), {"object_stiffness": float(k)},
                                record=True)
            else:
                r = run_episode(env, entry.policy, int(seeds[j]), record=True)
            r.update(policy=entry.name, label=entry.label, command=entry.command)
            out.append(r)
        env.close()
    return out


def nearest_drawn(config: EnvConfig, stiffnesses, seed: int = 0, draws: int = 4000) -> list[int]:
    """For each ``k~``, the seed of the object nearest it (in ``log k~``) among ``draws`` drawn by the env."""
    from agents.batch import draw_objects
    from agents.evaluate import GRID_SEED

    seeds = np.arange(GRID_SEED + seed * 1_000_003, GRID_SEED + seed * 1_000_003 + draws)
    k = np.log(np.asarray(draw_objects(config, seeds.tolist()).stiffness, dtype=float))
    return [int(seeds[np.argmin(np.abs(k - math.log(t)))]) for t in stiffnesses]


# ---------------------------------------------------------------------------------------------
# Training (pneunet-grasp train)
# ---------------------------------------------------------------------------------------------


def plot_training(run_dir: Path, path: Path | None = None, reference: float | None = None,
                  reference_label: str = "best-ramp") -> Path | None:
    """Evaluation success rate and mean return vs timesteps (``run_dir/evaluations.npz``) -> ``run_dir/training.png``.

    ``reference``: a success rate to draw as a horizontal line (e.g. best-ramp's on the same evaluation objects).
    Returns ``None`` when there is nothing to plot or matplotlib is missing.
    """
    evals = run_dir / "evaluations.npz"
    if not evals.is_file():
        return None
    try:
        plt = _matplotlib()
    except ImportError:
        return None
    data = np.load(evals)
    t = data["timesteps"]
    if not len(t):
        return None
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 4.6), sharex=True)
    if "successes" in data and len(data["successes"]):
        ax.plot(t, data["successes"].mean(axis=1), "o-", ms=3, color="#2ca02c", label="agent (deterministic)")
    if reference is not None:
        ax.axhline(reference, color="#1f5fbf", ls="--", lw=1.3, label=reference_label)
    trained = np.flatnonzero(t > 0) if (t > 0).any() else np.arange(len(t))  # the best model is a trained one
    best = int(trained[np.argmax(data["results"][trained].mean(axis=1))])
    ax.axvline(t[best], color="grey", ls=":", lw=1)
    ax.set_ylabel("success rate")
    vals = list(data["successes"].mean(axis=1)) if "successes" in data and len(data["successes"]) else []
    vals += [] if reference is None else [reference]
    if vals:
        ax.set_ylim(max(-0.02, min(vals) - 0.1), min(1.02, max(vals) + 0.1))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    ax2.plot(t, data["results"].mean(axis=1), "o-", ms=3, color="black")
    ax2.axvline(t[best], color="grey", ls=":", lw=1, label="best model (saved)")
    ax2.set_ylabel("mean return")
    ax2.set_xlabel("timesteps")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    n_eval = data["results"].shape[1]
    fig.suptitle(f"evaluation during training ({n_eval} episodes each, the same objects every time)", fontsize=9)
    fig.tight_layout()
    with deferred_interrupt():
        return save_figure(fig, run_dir / "training.png" if path is None else path, dpi=120)

# ---------------------------------------------------------------------------------------------
# The ramp search and the threshold sensitivity study (pneunet-grasp search)
# ---------------------------------------------------------------------------------------------


def plot_search(cands: Sequence[Candidate], best: Candidate, path: Path, config: EnvConfig, gripper: str) -> Path:
    """Success rate vs target, one line per duration; the best marked."""
    from agents.evaluate import task_description
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
    from agents.evaluate import SOFT_MAX, STIFF_MIN
    from agents.search import _pct

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

# ---------------------------------------------------------------------------------------------
# The seed study (pneunet-grasp train --seeds)
# ---------------------------------------------------------------------------------------------


def plot_seeds(result: dict[str, Any], path: Path) -> Path | None:
    """``learning_curves.png``: the evaluation success against timesteps (each seed thin, the mean bold, the range
    shaded, best-ramp dashed), and each seed's held-out success, untrained start against trained model."""
    try:
        plt = _matplotlib()
    except ImportError:
        return None
    curves = {s: c for s, c in result["curves"].items() if "success" in c}
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), gridspec_kw={"width_ratios": [1.7, 1]})
    common = sorted(set.intersection(*(set(c["timesteps"]) for c in curves.values()))) if curves else []
    if common:  # the mean and range where every seed was evaluated
        t = np.asarray(common, dtype=float)
        ys = np.array([[dict(zip(c["timesteps"], c["success"], strict=True))[x] for x in common]
                       for c in curves.values()])
        for c in curves.values():
            ax.plot(c["timesteps"], c["success"], lw=0.8, alpha=0.5, color="#2ca02c")
        ax.fill_between(t, ys.min(axis=0), ys.max(axis=0), color="#2ca02c", alpha=0.15, lw=0,
                        label=f"range over {len(curves)} seeds")
        ax.plot(t, ys.mean(axis=0), "o-", ms=3, lw=2, color="#1b7a1b", label="mean over seeds")
    refs = [r for r in result["eval_best_ramp"].values() if r is not None]
    if refs:
        ax.axhline(float(np.mean(refs)), color="#1f5fbf", ls="--", lw=1.3, label="best-ramp, same objects")
    ax.set_xlabel("timesteps (step 0: the untrained policy)")
    ax.set_ylabel("success rate (evaluation objects)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    scores = result["held_out"]
    seeds = list(scores["seeds"])
    x = np.arange(len(seeds))
    for key, marker, colour, dx in (("untrained", "o", "#999999", -0.12), ("trained", "s", "#1b7a1b", 0.12)):
        y = [scores["seeds"][s][key]["all"] if scores["seeds"][s].get(key) else np.nan for s in seeds]
        ax2.plot(x + dx, y, marker, color=colour, ms=7, ls="none", label=f"{key} (step 0)" if key == "untrained"
                 else "trained (best evaluation's model)")
    ax2.axhline(scores["best_ramp"]["all"], color="#1f5fbf", ls="--", lw=1.3, label="best-ramp")
    med = result.get("median_seed")
    ax2.set_xticks(x, [f"{s}*" if med is not None and int(s) == med else s for s in seeds])
    ax2.set_xlabel("seed (*: the median seed, exported)")
    ax2.set_ylabel(f"success, {scores['objects']} held-out objects")
    ax2.set_ylim(-0.02, 1.02)
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8, loc="lower right")
    fig.suptitle(f"{result['algo'].upper()} over {len(seeds)} seeds ({result['observation']}): learning curves and "
                 "held-out success against the untrained start", fontsize=9)
    fig.tight_layout()
    with deferred_interrupt():
        return save_figure(fig, path, dpi=120)

# ---------------------------------------------------------------------------------------------
# The success map (pneunet-grasp map)
# ---------------------------------------------------------------------------------------------



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
    from agents.maps import _arr

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

    from agents.maps import _arr, _pct, summarize

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
    from agents.maps import phi_definition

    text = result.get("regime_boundary") or phi_definition(result["regime_pressure_kpa"])
    head, _, sides = text.partition("; ")
    return f"{head};\n{sides}"


def _suptitle(result: dict[str, Any]) -> str:
    damage = result.get("damage") or f"{result['damage_rule']} rule"
    return (f"Grasp success over object modulus x radius: {result['thickness_rule']}, rho = "
            f"{result['density_kg_m3']:g} kg/m^3, failure strain eps_f = {result['failure_strain']:g}, "
            f"{result['episodes']} episode(s) per cell; blind policies tuned on {_use_case(result)}\n{damage}")


def _title(role: str, p: dict[str, Any], result: dict[str, Any]) -> str:
    from agents.maps import RIGID_ENV

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

    from agents.maps import _arr

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
