"""The design study's figures (agents/design/outputs.py): their text fits, and Table 1 stays in sight.

Drawn from a recorded study (``docs/img/design/kitchen/design.json``, the kitchen study of docs/results.md) with
matplotlib's Agg backend; no study is run.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from agents.design import outputs  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
KITCHEN = ROOT / "docs" / "img" / "design" / "kitchen" / "design.json"
WEIGHTS = {"apple": 1.0, "kiwifruit": 2.0, "soft_cheese": 1.0, "gelatin_gel": 0.5, "tomato": 1.0}


def _result(class_weights=None) -> dict:
    result = json.loads(KITCHEN.read_text())
    if class_weights is not None:  # titles name every class and its weight: the longest a title gets
        result["settings"]["class_weights"] = dict(class_weights)
    return result


def _base(result: dict):
    from pneunet_env import load_config

    st = result["settings"]
    return load_config(None, **({"use_case": st["use_case"]} if st["class_weights"] is None
                                else {"class_weights": st["class_weights"]}))


def _with_table1_as_best(result: dict) -> dict:
    """A small study's report: its best design is Table 1's own trial (``rank-1``, the same parameters)."""
    out = copy.deepcopy(result)
    table1 = next(row for row in out["designs"] if row["label"] == "table1")
    out["designs"] = [table1, {**copy.deepcopy(table1), "label": "rank-1"}]
    return out


def _outside(fig) -> list[str]:
    """What runs off the figure (drawn with Agg): each axes with all it draws (title, axis labels, tick labels,
    legend: its tight bounding box), the x label and the title on their own, and the suptitle; with their extents
    in pixels."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    parts = [("suptitle", fig._suptitle.get_window_extent(renderer))] if fig._suptitle is not None else []
    for i, ax in enumerate(fig.axes):
        parts.append((f"axes {i}", ax.get_tightbbox(renderer)))
        for name, t in (("x label", ax.xaxis.label), ("title", ax.title)):
            if t.get_visible() and t.get_text():
                parts.append((f"axes {i} {name} {t.get_text()!r}", t.get_window_extent(renderer)))
    return [f"{name}: x {e.x0:.0f}..{e.x1:.0f}, y {e.y0:.0f}..{e.y1:.0f} in {box.width:.0f} x {box.height:.0f}"
            for name, e in parts
            if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 or e.y1 > box.y1 + 0.5]


@pytest.mark.parametrize("weights", [None, WEIGHTS], ids=["use_case", "class_weights"])
def test_the_importance_and_pareto_figures_text_fits(weights):
    """The importance chart's x label (cut off at the right before) and the titles, however many classes they name,
    lie within the figure."""
    plt = outputs._plt()
    result = _result(weights)
    for make in (outputs.importance_figure, outputs.pareto_figure):
        fig = make(result, plt)
        try:
            assert _outside(fig) == [], make.__name__
        finally:
            plt.close(fig)


def _red_pixels(png: Path, panel: int) -> int:
    """Pixels of Table 1's red in one panel (a third of the width) of a curves figure."""
    import matplotlib.colors as mcolors
    import matplotlib.image as mimage

    img = mimage.imread(png)[..., :3]
    w = img.shape[1] // 3
    red = np.array(mcolors.to_rgb(outputs.TABLE1_COLOUR))
    return int(np.sum(np.abs(img[:, panel * w:(panel + 1) * w] - red).max(axis=-1) < 0.12))


@pytest.mark.slow
def test_a_design_identical_to_table1_does_not_hide_its_line(tmp_path):
    """A small study's best design can be Table 1 itself: drawn after it in its own colour, it hid Table 1's red
    line. Table 1's red shows as much as it does alone (within the dashes' share), and the design says it is
    Table 1; the curves figure's text fits too."""
    plt = outputs._plt()
    result = _result()
    base = _base(result)
    both = _with_table1_as_best(result)
    alone = {**both, "designs": both["designs"][:1]}
    outputs.plot_curves(both, base, tmp_path / "both.png", plt)
    outputs.plot_curves(alone, base, tmp_path / "alone.png", plt)
    for panel in range(3):
        shown, full = _red_pixels(tmp_path / "both.png", panel), _red_pixels(tmp_path / "alone.png", panel)
        assert full > 300 and shown > 0.4 * full, (panel, shown, full)
    fig = outputs.curves_figure(both, base, plt)
    try:
        labels = [line.get_label() for line in fig.axes[0].get_lines()]
        assert labels == ["Table 1 (table1)", "rank-1 (table1) = Table 1"]
        assert _outside(fig) == []
    finally:
        plt.close(fig)


def test_only_a_design_with_table1s_parameters_is_called_table1():
    result = _result()
    table1 = next(row for row in result["designs"] if row["label"] == "table1")
    assert [outputs._is_table1(row, table1) for row in result["designs"]] == [False] * len(result["designs"])
    same = _with_table1_as_best(result)
    assert [outputs._is_table1(row, same["designs"][0]) for row in same["designs"]] == [False, True]
    assert not outputs._is_table1(table1, None)
