"""The figures of ``pneunet-grasp train``: ``training.png`` (:func:`plot_training`) and, with ``--seeds``,
``learning_curves.png`` (:func:`plot_seeds`), from a run's files and a seed study's result.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agents.figures.style import _matplotlib
from pneunet_env.files import deferred_interrupt, save_figure

__all__ = ["plot_training", "plot_seeds"]


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
