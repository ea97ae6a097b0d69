"""Pictures of the grasp, drawn with numpy only (no matplotlib, no Pillow on the ``rgb_array`` path).

:func:`render_frame` draws one :class:`RenderState` (:func:`render_state` of an env's state) into an ``HxWx3``
uint8 array. The work is split by concern:

* :mod:`pneunet_env.envs.scene`: what is drawn, as geometry (lengths in units of the chamber width ``w``, like the
  model): the finger and the object of one state;
* :mod:`pneunet_env.envs.raster`: the numpy rasteriser (spans along subpixel rows, a label image, supersampling
  averaged at the edges only), with the colours of :mod:`pneunet_env.envs.palette`;
* :mod:`pneunet_env.envs.font`: the 5 x 8 bitmap font of the label and the legend;
* :mod:`pneunet_env.envs.png`: the PNG codec (zlib only);
* :mod:`pneunet_env.envs.viewer`: the ``render_mode="human"`` window (matplotlib, imported lazily).

This module is the public face of them all (every name below stays importable from here).

What is drawn:

* the **actuator**, ``chambers`` unit cells along an arc of the model's curvature ``kappa`` (pixels are
  mapped to arc length ``s`` and normal offset ``n`` about the centre of curvature, so each part is a
  rectangle in ``(s, n)``): the stiff PDMS base (dark), the elastomer side walls (radial) and top walls
  (thinned as they stretch, ``h (1+e)^-2``), and the cavities, shaded by pressure;
* the **object**, a layer of thickness ``H`` on an arc of curvature ``kappa_obj``, concentric with the
  actuator once in contact and indented by ``delta = 1/kappa_obj - 1/kappa`` (drawn up to ``H``; once
  crushed, the task's flag by the damage rule in force, a red film on the base); the loaded zone is tinted
  by the damage ratio (the larger of traction over failure traction and indentation over the crush
  depth), solid red once damaged, and the undeformed surface is dashed;
* the **gauges**: a pressure bar (left), a traction gauge on a log scale from 0.5 Pa to 50 kPa
  (right; ticks: grip traction in green, failure traction and crush traction in red; the bar is green
  above the grip traction, orange below it, red once damaged), the episode's progress (bottom; the hold
  phase shaded) and a status lamp (top right: grey squeezing, green held, orange dropped, red damaged);
* the **label** (top left, on frames of at least ``LABEL_MIN_WIDTH x LABEL_MIN_HEIGHT``, 240 x 180): the object
  (its catalogue class, else ``k~=1.0e-4``), the step, the pressure in kPa and the state (:func:`frame_status`:
  free, squeezing, gripping or held in green, slipped in orange, crushed or damaged in red), in a built-in 5 x 8
  bitmap font (printable ASCII, a numpy constant) at an integer scale (:func:`label_scale`: 1 at 320 x 240, 2 at
  480 x 360), each glyph ringed by the background's colour so that it reads over the scene; drawn on the final
  pixels, after the supersampled picture.

:func:`save_png` writes a PNG with ``zlib`` only (atomically); :func:`contact_sheet` tiles frames over a legend of
the colours (:func:`legend_strip`, in the same font). :class:`HumanViewer` shows frames in a matplotlib window
(imported lazily, only for ``render_mode="human"``).
"""

from __future__ import annotations

import math

import numpy as np

from pneunet_env.envs import palette as C
from pneunet_env.envs.font import FONT_HEIGHT, FONT_WIDTH, draw_text, text_mask
from pneunet_env.envs.palette import LEGEND
from pneunet_env.envs.png import read_png, save_png
from pneunet_env.envs.raster import layout, rasterise, to_uint8
from pneunet_env.envs.scene import RenderState, render_state
from pneunet_env.envs.viewer import HumanViewer

__all__ = [
    "RenderState", "render_state", "render_frame", "save_png", "read_png", "contact_sheet", "legend_strip", "LEGEND",
    "text_mask", "label_lines", "frame_status", "label_fits", "check_label_size", "label_scale", "LABEL_MIN_WIDTH",
    "LABEL_MIN_HEIGHT", "FONT_WIDTH", "FONT_HEIGHT", "HumanViewer",
]


def render_frame(
    state: RenderState, width: int = 480, height: int = 360, chambers: int = 6, supersample: int = 2,
    label: bool | None = None,
) -> np.ndarray:
    """Draw one state; returns a ``(height, width, 3)`` uint8 array. See the module docstring.

    ``label``: the text label in the top left corner (:func:`label_lines`); ``None`` (default) draws it where the
    frame is at least ``LABEL_MIN_WIDTH x LABEL_MIN_HEIGHT`` (240 x 180) pixels, ``True`` requires it (a smaller
    frame raises ``ValueError``), ``False`` leaves it out.
    """
    width, height, chambers, supersample = int(width), int(height), int(chambers), int(supersample)
    if width < 32 or height < 32:
        raise ValueError(f"frame must be at least 32 x 32 pixels, got {width} x {height}")
    if label:
        check_label_size(width, height)
    if chambers < 1:
        raise ValueError(f"chambers must be >= 1, got {chambers}")
    if supersample < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    img = rasterise(state, width, height, chambers, supersample)
    if label or (label is None and label_fits(width, height)):
        lay = layout(width, height, chambers, supersample)
        draw_text(img, label_lines(state), lay.label_x, lay.label_y, label_scale(width, height),
                  halo=to_uint8(C.BACKGROUND))
    return img


# ---------------------------------------------------------------------------------------------
# The frame's label
# ---------------------------------------------------------------------------------------------

LABEL_MIN_WIDTH, LABEL_MIN_HEIGHT = 240, 180
"""The smallest frame that carries the label (:func:`render_frame`'s ``label``); below it the label would cover the
actuator."""


def label_scale(width: int, height: int) -> int:
    """The label's integer font scale for a frame: 1 a 240 pixels of its width (or of 4/3 its height, if less),
    at least 1: 1 at 320 x 240, 2 at 480 x 360 and 640 x 480, 3 at 720 x 540."""
    return max(1, min(int(width), 4 * int(height) // 3) // 240)


def label_fits(width: int, height: int) -> bool:
    """Whether a ``width x height`` frame carries the label (at least ``LABEL_MIN_WIDTH x LABEL_MIN_HEIGHT``)."""
    return int(width) >= LABEL_MIN_WIDTH and int(height) >= LABEL_MIN_HEIGHT


def check_label_size(width: int, height: int) -> None:
    """``ValueError`` naming the size unless a ``width x height`` frame carries the label."""
    if int(width) < LABEL_MIN_WIDTH:
        raise ValueError(f"a frame {width} px wide is too narrow for its label: at least {LABEL_MIN_WIDTH} px")
    if int(height) < LABEL_MIN_HEIGHT:
        raise ValueError(f"a frame {height} px high is too low for its label: at least {LABEL_MIN_HEIGHT} px")


def frame_status(state: RenderState) -> str:
    """The state the label names, by the task's rules (first that applies).

    ``"crushed"`` (damaged, and the indentation is past the crush depth now) or ``"damaged"`` (red); ``"slipped"``
    (dropped in the hold phase; orange); ``"held"`` (a hold-phase step, intact; green); before the hold phase
    ``"gripping"`` (in contact with the traction at or above the grip traction: it would hold if lifted now; green),
    ``"squeezing"`` (in contact, below it) or ``"free"`` (out of contact).
    """
    if state.damaged:
        return "crushed" if state.crushed else "damaged"
    if state.dropped:
        return "slipped"
    if state.in_hold:
        return "held"
    if not state.in_contact:
        return "free"
    return "gripping" if float(state.contact_force) >= float(state.grip_traction) else "squeezing"


_STATUS_COLOURS = {"crushed": C.TEXT_RED, "damaged": C.TEXT_RED, "slipped": C.TEXT_ORANGE, "held": C.TEXT_GREEN,
                   "gripping": C.TEXT_GREEN}


def _short_e(x: float) -> str:
    """``1.0e-4`` for 1e-4, ``1.3e0`` for 1.3: two digits, the exponent without padding."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def label_lines(state: RenderState) -> list[tuple[str, np.ndarray]]:
    """The label's lines and their colours: the object (its class, else its stiffness, ``k~=1.0e-4``), the step,
    the pressure in kPa and the state (:func:`frame_status`, in its colour)."""
    name = state.object_name
    if not name:
        k = float(state.object_stiffness)
        name = "k~=" + _short_e(k) if math.isfinite(k) else "object"
    status = frame_status(state)
    return [(name, C.TEXT), (f"step {int(state.step)}", C.TEXT), (f"{float(state.pressure_kpa):.1f} kPa", C.TEXT),
            (status, _STATUS_COLOURS.get(status, C.TEXT))]

# ---------------------------------------------------------------------------------------------
# Contact sheets and their legend
# ---------------------------------------------------------------------------------------------

def contact_sheet(
    frames, columns: int, gutter: int = 4, background: int = 255, legend: bool = True, legend_scale: int | None = None
) -> np.ndarray:
    """Tile equal-sized ``HxWx3`` frames, row by row, ``columns`` per row, over a legend of the frames' colours.

    ``legend``: a strip under the frames (:func:`legend_strip`, as wide as the sheet) saying what the colours
    and the label mean; ``legend_scale``: its font scale (default: 1 a 900 px of the sheet's width, at least 1).
    """
    frames = [np.asarray(f) for f in frames]
    if not frames:
        raise ValueError("contact_sheet needs at least one frame")
    h, w, _ = frames[0].shape
    if any(f.shape != frames[0].shape for f in frames):
        raise ValueError("contact_sheet needs frames of one shape")
    columns = max(1, min(int(columns), len(frames)))
    rows = -(-len(frames) // columns)
    sheet = np.full((rows * h + (rows + 1) * gutter, columns * w + (columns + 1) * gutter, 3), background, np.uint8)
    for i, f in enumerate(frames):
        r, c = divmod(i, columns)
        y, x = gutter + r * (h + gutter), gutter + c * (w + gutter)
        sheet[y : y + h, x : x + w] = f
    if legend:
        sheet = np.concatenate([sheet, legend_strip(sheet.shape[1], legend_scale, background, margin=gutter)])
    return sheet

def legend_strip(width: int, scale: int | None = None, background: int = 255, margin: int = 4) -> np.ndarray:
    """The legend (:data:`LEGEND`) as an ``HxWx3`` uint8 strip ``width`` pixels wide: its entries one after the
    other, wrapped to the width (an entry wider than the strip is cut at its edge); ``scale``: the font's (default:
    1 a 900 px of width, at least 1)."""
    width, margin = int(width), int(margin)
    s = max(1, width // 900) if scale is None else int(scale)
    if s < 1:
        raise ValueError(f"legend scale must be >= 1, got {s}")
    box, step, gap = (FONT_HEIGHT - 1) * s, (FONT_WIDTH + 1) * s, 3 * (FONT_WIDTH + 1) * s
    pitch = (FONT_HEIGHT + 4) * s
    placed, x, row = [], 0, 0  # (row, x, swatches, text) each
    for swatches, text in LEGEND:
        w = len(swatches) * (box + s) + (step if swatches else 0) + text_mask(text, s).shape[1]
        if x > 0 and x + w > width - 2 * margin:
            x, row = 0, row + 1
        placed.append((row, x, swatches, text))
        x += w + gap
    strip = np.full((2 * margin + (row + 1) * pitch, width, 3), background, np.uint8)
    for r, x0, swatches, text in placed:
        y, x = margin + r * pitch + s, margin + x0
        for colour in swatches:
            a, b, c, d = y, y + box, x, min(x + box, width)
            if c < d:
                strip[a:b, c:d] = C.OUTLINE
                strip[a + 1 : b - 1, c + 1 : d - 1] = to_uint8(colour)
            x += box + s
        if swatches:
            x += step
        draw_text(strip, [(text, C.TEXT)], x, y, s)
    return strip
