"""Pictures of the grasp, drawn with numpy only (no matplotlib on the ``rgb_array`` path).

:func:`render_frame` rasterises one state into an ``HxWx3`` uint8 array, supersampled (``2 x 2`` subpixels a
pixel by default) and averaged down for smooth edges. It draws in three passes, each vectorised over rows:

1. **spans**: every part's boundaries are circles (about the actuator's centre of curvature, or the object's
   centre) or radial lines, so along each subpixel row a part covers one span of columns, found in closed form
   (``|x|`` where the boundary crosses the row); a subpixel centre lying on a boundary, to rounding, is decided
   by the part's own definition (its arc length ``s``, normal offset ``n`` or distance to the object's surface);
2. **labels**: the spans are painted into a label image (one byte a subpixel, the topmost part's label), on
   each part's bounding box only; the picture is symmetric in ``x`` but for the dashes and the gauges, so the
   right half is painted and mirrored; the outlines are the subpixels within ``supersample`` (4-neighbour
   steps) of a part's edge, for all outlined parts at once (one bit plane each);
3. **colours**: a pixel whose subpixels share one label takes that label's colour from a table (two pixels a
   look-up), the others (the edges) average their subpixels' colours as the supersampling does, only in the
   rows of the scene and the gauges' boxes (the rest is the background, copied).

What is drawn:

* the **actuator**, ``chambers`` unit cells along an arc of the model's curvature ``kappa`` (pixels are
  mapped to arc length ``s`` and normal offset ``n`` about the centre of curvature, so each part is a
  rectangle in ``(s, n)``): the stiff PDMS base (dark), the elastomer side walls (radial) and top walls
  (thinned as they stretch, ``h (1+e)^-2``), and the cavities, shaded by pressure;
* the **object**, a layer of thickness ``H`` on an arc of curvature ``kappa_obj``, concentric with the
  actuator once in contact and indented by ``delta = 1/kappa_obj - 1/kappa`` (drawn up to ``H``: beyond
  it the object is crushed through, and only a red film is left on the base); the loaded zone is tinted
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

Lengths are in units of the chamber width ``w``, like the model. :func:`save_png` writes a PNG with
``zlib`` only; :func:`contact_sheet` tiles frames over a legend of the colours (:func:`legend_strip`, in the
same font). :class:`HumanViewer` shows frames in a matplotlib window (imported lazily, only for
``render_mode="human"``).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from pneunet_env.envs.font import FONT_HEIGHT, FONT_WIDTH, draw_text, text_mask
from pneunet_env.envs.png import read_png, save_png
from pneunet_env.physics.params import ActuatorParams

__all__ = [
    "RenderState", "render_state", "render_frame", "save_png", "read_png", "contact_sheet", "legend_strip", "LEGEND",
    "text_mask", "label_lines", "frame_status", "label_fits", "check_label_size", "label_scale", "LABEL_MIN_WIDTH",
    "LABEL_MIN_HEIGHT", "FONT_WIDTH", "FONT_HEIGHT", "HumanViewer",
]

# colours (RGB)
_BACKGROUND = np.array([248, 248, 244], float)
_BASE = np.array([96, 104, 118], float)  # PDMS base
_ELASTOMER = np.array([196, 206, 222], float)
_CAVITY_LOW = np.array([240, 244, 252], float)
_CAVITY_HIGH = np.array([92, 150, 235], float)
_OUTLINE = np.array([40, 44, 52], float)
_OBJECT = np.array([232, 196, 140], float)
_OBJECT_EDGE = np.array([150, 112, 60], float)
_LOADED = np.array([235, 120, 30], float)
_DAMAGED = np.array([200, 24, 24], float)
_GREEN = np.array([40, 160, 70], float)
_ORANGE = np.array([240, 150, 20], float)
_GREY = np.array([150, 150, 150], float)
_GAUGE_BG = np.array([225, 225, 225], float)
_PRESSURE = np.array([60, 110, 220], float)
_HOLD = np.array([200, 230, 205], float)
_PROGRESS = np.array([90, 90, 90], float)

_TRACTION_LOG_RANGE = (-5.0, 0.0)  # log10(F~): 0.5 Pa to 50 kPa at mu = 50 kPa


class RenderState(NamedTuple):
    """What one frame shows (dimensionless: lengths / ``w``, tractions / ``mu``)."""

    curvature: float  # kappa~ of the base
    side_strain: float  # e_s
    params: ActuatorParams
    pressure_fraction: float  # p / p_max
    object_curvature: float  # w kappa_obj
    object_thickness: float  # H / w
    contact_force: float  # F~
    indentation: float  # delta~ (0 out of contact)
    in_contact: bool
    failure_traction: float  # F~ at failure
    crush_indentation: float  # delta~ at which it is crushed through
    grip_traction: float  # F~ needed to hold it
    damaged: bool
    dropped: bool
    in_hold: bool
    progress: float  # step / episode length
    hold_start: float  # squeeze_steps / episode length
    # what the label says (see :func:`label_lines`); the defaults draw a label of an unnamed object at step 0
    step: int = 0
    pressure_kpa: float = 0.0
    object_name: str = ""  # a catalogue class; "" names the object by its stiffness
    object_stiffness: float = math.nan  # k~


def render_state(
    state, params, i: int | None = None, class_names: tuple[str, ...] = (), object_name: str | None = None
) -> RenderState:
    """What a frame shows of an env's :class:`pneunet_env.task.EnvState` (of its entry ``i`` for a batch).

    The label names the object by ``object_name`` if given, else by its catalogue class (``class_names``, by the
    object's class code), else (``""``: no class, e.g. the paper's task) by its stiffness ``k~``.
    """

    def at(v):
        return v if i is None else v[i]

    eq, obj, thr, st, tp = state.eq, state.obj, state.thresholds, state.task, params.task
    step = int(at(st.step))
    in_contact = bool(at(eq.in_contact))
    if object_name is None:
        cid = int(at(obj.class_id))
        object_name = class_names[cid] if 0 <= cid < len(class_names) else ""
    return RenderState(
        curvature=float(at(eq.curvature)),
        side_strain=float(at(eq.side_strain)),
        params=params.actuator_params,
        pressure_fraction=float(at(state.command)) / tp.pressure_max,
        object_curvature=float(at(obj.curvature)),
        object_thickness=float(at(obj.thickness)),
        contact_force=float(at(eq.contact_force)),
        indentation=float(at(eq.indentation)) if in_contact else 0.0,
        in_contact=in_contact,
        failure_traction=float(at(thr.failure_traction)),
        crush_indentation=float(at(thr.crush_indentation)),
        grip_traction=float(at(thr.grip_traction)),
        damaged=bool(at(st.damaged)),
        dropped=bool(at(st.dropped)),
        in_hold=step > tp.squeeze_steps,
        progress=step / tp.episode_steps,
        hold_start=tp.squeeze_steps / tp.episode_steps,
        step=step,
        pressure_kpa=float(at(eq.pressure)) * tp.shear_modulus_kpa,
        object_name=str(object_name),
        object_stiffness=float(at(obj.stiffness)),
    )


def _safe_ratio(a, b) -> float:
    a, b = float(a), float(b)
    return a / b if b > 0.0 else 0.0


# ---------------------------------------------------------------------------------------------
# The rasteriser: spans per subpixel row, a label image, supersampling averaged at the edges only
# ---------------------------------------------------------------------------------------------

# Labels of the (supersampled) label image: the scene's layers in paint order (each pixel keeps the
# topmost layer that covers it), then the gauges' colours (stamped over the scene, in their own order).
(
    _L_BACKGROUND, _L_OBJECT, _L_ZONE, _L_OBJECT_EDGE, _L_FILM, _L_DASH, _L_ELASTOMER, _L_CAVITY, _L_CAVITY_EDGE,
    _L_BASE, _L_OUTLINE, _L_GAUGE_BG, _L_PRESSURE, _L_TRACTION, _L_GREEN, _L_DAMAGED, _L_HOLD, _L_PROGRESS, _L_LAMP,
) = range(19)
_N_LABELS = 19

_PALETTE = np.zeros((_N_LABELS, 3), np.float32)  # the labels' colours that do not depend on the state
for _label, _colour in (
    (_L_BACKGROUND, _BACKGROUND), (_L_OBJECT, _OBJECT), (_L_FILM, _DAMAGED), (_L_ELASTOMER, _ELASTOMER),
    (_L_BASE, _BASE), (_L_OUTLINE, _OUTLINE), (_L_GAUGE_BG, _GAUGE_BG), (_L_PRESSURE, _PRESSURE),
    (_L_GREEN, _GREEN), (_L_DAMAGED, _DAMAGED), (_L_HOLD, _HOLD), (_L_PROGRESS, _PROGRESS), (_L_LAMP, _GREY),
):
    _PALETTE[_label] = _colour
# the loaded zone when damaged (else it is tinted per pixel): painted at 0.85 over the object
_PALETTE[_L_ZONE] = (1.0 - 0.85) * _PALETTE[_L_OBJECT] + 0.85 * _DAMAGED


class _Layout:
    """What depends only on the frame's size: the subpixel grid, the dash pattern, the gauges' places."""

    def __init__(self, width: int, height: int, chambers: int, ss: int) -> None:
        self.width, self.height, self.ss = width, height, ss
        self.ws, self.hs = width * ss, height * ss  # the supersampled grid
        self.px = self.ws / max(2.0 * chambers, 12.0)  # subpixels per unit; the origin is at (0.5 w, 0.4 h)
        self.y = (0.4 * self.hs - (np.arange(self.hs) + 0.5)) / self.px  # subpixel rows' centres (y up)
        x = (np.arange(self.ws) + 0.5 - 0.5 * self.ws) / self.px
        self.dash = np.floor(x * 4.0) % 2 == 0  # the dashed line's pattern, per column
        # The picture is symmetric in x (but for the dashes and the gauges): columns are indexed by |x|, as
        # "half-columns" q with |x| px = q + off. With an even grid width the right half (x > 0) is drawn and
        # mirrored; with an odd one, every column (q of each).
        self.even = self.ws % 2 == 0
        self.off = 0.5 if self.even else 0.0
        self.jc = self.ws // 2  # the first column with x >= 0
        self.nh = self.ws - self.jc  # half-columns
        self.itype = np.int16 if self.ws < 32000 else np.int32
        self.utype = np.uint16 if self.itype == np.int16 else np.uint32
        self.q_full = (np.abs(np.arange(self.ws) + 0.5 - 0.5 * self.ws) - self.off).astype(self.itype)[None, :]
        self.q = np.arange(self.nh, dtype=self.itype)[None, :] if self.even else self.q_full
        # a pixel's subpixels, as offsets in the flat label image (in the supersampling's order)
        self.block = np.array([di * self.ws + dj for di in range(ss) for dj in range(ss)])
        self.blank = np.empty((height, width, 3), np.uint8)
        self.blank[...] = _uniform_colours(_BACKGROUND.astype(np.float32)[None, :], ss)[0]

        # gauges (final-image pixels)
        m, bw = self.m, self.bw = max(6, width // 60), max(8, width // 40)  # margin, bar width
        self.top, self.bottom = int(0.12 * height), int(0.80 * height)
        self.pb_top, self.pb_bot = height - m - max(6, height // 40), height - m
        x1 = width - m - bw
        self.bars = (
            self.bar(m, self.top, m + bw, self.bottom),  # pressure
            self.bar(x1, self.top, x1 + bw, self.bottom),  # traction
            self.bar(m, self.pb_top, width - m, self.pb_bot),  # progress
        )
        r = max(5, width // 48)  # the status lamp
        cx, cy = width - m - r, m + r
        a, b = max(self._px(cy - r) - 1, 0), min(self._px(cy + r) + 1, self.hs)
        c, d = max(self._px(cx - r) - 1, 0), min(self._px(cx + r) + 1, self.ws)
        dist = np.hypot(np.arange(c, d)[None, :] + 0.5 - cx * ss, np.arange(a, b)[:, None] + 0.5 - cy * ss)
        self.lamp = (slice(a, b), slice(c, d))
        self.lamp_disc = dist <= r * ss
        self.lamp_edge = self.lamp_disc & (dist > (r - 1.0) * ss)
        # the boxes (final pixels, with a margin) where the gauges are drawn
        boxes = [
            (self.top - 1, self.bottom + 1, m - 1, m + bw + 1),
            (self.top - 2, self.bottom + 2, x1 - bw // 2 - 1, x1 + bw + bw // 2 + 1),  # with the ticks
            (self.pb_top - 1, self.pb_bot + 1, 0, width),  # the hold phase's shade starts anywhere
            (a // ss - 1, -(-b // ss) + 1, c // ss - 1, -(-d // ss) + 1),
        ]
        self.gauge_boxes = [(max(a, 0), min(b, height), max(c, 0), min(d, width)) for a, b, c, d in boxes]
        self.label_x, self.label_y = m + bw + m, m  # the label's top left corner: right of the pressure bar

    def _px(self, v) -> int:
        return int(round(float(v) * self.ss))

    def rect(self, x0, y0, x1, y1):
        """The subpixels ``(row0, row1, col0, col1)`` of the rectangle ``[x0, x1) x [y0, y1)`` (final pixels)."""
        a, b = max(self._px(y0), 0), min(self._px(y1), self.hs)
        c, d = max(self._px(x0), 0), min(self._px(x1), self.ws)
        return (a, max(a, b), c, max(c, d))

    def bar(self, x0, y0, x1, y1):
        """A gauge's box: its background, its x range and its outline (one final pixel wide)."""
        outline = [self.rect(x0, y0, x1, y0 + 1.0), self.rect(x0, y1 - 1.0, x1, y1), self.rect(x0, y0, x0 + 1.0, y1),
                   self.rect(x1 - 1.0, y0, x1, y1)]
        return self.rect(x0, y0, x1, y1), x0, x1, outline


@functools.lru_cache(maxsize=8)
def _layout(width: int, height: int, chambers: int, ss: int) -> _Layout:
    return _Layout(width, height, chambers, ss)


class _Scene:
    """One frame's shapes: where each boundary crosses each subpixel row, and the exact tests at a point.

    Lengths in units of ``w``; ``x`` is ``|x|`` (the shapes are symmetric), rows are the supersampled grid's.
    """

    def __init__(self, lay: _Layout, state: RenderState, chambers: int) -> None:
        prm = state.params
        d, hb, hs, hm = prm.chamber_height, prm.base_thickness, prm.side_thickness, prm.top_thickness
        self.lay = lay
        self.k = k = max(float(state.curvature), 0.0)
        self.flat = k <= 1e-12
        es = float(state.side_strain)
        self.L = float(chambers)
        # the object: a layer of thickness H below its undeformed surface (radius R_u about (0, oy)), concentric
        # with the actuator once in contact and indented by delta (drawn up to H)
        self.R_u = 1.0 / float(state.object_curvature) - 0.5 * hb  # its undeformed surface (base's lower face)
        self.H = H = float(state.object_thickness)
        self.delta = delta = max(float(state.indentation), 0.0) if state.in_contact else 0.0
        self.crushed_through = delta > H
        self.delta_draw = min(delta, H)
        self.oy = -0.5 * hb + self.delta_draw - self.R_u
        self.yo = lay.y - self.oy
        # the actuator: offsets n of its parts (the top wall thinned as it stretches, the side walls too)
        em = d * (1.0 + es) * k
        tm = hm * (1.0 + em) ** -2
        self.ts = hs * (1.0 + es) ** -2
        n_top = d * (1.0 + es)  # the top wall's centre-line
        self.n_film = -0.5 * hb - 0.15 * min(H, 1.0)
        self.n_low = -0.5 * hb  # the base's lower face
        self.n_base = 0.5 * hb  # the base's upper face
        self.n_cavity = n_top - 0.5 * tm  # the cavities' roof
        self.n_top = n_top + 0.5 * tm  # the top wall's outer face
        self.hb = hb

    # ---- where the tests change along each row (|x|; inf: nowhere) --------------------------------------
    def x_radius(self, radius: float):
        """First ``|x|`` with ``hypot(x, y - oy) >= radius``."""
        yo = self.yo
        if radius <= 0.0:
            return np.zeros(yo.shape)
        return np.sqrt(np.maximum((radius - yo) * (radius + yo), 0.0))

    def x_normal(self, cs, strict):
        """First ``|x|`` with the normal offset ``n >= c`` (``n > c`` where ``strict``), for each ``c`` of ``cs``.

        ``n`` grows with ``|x|``: ``n = rho - 1/k`` with ``rho`` the distance to the centre of curvature
        ``(0, -1/k)``, so ``n = c`` at ``x^2 = (c + 1/k)^2 - (y + 1/k)^2 = (c - y)(c + y + 2/k)``; flat
        (``k <= 1e-12``): ``n = y``.
        """
        y, k = self.lay.y, self.k
        c = np.asarray(cs, float)[:, None]
        if self.flat:
            inside = np.where(np.asarray(strict)[:, None], y > c, y >= c)
            return np.where(inside, 0.0, np.inf)
        x = np.sqrt(np.maximum((c - y) * (c + y + 2.0 / k), 0.0))
        return np.where(c + 1.0 / k <= 0.0, 0.0, x)

    def x_arc(self, ss):
        """Where the radial line at arc length ``s >= 0`` crosses each row, for each ``s`` of ``ss`` (inf: never).

        Along a row (``x >= 0``) the arc length ``atan2(k x, 1 + k y) / k`` is monotonic: it grows with ``x``
        above the centre of curvature and shrinks below it. Flat: ``s = x``.
        """
        y, k = self.lay.y, self.k
        s = np.asarray(ss, float)[:, None]
        if self.flat:
            return np.broadcast_to(s, (len(s), len(y)))
        phi = np.minimum(k * s, math.pi)
        a = 1.0 + k * y  # k (y + 1/k): > 0 above the centre
        with np.errstate(over="ignore"):
            x = a * (np.tan(phi) / k)
        crosses = ((phi < 0.5 * math.pi) & (a > 0.0)) | ((phi > 0.5 * math.pi) & (a < 0.0))
        return np.where(crosses, x, np.inf)

    # ---- the tests at points (half-column q, row), computed as the picture defines them -----------------
    def _xy(self, q, rows):
        lay = self.lay
        return (lay.jc + q + 0.5 - 0.5 * lay.ws) / lay.px, lay.y[rows]

    def arc(self, q, rows):
        """Arc length ``s`` and normal offset ``n`` of points."""
        return _arc_coordinates(*self._xy(q, rows), self.k)

    def radial(self, q, rows):
        """Signed distance to the object's undeformed surface (negative inside)."""
        X, Y = self._xy(q, rows)
        Yo = Y - self.oy
        return (X * X + Yo * Yo - self.R_u * self.R_u) / (np.hypot(X, Yo) + self.R_u)

    def in_span(self, s):
        return np.abs(s) <= 0.5 * self.L

    # ---- spans -----------------------------------------------------------------------------------------
    def spans(self, parts):
        """Half-columns ``lo, hi`` (arrays: part x row) of each part's points, ``xlo <= |x| < xhi``.

        ``parts``: ``(xlo, xhi, test)`` per part. A column whose centre lies on a boundary (to rounding) is decided
        by ``test(q, rows)``, the part's own definition, so that the picture does not depend on how the boundary
        was found.
        """
        lay = self.lay
        v = np.array([x for xlo, xhi, _ in parts for x in (xlo, xhi)]) * lay.px - lay.off
        t = np.clip(np.ceil(v), 0, lay.nh).astype(lay.itype)
        c = np.rint(v)
        with np.errstate(invalid="ignore"):  # inf - inf
            near = (np.abs(v - c) < 1e-6) & (c >= 0) & (c < lay.nh)
        if near.any():
            for i in np.flatnonzero(near.any(axis=1)).tolist():
                rows = np.flatnonzero(near[i])
                cols = c[i, rows]
                inside = parts[i // 2][2](cols, rows)
                t[i, rows] = np.where(inside, cols, cols + 1) if i % 2 == 0 else np.where(inside, cols + 1, cols)
        return t[0::2], t[1::2]


def _draw_scene(labels: np.ndarray, lay: _Layout, state: RenderState, chambers: int):
    """Paint the object and the actuator into ``labels``.

    Returns the rows painted (``(row0, row1)`` or ``None``) and the loaded zone's tint (or ``None``).
    """
    g = _Scene(lay, state, chambers)
    L, ts, eps = g.L, g.ts, 0.6 / lay.px * lay.ss

    def test_band(q, rows):
        rmr = g.radial(q, rows)
        return (rmr <= 0.0) & (rmr >= -g.H)

    def test_actuator(lo, hi, strict_lo=False, strict_hi=False, cell=None):
        def test(q, rows):
            s, n = g.arc(q, rows)
            inside = (np.abs(s) <= 0.5 * L) & ((n > lo) if strict_lo else (n >= lo))
            inside &= (n < hi) if strict_hi else (n <= hi)
            if cell is not None:
                u = s + 0.5 * L
                frac = u - np.floor(u)
                inside &= (frac > 0.5 * ts) & (frac < 1.0 - 0.5 * ts) & (np.floor(u) == cell)
            return inside

        return test

    def test_zone(q, rows):
        return test_band(q, rows) & test_actuator(-np.inf, g.n_low)(q, rows)

    def test_dash(q, rows):
        return test_actuator(g.n_low, np.inf, strict_lo=True)(q, rows) & (np.abs(g.radial(q, rows)) <= eps)

    # ---- the parts' spans along the rows: |x| from .. to, and the part's own test ------------------------
    cells = []  # the cavities between the side walls (radial), as arc lengths (x >= 0)
    s_max = 0.5 * L if g.flat else min(0.5 * L, math.pi / g.k)
    for m in range(chambers):
        s0, s1 = m + 0.5 * ts - 0.5 * L, m + 1.0 - 0.5 * ts - 0.5 * L
        if s0 < s1 and s1 > 0.0 and max(s0, 0.0) < s_max:
            cells.append((m, max(s0, 0.0), s1))
    arc = g.x_arc([0.0, 0.5 * L] + [s for _, s0, s1 in cells for s in (s0, s1)])
    span_x0, span_x1 = np.minimum(arc[0], arc[1]), np.maximum(arc[0], arc[1])  # |s| <= L/2
    n_low_gt, n_low, n_top, n_base, n_cavity, n_film = g.x_normal(
        [g.n_low, g.n_low, g.n_top, g.n_base, g.n_cavity, g.n_film], [True, False, True, True, False, False]
    )
    dent_x0 = np.maximum(span_x0, n_low_gt)  # the actuator and above: no object material
    body_x0 = np.maximum(span_x0, n_low)
    band_x0, band_x1 = g.x_radius(g.R_u - g.H), g.x_radius(g.R_u)
    parts = [
        (band_x0, band_x1, test_band),
        (dent_x0, span_x1, test_actuator(g.n_low, np.inf, strict_lo=True)),
        (body_x0, np.minimum(span_x1, n_top), test_actuator(g.n_low, g.n_top)),
        (body_x0, np.minimum(span_x1, n_base), test_actuator(g.n_low, g.n_base)),
    ]
    _BAND, _DENT, _BODY, _BASE = range(4)
    zone = film = dash = None
    if g.delta > 0.0:  # the loaded zone: the object under the actuator
        zone = len(parts)
        parts.append((np.maximum(band_x0, span_x0), np.minimum(np.minimum(band_x1, dent_x0), span_x1), test_zone))
    if g.crushed_through:  # what is left of the object: a crushed film on the actuator's base
        film = len(parts)
        parts.append((np.maximum(span_x0, n_film), np.minimum(span_x1, n_low_gt), test_actuator(g.n_film, g.n_low)))
    if g.delta_draw > 0.0:  # the undeformed surface where the actuator pushed the object in
        dash = len(parts)
        parts.append((np.maximum(g.x_radius(g.R_u - eps), dent_x0), np.minimum(g.x_radius(g.R_u + eps), span_x1),
                      test_dash))
    first_cell = len(parts)
    cav_x0, cav_x1 = np.maximum(span_x0, n_base), np.minimum(span_x1, n_cavity)
    for i, (m, _, _) in enumerate(cells):
        x0, x1 = arc[2 + 2 * i], arc[3 + 2 * i]
        parts.append((np.maximum(np.minimum(x0, x1), cav_x0), np.minimum(np.maximum(x0, x1), cav_x1),
                      test_actuator(g.n_base, g.n_cavity, True, True, cell=m)))
    lo, hi = g.spans(parts)
    width = np.maximum(hi - lo, 0).view(lay.utype)
    box = _boxes(lo, hi, lay)

    # ---- paint them (the right half, mirrored), each on its own box ----------------------------------
    scene = [box[i] for i in (_BAND, _BODY, film) if i is not None and box[i] is not None]
    tint = drawn = None
    if scene:
        r0, r1 = max(min(b[0] for b in scene) - 2, 0), min(max(b[1] for b in scene) + 2, lay.hs)
        c1 = min(max(b[3] for b in scene) + 2, lay.q.shape[1])
        lab = labels[r0:r1, lay.jc : lay.jc + c1] if lay.even else labels[r0:r1]  # x >= 0, or all (odd width)

        def region(i, margin=0):
            a, b, c, d = box[i]
            return max(a - margin, r0), min(b + margin, r1), max(c - margin, 0), min(d + margin, c1)

        def mask(i, reg):  # lo <= q < hi, as one unsigned comparison: 0 <= q - lo < hi - lo
            a, b, c, d = reg
            return (lay.q[:, c:d] - lo[i, a:b, None]).view(lay.utype) < width[i, a:b, None]

        def paint(reg, m, label):
            a, b, c, d = reg
            sub = lab[a - r0 : b - r0, c:d]
            np.maximum(sub, m.view(np.uint8) * np.uint8(label), out=sub)

        # the parts with an outline, as bit planes of one array: the object (1), the cavities (2), the body (4)
        bits = np.zeros(lab.shape, np.uint8)
        if box[_BAND] is not None:
            a, b, c, d = reg = region(_BAND)
            bits[a - r0 : b - r0, c:d] = (mask(_BAND, reg) & ~mask(_DENT, reg)).view(np.uint8)
        if box[_BODY] is not None:
            a, b, c, d = reg = region(_BODY)
            planes = bits[a - r0 : b - r0, c:d]
            planes |= mask(_BODY, reg).view(np.uint8) << 2
            for i in range(first_cell, len(parts)):
                if box[i] is not None:
                    a, b, c, d = region(i)
                    planes = bits[a - r0 : b - r0, c:d]
                    planes |= mask(i, (a, b, c, d)).view(np.uint8) << 1
        edges = bits & ~_erode(bits, lay.ss)  # pixels within `ss` subpixels of a part's edge
        # paint in order: each pixel keeps the topmost part
        lab[...] = bits & 1  # _L_OBJECT
        if zone is not None and box[zone] is not None:
            reg = region(zone)
            paint(reg, mask(zone, reg), _L_ZONE)
            if not state.damaged:  # tinted by the damage ratio (fading with depth)
                ratio = max(
                    _safe_ratio(state.contact_force, state.failure_traction),
                    _safe_ratio(g.delta, state.crush_indentation),
                )
                tint = (float(np.clip(ratio, 0.0, 1.0)) * 0.85, g.k, g.hb, g.H)
        whole = (r0, r1, 0, lab.shape[1])
        paint(whole, (edges & 1).view(bool), _L_OBJECT_EDGE)
        if film is not None and box[film] is not None:
            reg = region(film)
            paint(reg, mask(film, reg), _L_FILM)
        if box[_BODY] is not None:
            a, b, c, d = reg = region(_BODY)
            sub = bits[a - r0 : b - r0, c:d]
            paint(reg, (sub >> 2).view(bool), _L_ELASTOMER)
            if box[_BASE] is not None:
                rb = region(_BASE)
                paint(rb, mask(_BASE, rb), _L_BASE)
            paint(reg, ((sub >> 1) & 1).view(bool), _L_CAVITY)
            sub = edges[a - r0 : b - r0, c:d]
            paint(reg, ((sub >> 1) & 1).view(bool), _L_CAVITY_EDGE)
            paint(reg, (sub >> 2).view(bool), _L_OUTLINE)
        drawn = (r0, r1)
        if lay.even:
            labels[r0:r1, lay.jc - c1 : lay.jc] = lab[:, ::-1]

    # ---- the undeformed surface, dashed (the one part not symmetric) ----------------------------------
    if dash is not None and box[dash] is not None:
        a, b = box[dash][:2]
        line = ((lay.q_full - lo[dash, a:b, None]).view(lay.utype) < width[dash, a:b, None]) & lay.dash
        np.copyto(labels[a:b], _L_DASH, where=line & (labels[a:b] < _L_DASH))
        drawn = (a, b) if drawn is None else (min(drawn[0], a), max(drawn[1], b))
    return drawn, tint


def _boxes(lo, hi, lay: _Layout):
    """Each span set's bounding box ``(row0, row1, col0, col1)`` (``None`` if empty)."""
    ne = lo < hi
    rows = ne.any(axis=1)
    first = ne.argmax(axis=1)
    last = ne.shape[1] - ne[:, ::-1].argmax(axis=1)
    if lay.even:
        c0 = np.where(ne, lo, lay.nh).min(axis=1)
        c1 = np.where(ne, hi, 0).max(axis=1)
    else:  # columns are |x|-indexed but laid out in full: no column box
        c0, c1 = np.zeros_like(first), np.full_like(first, lay.ws)
    boxes = zip(rows.tolist(), first.tolist(), last.tolist(), c0.tolist(), c1.tolist(), strict=True)
    return [(a, b, c, d) if r else None for r, a, b, c, d in boxes]


def _erode(planes: np.ndarray, r: int) -> np.ndarray:
    """Erode each bit plane ``r`` times by a pixel and its 4 neighbours (the array's border counts as inside)."""
    inner = planes
    for _ in range(max(1, r)):
        nxt = inner.copy()
        nxt[1:, :] &= inner[:-1, :]
        nxt[:-1, :] &= inner[1:, :]
        nxt[:, 1:] &= inner[:, :-1]
        nxt[:, :-1] &= inner[:, 1:]
        inner = nxt
    return inner


def _arc_coordinates(X, Y, kappa):
    """Arc length ``s`` and outward normal offset ``n`` of points, for an arc through the origin.

    The arc has curvature ``kappa >= 0``, is tangent to the x axis at the origin and curls downwards
    (centre at ``(0, -1/kappa)``); ``s`` is measured along it from the origin and ``n`` away from the
    centre. Exact and smooth as ``kappa -> 0`` (``s = X``, ``n = Y``).
    """
    k = float(kappa)
    q = np.hypot(k * X, 1.0 + k * Y)
    n = (k * (X * X + Y * Y) + 2.0 * Y) / (q + 1.0)
    s = np.arctan2(k * X, 1.0 + k * Y) / k if k > 1e-12 else X
    return s, n


def _normal_offset(k: float, x, y):
    """The actuator's normal offset ``n`` of points (exact and smooth as ``k -> 0``)."""
    q = np.sqrt((k * x) ** 2 + (1.0 + k * y) ** 2)
    return (k * (x * x + y * y) + 2.0 * y) / (q + 1.0)


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
    lay = _layout(width, height, chambers, supersample)
    labels = np.zeros((lay.hs, lay.ws), np.uint8)
    drawn, tint = _draw_scene(labels, lay, state, chambers)
    _draw_gauges(labels, lay, state)
    # average the label image down, where anything is drawn: the scene's rows and the gauges' boxes
    pal = _palette(state)
    colours = _uniform_colours(pal, lay.ss)
    pairs = _pair_colours(colours) if lay.ss == 2 else None
    img = lay.blank.copy()
    i0 = i1 = 0
    if drawn is not None:
        i0, i1 = drawn[0] // lay.ss, -(-drawn[1] // lay.ss)
        _resolve(img, labels, lay, pal, colours, pairs, tint, i0, i1, 0, width)
    for a, b, c, d in lay.gauge_boxes:
        for a2, b2 in ((a, min(b, i0)), (max(a, i1), b)):  # less the scene's rows, done already
            if a2 < b2:
                _resolve(img, labels, lay, pal, colours, pairs, None, a2, b2, c, d)
    if label or (label is None and label_fits(width, height)):
        draw_text(img, label_lines(state), lay.label_x, lay.label_y, label_scale(width, height),
                  halo=_to_uint8(_BACKGROUND))
    return img


def _stamp(labels: np.ndarray, rect, label: int) -> None:
    a, b, c, d = rect
    labels[a:b, c:d] = label


def _draw_gauges(labels: np.ndarray, lay: _Layout, state: RenderState) -> None:
    """Stamp the gauges (see the module docstring) over the scene, in their order."""
    top, bottom, rect, (p_bar, t_bar, progress) = lay.top, lay.bottom, lay.rect, lay.bars
    # pressure bar (left)
    pf = min(max(float(state.pressure_fraction), 0.0), 1.0)
    _stamp(labels, p_bar[0], _L_GAUGE_BG)
    _stamp(labels, rect(p_bar[1], bottom - pf * (bottom - top), p_bar[2], bottom), _L_PRESSURE)
    for r in p_bar[3]:
        _stamp(labels, r, _L_OUTLINE)
    # traction gauge (right), log scale
    lo, hi = _TRACTION_LOG_RANGE

    def level(f):
        if f <= 0.0:
            return float(bottom)
        t = (math.log10(f) - lo) / (hi - lo)
        return bottom - min(max(t, 0.0), 1.0) * (bottom - top)

    _stamp(labels, t_bar[0], _L_GAUGE_BG)
    F = float(state.contact_force)
    if F > 0.0:
        _stamp(labels, rect(t_bar[1], level(F), t_bar[2], bottom), _L_TRACTION)
    for r in t_bar[3]:
        _stamp(labels, r, _L_OUTLINE)
    ticks = [(float(state.grip_traction), _L_GREEN), (float(state.failure_traction), _L_DAMAGED)]
    if state.in_contact and state.indentation > 0:
        # the traction at which this object is crushed through: k~ delta~_c
        ticks.append(
            (float(state.contact_force) / float(state.indentation) * float(state.crush_indentation), _L_DAMAGED)
        )
    bw = lay.bw
    for f, c in ticks:
        if f > 0.0 and lo <= math.log10(f) <= hi:
            y = level(f)
            _stamp(labels, rect(t_bar[1] - bw // 2, y - 1, t_bar[2] + bw // 2, y + 1), c)
    # progress (bottom), the hold phase shaded
    xa, xb = progress[1], progress[2]
    _stamp(labels, progress[0], _L_GAUGE_BG)
    _stamp(labels, rect(xa + float(state.hold_start) * (xb - xa), lay.pb_top, xb, lay.pb_bot), _L_HOLD)
    xp = xa + min(max(float(state.progress), 0.0), 1.0) * (xb - xa)
    _stamp(labels, rect(xa, lay.pb_top, xp, lay.pb_bot), _L_PROGRESS)
    for r in progress[3]:
        _stamp(labels, r, _L_OUTLINE)
    # status lamp (top right)
    patch = labels[lay.lamp]
    patch[lay.lamp_disc] = _L_LAMP
    patch[lay.lamp_edge] = _L_OUTLINE


def _palette(state: RenderState) -> np.ndarray:
    """The float32 colour of each label, as the layers' paint would leave it."""
    pal = _PALETTE.copy()
    pal[_L_OBJECT_EDGE] = _DAMAGED if state.damaged else _OBJECT_EDGE
    crushed_through = state.in_contact and float(state.indentation) > float(state.object_thickness)
    pal[_L_DASH] = _DAMAGED if crushed_through else _OBJECT_EDGE
    pf = min(max(float(state.pressure_fraction), 0.0), 1.0)
    pal[_L_CAVITY] = _CAVITY_LOW + pf * (_CAVITY_HIGH - _CAVITY_LOW)
    pal[_L_CAVITY_EDGE] = (1.0 - 0.6) * pal[_L_CAVITY] + 0.6 * _OUTLINE
    F = float(state.contact_force)
    pal[_L_TRACTION] = _DAMAGED if state.damaged else (_GREEN if F >= float(state.grip_traction) else _ORANGE)
    if state.damaged:
        pal[_L_LAMP] = _DAMAGED
    elif state.dropped:
        pal[_L_LAMP] = _ORANGE
    elif state.in_hold:
        pal[_L_LAMP] = _GREEN
    return pal


def _to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _tint_colours(tint, lay: _Layout, xs, ys) -> np.ndarray:
    """The loaded zone's colour at points given in subpixel coordinates (float32, as painted)."""
    strength, kappa, hb, H = tint
    x = (xs - 0.5 * lay.ws) / lay.px
    y = (0.4 * lay.hs - ys) / lay.px
    n = _normal_offset(kappa, x, y) if kappa > 1e-12 else y
    depth = np.clip((-0.5 * hb - n) / max(H, 1e-9), 0.0, 1.0)
    a = (strength * (1.0 - depth))[:, None]
    return ((1.0 - a) * _OBJECT.astype(np.float32) + a * _LOADED).astype(np.float32)


def _uniform_colours(pal: np.ndarray, s: int) -> np.ndarray:
    """The uint8 colour of a pixel whose ``s x s`` subpixels all have one label (summed as the supersampling sums)."""
    acc = np.zeros_like(pal)
    for _ in range(s * s):
        acc += pal
    return _to_uint8(acc / (s * s))


_PAIRS = (np.arange(_N_LABELS)[:, None] + 256 * np.arange(_N_LABELS)[None, :]).ravel()


def _pair_colours(colours: np.ndarray) -> np.ndarray:
    """``(65536, 6)``: the colours of two pixels side by side, labels ``a, b`` at ``a + 256 b`` (the pair's
    two bytes read as one little-endian uint16); the entries of no pair of labels are left unset."""
    pairs = np.empty((65536, 6), np.uint8)
    pairs[_PAIRS, :3] = np.repeat(colours, _N_LABELS, axis=0)  # a, the left pixel
    pairs[_PAIRS, 3:] = np.tile(colours, (_N_LABELS, 1))  # b, the right one
    return pairs


def _resolve(img, labels, lay: _Layout, pal, colours, pairs, tint, i0: int, i1: int, j0: int, j1: int) -> None:
    """Average the label image down to the frame's pixels ``[i0, i1) x [j0, j1)``.

    A pixel whose subpixels have one label takes that label's colour; the others (the edges) average their
    subpixels' colours (float32, in the supersampling's order); the loaded zone's tint is computed per pixel.
    """
    s, h, w = lay.ss, i1 - i0, j1 - j0
    sub = labels[s * i0 : s * i1, s * j0 : s * j1]
    if s == 2:  # a pixel's two subpixels in a row are one uint16
        v = sub.view("<u2").reshape(h, 2, w)
        p0, p1 = v[:, 0], v[:, 1]
        first = p0.astype(np.uint8)
        mixed = (p0 != p1) | (p0 >> 8 != (p0 & 0xFF))
    else:
        blocks = sub.reshape(h, s, w, s)
        first = blocks[:, 0, :, 0]
        mixed = (blocks != first[:, None, :, None]).any(axis=(1, 3))
    out = img[i0:i1, j0:j1]
    if w % 2 == 0 and s == 2:  # two pixels per look-up, in a table of label pairs
        if out.flags.c_contiguous:
            np.take(pairs, first.view("<u2"), axis=0, out=out.reshape(h, w // 2, 6), mode="clip")
        else:
            out[...] = np.take(pairs, first.view("<u2"), axis=0).reshape(h, w, 3)
    else:
        out[...] = np.take(colours, first, axis=0)
    if tint is not None:
        z = np.flatnonzero((first == _L_ZONE) & ~mixed)
        if z.size:
            zi, zj = np.divmod(z, w)
            c = _tint_colours(tint, lay, s * (j0 + zj) + 0.5 * s, s * (i0 + zi) + 0.5 * s)
            out[zi, zj] = _to_uint8(c)
    idx = np.flatnonzero(mixed)
    if idx.size:
        i, j = np.divmod(idx, w)
        i += i0
        j += j0
        base = (s * i) * lay.ws + s * j  # each pixel's first subpixel, in the flat label image
        lab = labels.reshape(-1)[lay.block[:, None] + base]  # (subpixel, pixel)
        c = np.take(pal, lab, axis=0)
        if tint is not None:
            zs, zp = np.nonzero(lab == _L_ZONE)
            if zp.size:
                di, dj = np.divmod(zs, s)
                c[zs, zp] = _tint_colours(tint, lay, s * j[zp] + dj + 0.5, s * i[zp] + di + 0.5)
        acc = c[0]
        for k in range(1, s * s):  # in order, as the supersampling sums
            acc += c[k]
        img[i, j] = _to_uint8(acc / (s * s))


# ---------------------------------------------------------------------------------------------
# Text: a 5 x 8 bitmap font, the frame's label, the contact sheet's legend
# ---------------------------------------------------------------------------------------------

LABEL_MIN_WIDTH, LABEL_MIN_HEIGHT = 240, 180
"""The smallest frame that carries the label (:func:`render_frame`'s ``label``); below it the label would cover the
actuator."""

# text colours: dark on the light background, and the state's (darker than the gauges' green and orange, for contrast)
_TEXT = np.array([32, 36, 44], np.uint8)
_TEXT_GREEN = np.array([24, 128, 52], np.uint8)
_TEXT_RED = np.array([196, 20, 20], np.uint8)
_TEXT_ORANGE = np.array([204, 108, 0], np.uint8)


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
        crushed = state.in_contact and float(state.indentation) > float(state.crush_indentation)
        return "crushed" if crushed else "damaged"
    if state.dropped:
        return "slipped"
    if state.in_hold:
        return "held"
    if not state.in_contact:
        return "free"
    return "gripping" if float(state.contact_force) >= float(state.grip_traction) else "squeezing"


_STATUS_COLOURS = {"crushed": _TEXT_RED, "damaged": _TEXT_RED, "slipped": _TEXT_ORANGE, "held": _TEXT_GREEN,
                   "gripping": _TEXT_GREEN}


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
    return [(name, _TEXT), (f"step {int(state.step)}", _TEXT), (f"{float(state.pressure_kpa):.1f} kPa", _TEXT),
            (status, _STATUS_COLOURS.get(status, _TEXT))]


# ---------------------------------------------------------------------------------------------
# PNG, contact sheets, the human window
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


# The legend: (swatches, text) per entry, in the palette's colours (see the module docstring)
LEGEND = (
    ((_BASE, _ELASTOMER, _CAVITY_HIGH), "finger: base, walls, chambers (bluer: more pressure)"),
    ((_OBJECT, 0.15 * _OBJECT + 0.85 * _LOADED), "object, loaded zone (oranger: nearer damage)"),
    ((), "dashed: its undeformed surface"),
    ((_PRESSURE,), "left bar: pressure"),
    ((), "right bar: contact traction, log 0.5 Pa to 50 kPa; ticks: grip (green), failure and crush (red)"),
    ((_GREEN,), "green: held, or gripping (traction above grip)"),
    ((_ORANGE,), "orange: slipped, or traction below grip"),
    ((_DAMAGED,), "red: damaged or crushed"),
    ((_GREY,), "lamp grey: squeeze phase"),
    ((_PROGRESS, _HOLD), "bottom bar: step, hold phase shaded"),
    ((), "label: object (or k~), step, pressure, state"),
)
"""The contact sheet's legend: each entry's colour swatches (RGB) and its words."""


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
                strip[a:b, c:d] = _OUTLINE
                strip[a + 1 : b - 1, c + 1 : d - 1] = _to_uint8(colour)
            x += box + s
        if swatches:
            x += step
        draw_text(strip, [(text, _TEXT)], x, y, s)
    return strip


class HumanViewer:
    """A matplotlib window showing frames (``render_mode="human"``); matplotlib is imported here only.

    With a non-interactive backend (headless, e.g. ``Agg``) the frame is drawn to the figure's canvas and
    nothing is shown; with an interactive one, the window is updated and the GUI given ``1/fps`` seconds.
    """

    def __init__(self, title: str = "PneuNetGrasp-v0", fps: float = 20.0) -> None:
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
