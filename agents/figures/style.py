"""How ``agents`` draws: matplotlib on the Agg backend, imported when a figure is drawn (:func:`_matplotlib`, the one
way ``agents`` reaches matplotlib), and each policy's line style.
"""

from __future__ import annotations

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
