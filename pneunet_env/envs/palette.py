"""The frames' colours (RGB), the label's text colours and the contact sheet's legend of them (numpy only)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "BACKGROUND", "BASE", "ELASTOMER", "CAVITY_LOW", "CAVITY_HIGH", "OUTLINE", "OBJECT", "OBJECT_EDGE", "LOADED",
    "DAMAGED", "GREEN", "ORANGE", "GREY", "GAUGE_BG", "PRESSURE", "HOLD", "PROGRESS", "TEXT", "TEXT_GREEN",
    "TEXT_RED", "TEXT_ORANGE", "LEGEND",
]

# the picture's colours (RGB, float)
BACKGROUND = np.array([248, 248, 244], float)
BASE = np.array([96, 104, 118], float)  # PDMS base
ELASTOMER = np.array([196, 206, 222], float)
CAVITY_LOW = np.array([240, 244, 252], float)
CAVITY_HIGH = np.array([92, 150, 235], float)
OUTLINE = np.array([40, 44, 52], float)
OBJECT = np.array([232, 196, 140], float)
OBJECT_EDGE = np.array([150, 112, 60], float)
LOADED = np.array([235, 120, 30], float)
DAMAGED = np.array([200, 24, 24], float)
GREEN = np.array([40, 160, 70], float)
ORANGE = np.array([240, 150, 20], float)
GREY = np.array([150, 150, 150], float)
GAUGE_BG = np.array([225, 225, 225], float)
PRESSURE = np.array([60, 110, 220], float)
HOLD = np.array([200, 230, 205], float)
PROGRESS = np.array([90, 90, 90], float)

# text colours (uint8): dark on the light background, and the state's (darker than the gauges' green and orange,
# for contrast)
TEXT = np.array([32, 36, 44], np.uint8)
TEXT_GREEN = np.array([24, 128, 52], np.uint8)
TEXT_RED = np.array([196, 20, 20], np.uint8)
TEXT_ORANGE = np.array([204, 108, 0], np.uint8)

# The legend: (swatches, text) per entry, in the palette's colours (see :mod:`pneunet_env.envs.render`)
LEGEND = (
    ((BASE, ELASTOMER, CAVITY_HIGH), "finger: base, walls, chambers (bluer: more pressure)"),
    ((OBJECT, 0.15 * OBJECT + 0.85 * LOADED), "object, loaded zone (oranger: nearer damage)"),
    ((), "dashed: its undeformed surface"),
    ((PRESSURE,), "left bar: pressure"),
    ((), "right bar: contact traction, log 0.5 Pa to 50 kPa; ticks: grip (green), failure and crush (red)"),
    ((GREEN,), "green: held, or gripping (traction above grip)"),
    ((ORANGE,), "orange: slipped, or traction below grip"),
    ((DAMAGED,), "red: damaged or crushed"),
    ((GREY,), "lamp grey: squeeze phase"),
    ((PROGRESS, HOLD), "bottom bar: step, hold phase shaded"),
    ((), "label: object (or k~), step, pressure, state"),
)
"""The contact sheet's legend: each entry's colour swatches (RGB) and its words."""
