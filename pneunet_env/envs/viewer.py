"""The ``render_mode="human"`` window: frames shown with matplotlib, imported lazily (only when a window opens)."""

from __future__ import annotations

import numpy as np

__all__ = ["HumanViewer"]


class HumanViewer:
    """A matplotlib window showing frames (``render_mode="human"``); matplotlib is imported here only.

    With a non-interactive backend (headless, e.g. ``Agg``) the frame is drawn to the figure's canvas and
    nothing is shown; with an interactive one, the window is updated and the GUI given ``1/fps`` seconds.
    """

    def __init__(self, title: str = "PneuNetGrasp-v1", fps: float = 20.0) -> None:
        try:
            import matplotlib
            import matplotlib.pyplot as plt
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError(
                'render_mode="human" needs matplotlib: pip install "pneunet-env[plot]"'
            ) from exc
        self._plt = plt
        backend = matplotlib.get_backend().lower()
        non_interactive = {"agg", "pdf", "ps", "svg", "cairo", "template", "pgf"}
        self._interactive = backend not in non_interactive and not backend.startswith("module://matplotlib_inline")
        if self._interactive:
            plt.ion()
        self.fig, self.ax = plt.subplots()
        manager = getattr(self.fig.canvas, "manager", None)
        if manager is not None:
            manager.set_window_title(title)
        self.ax.set_axis_off()
        self.fig.subplots_adjust(0, 0, 1, 1)
        self.image = None
        self.pause = 1.0 / float(fps)

    def show(self, frame: np.ndarray) -> None:
        if self.image is None:
            self.image = self.ax.imshow(frame)
        else:
            self.image.set_data(frame)
        if self._interactive:
            self.fig.canvas.draw_idle()
            self._plt.pause(self.pause)
        else:
            self.fig.canvas.draw()

    def close(self) -> None:
        self._plt.close(self.fig)
