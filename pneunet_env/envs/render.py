"""Pictures of the grasp, drawn with numpy only (no matplotlib on the ``rgb_array`` path).

:func:`render_frame` rasterises one state into an ``HxWx3`` uint8 array. Every shape is a mask over
the pixel grid, supersampled and averaged down for smooth edges:

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
  phase shaded) and a status lamp (top right: grey squeezing, green held, orange dropped, red damaged).

Lengths are in units of the chamber width ``w``, like the model. :func:`save_png` writes a PNG with
``zlib`` only; :func:`contact_sheet` tiles frames. :class:`HumanViewer` shows frames in a matplotlib
window (imported lazily, only for ``render_mode="human"``).
"""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from pneunet_env.physics.params import ActuatorParams

__all__ = ["RenderState", "render_state", "render_frame", "save_png", "read_png", "contact_sheet", "HumanViewer"]

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


def render_state(state, params, i: int | None = None) -> RenderState:
    """What a frame shows of an env's :class:`pneunet_env.task.EnvState` (of its entry ``i`` for a batch)."""

    def at(v):
        return v if i is None else v[i]

    eq, obj, thr, st, tp = state.eq, state.obj, state.thresholds, state.task, params.task
    step = int(at(st.step))
    in_contact = bool(at(eq.in_contact))
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
    )


class _Canvas:
    """A float RGB image with world coordinates (y up) for its pixel centres."""

    def __init__(self, width: int, height: int, supersample: int, units_wide: float, origin: tuple[float, float]):
        self.ss = int(supersample)
        self.w, self.h = width * self.ss, height * self.ss
        self.img = np.empty((self.h, self.w, 3), np.float32)
        self.img[:] = _BACKGROUND
        self.px = self.w / units_wide  # pixels per unit
        i = np.arange(self.h)[:, None] + 0.5
        j = np.arange(self.w)[None, :] + 0.5
        self.X = (j - origin[0] * self.w) / self.px
        self.Y = (origin[1] * self.h - i) / self.px

    def paint(self, mask, colour, alpha=1.0):
        if np.ndim(alpha) == 0:
            if alpha >= 1.0:
                self.img[mask] = colour
            else:
                self.img[mask] = (1.0 - alpha) * self.img[mask] + alpha * np.asarray(colour, float)
        else:
            a = np.broadcast_to(alpha, mask.shape)[mask][:, None]
            c = np.asarray(colour, float)
            if c.ndim > 1:
                c = c[mask] if c.shape[:2] == mask.shape else c
            self.img[mask] = (1.0 - a) * self.img[mask] + a * c

    def _px(self, v) -> int:
        return int(round(float(v) * self.ss))

    def fill_rect(self, x0, y0, x1, y1, colour) -> None:
        """Fill the rectangle ``[x0, x1) x [y0, y1)``, given in final-image pixels."""
        a, b = max(self._px(y0), 0), min(self._px(y1), self.h)
        c, d = max(self._px(x0), 0), min(self._px(x1), self.w)
        if a < b and c < d:
            self.img[a:b, c:d] = colour

    def frame_rect(self, x0, y0, x1, y1, colour) -> None:
        """Outline the rectangle with a one-(final-)pixel line."""
        t = 1.0
        self.fill_rect(x0, y0, x1, y0 + t, colour)
        self.fill_rect(x0, y1 - t, x1, y1, colour)
        self.fill_rect(x0, y0, x0 + t, y1, colour)
        self.fill_rect(x1 - t, y0, x1, y1, colour)

    def disc(self, cx, cy, r, colour, edge=None) -> None:
        a, b = max(self._px(cy - r) - 1, 0), min(self._px(cy + r) + 1, self.h)
        c, d = max(self._px(cx - r) - 1, 0), min(self._px(cx + r) + 1, self.w)
        i = np.arange(a, b)[:, None] + 0.5
        j = np.arange(c, d)[None, :] + 0.5
        dist = np.hypot(j - cx * self.ss, i - cy * self.ss)
        patch = self.img[a:b, c:d]
        patch[dist <= r * self.ss] = colour
        if edge is not None:
            patch[(dist <= r * self.ss) & (dist > (r - 1.0) * self.ss)] = edge

    def result(self) -> np.ndarray:
        s = self.ss
        img = self.img
        if s > 1:
            acc = np.zeros((self.h // s, self.w // s, 3), np.float32)
            for di in range(s):
                for dj in range(s):
                    acc += img[di::s, dj::s]
            img = acc / (s * s)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _boundary(mask: np.ndarray, r: int) -> np.ndarray:
    """Pixels of ``mask`` within ``r`` pixels of its edge."""
    inner = mask.copy()
    for _ in range(max(1, r)):
        nxt = inner.copy()
        nxt[1:, :] &= inner[:-1, :]
        nxt[:-1, :] &= inner[1:, :]
        nxt[:, 1:] &= inner[:, :-1]
        nxt[:, :-1] &= inner[:, 1:]
        inner = nxt
    return mask & ~inner


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


def render_frame(
    state: RenderState, width: int = 480, height: int = 360, chambers: int = 6, supersample: int = 2
) -> np.ndarray:
    """Draw one state; returns a ``(height, width, 3)`` uint8 array. See the module docstring."""
    width, height, chambers, supersample = int(width), int(height), int(chambers), int(supersample)
    if width < 32 or height < 32:
        raise ValueError(f"frame must be at least 32 x 32 pixels, got {width} x {height}")
    if chambers < 1:
        raise ValueError(f"chambers must be >= 1, got {chambers}")
    prm = state.params
    d, hb, hs, hm = prm.chamber_height, prm.base_thickness, prm.side_thickness, prm.top_thickness
    kappa = max(float(state.curvature), 0.0)
    es = float(state.side_strain)
    L = float(chambers)
    units_wide = max(2.0 * L, 12.0)
    cv = _Canvas(width, height, supersample, units_wide, origin=(0.5, 0.4))
    X, Y = cv.X, cv.Y

    # ---- the object (drawn first; the actuator covers it) ---------------------------------------
    R_u = 1.0 / float(state.object_curvature) - 0.5 * hb  # its undeformed surface, as drawn (base's lower face)
    H = float(state.object_thickness)
    delta = max(float(state.indentation), 0.0) if state.in_contact else 0.0
    crushed_through = delta > H
    delta_draw = min(delta, H)
    oy = -0.5 * hb + delta_draw - R_u  # object centre (0, oy); concentric with the actuator while delta <= H
    # signed distance to the undeformed surface (negative inside), stable for a large radius
    Yo = Y - oy
    r_minus_R = (X * X + Yo * Yo - R_u * R_u) / (np.hypot(X, Yo) + R_u)
    s_act, n_act = _arc_coordinates(X, Y, kappa)
    in_span = np.abs(s_act) <= 0.5 * L
    dent = in_span & (n_act > -0.5 * hb)  # where the actuator sits: no object material
    obj = (r_minus_R <= 0.0) & (r_minus_R >= -H) & ~dent
    cv.paint(obj, _OBJECT)
    # the loaded zone under the actuator, tinted by the damage ratio (fading with depth)
    if state.in_contact and delta > 0.0:
        ratio = max(
            _safe_ratio(state.contact_force, state.failure_traction),
            _safe_ratio(delta, state.crush_indentation),
        )
        depth = np.clip((-0.5 * hb - n_act) / max(H, 1e-9), 0.0, 1.0)
        zone = obj & in_span
        if state.damaged:
            cv.paint(zone, _DAMAGED, 0.85)
        else:
            cv.paint(zone, _LOADED, np.clip(ratio, 0.0, 1.0) * 0.85 * (1.0 - depth))
    cv.paint(_boundary(obj, supersample), _DAMAGED if state.damaged else _OBJECT_EDGE)
    if crushed_through:
        # pushed in past its thickness: what is left is a crushed film on the actuator's base
        film = in_span & (n_act <= -0.5 * hb) & (n_act >= -0.5 * hb - 0.15 * min(H, 1.0))
        cv.paint(film, _DAMAGED)
    # the undeformed surface where the actuator pushed it in: dashed
    if delta_draw > 0.0:
        dash = (np.floor(X * 4.0) % 2 == 0)
        line = dent & (np.abs(r_minus_R) <= 0.6 / cv.px * supersample) & dash
        cv.paint(line, _DAMAGED if crushed_through else _OBJECT_EDGE)

    # ---- the actuator ------------------------------------------------------------------------------
    em = d * (1.0 + es) * kappa
    tm = hm * (1.0 + em) ** -2  # top wall, thinned
    ts = hs * (1.0 + es) ** -2  # side walls, thinned
    n_top = d * (1.0 + es)  # the top wall's centre-line
    body = in_span & (n_act >= -0.5 * hb) & (n_act <= n_top + 0.5 * tm)
    cv.paint(body, _ELASTOMER)
    # cavities: between the side walls (radial: constant s), above the base, below the top wall
    u = s_act + 0.5 * L  # 0 .. L across the actuator
    cell = np.floor(u)
    frac = u - cell
    cavity = (
        in_span
        & (n_act > 0.5 * hb)
        & (n_act < n_top - 0.5 * tm)
        & (frac > 0.5 * ts)
        & (frac < 1.0 - 0.5 * ts)
    )
    pf = float(np.clip(state.pressure_fraction, 0.0, 1.0))
    cv.paint(cavity, _CAVITY_LOW + pf * (_CAVITY_HIGH - _CAVITY_LOW))
    cv.paint(_boundary(cavity, supersample), _OUTLINE, 0.6)
    base = in_span & (n_act >= -0.5 * hb) & (n_act <= 0.5 * hb)
    cv.paint(base, _BASE)
    cv.paint(_boundary(body, supersample), _OUTLINE)

    # ---- gauges (final-image pixel units) ------------------------------------------------------------
    _gauges(cv, state, width, height)
    return cv.result()


def _safe_ratio(a, b) -> float:
    a, b = float(a), float(b)
    return a / b if b > 0.0 else 0.0


def _gauges(cv: _Canvas, state: RenderState, width: int, height: int) -> None:
    m = max(6, width // 60)  # margin
    bw = max(8, width // 40)  # bar width
    top, bottom = int(0.12 * height), int(0.80 * height)
    # pressure bar (left)
    x0 = m
    cv.fill_rect(x0, top, x0 + bw, bottom, _GAUGE_BG)
    pf = float(np.clip(state.pressure_fraction, 0.0, 1.0))
    cv.fill_rect(x0, bottom - pf * (bottom - top), x0 + bw, bottom, _PRESSURE)
    cv.frame_rect(x0, top, x0 + bw, bottom, _OUTLINE)
    # traction gauge (right), log scale
    x1 = width - m - bw
    lo, hi = _TRACTION_LOG_RANGE

    def level(f):
        if f <= 0.0:
            return float(bottom)
        t = (math.log10(f) - lo) / (hi - lo)
        return bottom - float(np.clip(t, 0.0, 1.0)) * (bottom - top)

    cv.fill_rect(x1, top, x1 + bw, bottom, _GAUGE_BG)
    F = float(state.contact_force)
    if state.damaged:
        colour = _DAMAGED
    elif F >= float(state.grip_traction):
        colour = _GREEN
    else:
        colour = _ORANGE
    if F > 0.0:
        cv.fill_rect(x1, level(F), x1 + bw, bottom, colour)
    cv.frame_rect(x1, top, x1 + bw, bottom, _OUTLINE)
    ticks = [(float(state.grip_traction), _GREEN), (float(state.failure_traction), _DAMAGED)]
    if state.in_contact and state.indentation > 0:
        # the traction at which this object is crushed through: k~ delta~_c
        ticks.append((float(state.contact_force) / float(state.indentation) * float(state.crush_indentation), _DAMAGED))
    for f, c in ticks:
        if f > 0.0 and lo <= math.log10(f) <= hi:
            y = level(f)
            cv.fill_rect(x1 - bw // 2, y - 1, x1 + bw + bw // 2, y + 1, c)
    # progress (bottom), the hold phase shaded
    pb_top, pb_bot = height - m - max(6, height // 40), height - m
    xa, xb = m, width - m
    xh = xa + float(state.hold_start) * (xb - xa)
    cv.fill_rect(xa, pb_top, xb, pb_bot, _GAUGE_BG)
    cv.fill_rect(xh, pb_top, xb, pb_bot, _HOLD)
    xp = xa + float(np.clip(state.progress, 0.0, 1.0)) * (xb - xa)
    cv.fill_rect(xa, pb_top, xp, pb_bot, _PROGRESS)
    cv.frame_rect(xa, pb_top, xb, pb_bot, _OUTLINE)
    # status lamp (top right)
    r = max(5, width // 48)
    if state.damaged:
        lamp = _DAMAGED
    elif state.dropped:
        lamp = _ORANGE
    elif state.in_hold:
        lamp = _GREEN
    else:
        lamp = _GREY
    cv.disc(width - m - r, m + r, r, lamp, edge=_OUTLINE)


# ---------------------------------------------------------------------------------------------
# PNG, contact sheets, the human window
# ---------------------------------------------------------------------------------------------


def _chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an ``HxWx3`` uint8 array as an 8-bit RGB PNG (zlib only); returns the path."""
    img = np.ascontiguousarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image must be an HxWx3 uint8 array, got {img.dtype} {img.shape}")
    h, w, _ = img.shape
    raw = np.zeros((h, 1 + 3 * w), np.uint8)  # filter type 0 on every row
    raw[:, 1:] = img.reshape(h, 3 * w)
    png = b"\x89PNG\r\n\x1a\n"
    png += _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6))
    png += _chunk(b"IEND", b"")
    path = Path(path)
    path.write_bytes(png)
    return path


def read_png(path: str | Path) -> np.ndarray:
    """Read back a PNG written by :func:`save_png` (8-bit RGB, unfiltered rows)."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, w, h = 8, b"", 0, 0
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        tag, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        (crc,) = struct.unpack(">I", data[pos + 8 + n : pos + 12 + n])
        if zlib.crc32(tag + body) & 0xFFFFFFFF != crc:
            raise ValueError(f"{path}: bad CRC in chunk {tag!r}")
        if tag == b"IHDR":
            w, h, depth, ctype, _, _, _ = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype != 2:
                raise ValueError(f"{path}: only 8-bit RGB is supported")
        elif tag == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    if np.any(raw[:, 0] != 0):
        raise ValueError(f"{path}: filtered rows are not supported")
    return raw[:, 1:].reshape(h, w, 3).copy()


def contact_sheet(frames, columns: int, gutter: int = 4, background: int = 255) -> np.ndarray:
    """Tile equal-sized ``HxWx3`` frames, row by row, ``columns`` per row."""
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
    return sheet


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
