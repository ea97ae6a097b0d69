"""The rasteriser: pixels of a :class:`pneunet_env.envs.scene.RenderState`, drawn with numpy only.

:func:`rasterise` draws one state into an ``HxWx3`` uint8 array (without the text label, which
:func:`pneunet_env.envs.render.render_frame` writes over it), supersampled (``ss x ss`` subpixels a pixel) and
averaged down for smooth edges, in three passes, each vectorised over rows:

1. **spans**: the scene's parts (:func:`pneunet_env.envs.scene.scene_parts`) cover one span of columns along each
   subpixel row, found in closed form; a subpixel centre lying on a boundary, to rounding, is decided by the part's
   own test;
2. **labels**: the spans are painted into a label image (one byte a subpixel, the topmost part's label), on each
   part's bounding box only; the picture is symmetric in ``x`` but for the dashes and the gauges, so the right
   half is painted and mirrored; the outlines are the subpixels within ``ss`` (4-neighbour steps) of a part's
   edge, for all outlined parts at once (one bit plane each); the gauges are stamped over the scene;
3. **colours**: a pixel whose subpixels share one label takes that label's colour from a table (two pixels a
   look-up), the others (the edges) average their subpixels' colours as the supersampling does, only in the rows
   of the scene and the gauges' boxes (the rest is the background, copied).

The frame maps ``w`` (the model's unit of length) to ``width * ss / max(2 chambers, 12)`` subpixels, with the
origin at ``(0.5 width, 0.4 height)``; the colours are :mod:`pneunet_env.envs.palette`'s.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from pneunet_env.envs import palette as C
from pneunet_env.envs.scene import BAND, BASE, BODY, DENT, RenderState, SceneGeometry, normal_offset, scene_parts

__all__ = ["Layout", "layout", "rasterise", "to_uint8"]

_TRACTION_LOG_RANGE = (-5.0, 0.0)  # log10(F~): 0.5 Pa to 50 kPa at mu = 50 kPa

# Labels of the (supersampled) label image: the scene's layers in paint order (each pixel keeps the
# topmost layer that covers it), then the gauges' colours (stamped over the scene, in their own order).
(
    _L_BACKGROUND, _L_OBJECT, _L_ZONE, _L_OBJECT_EDGE, _L_FILM, _L_DASH, _L_ELASTOMER, _L_CAVITY, _L_CAVITY_EDGE,
    _L_BASE, _L_OUTLINE, _L_GAUGE_BG, _L_PRESSURE, _L_TRACTION, _L_GREEN, _L_DAMAGED, _L_HOLD, _L_PROGRESS, _L_LAMP,
) = range(19)
_N_LABELS = 19

_PALETTE = np.zeros((_N_LABELS, 3), np.float32)  # the labels' colours that do not depend on the state
for _label, _colour in (
    (_L_BACKGROUND, C.BACKGROUND), (_L_OBJECT, C.OBJECT), (_L_FILM, C.DAMAGED), (_L_ELASTOMER, C.ELASTOMER),
    (_L_BASE, C.BASE), (_L_OUTLINE, C.OUTLINE), (_L_GAUGE_BG, C.GAUGE_BG), (_L_PRESSURE, C.PRESSURE),
    (_L_GREEN, C.GREEN), (_L_DAMAGED, C.DAMAGED), (_L_HOLD, C.HOLD), (_L_PROGRESS, C.PROGRESS), (_L_LAMP, C.GREY),
):
    _PALETTE[_label] = _colour
# the loaded zone when damaged (else it is tinted per pixel): painted at 0.85 over the object
_PALETTE[_L_ZONE] = (1.0 - 0.85) * _PALETTE[_L_OBJECT] + 0.85 * C.DAMAGED


class Layout:
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
        self.blank[...] = _uniform_colours(C.BACKGROUND.astype(np.float32)[None, :], ss)[0]

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
def layout(width: int, height: int, chambers: int, ss: int) -> Layout:
    return Layout(width, height, chambers, ss)

def _xy(lay: Layout, q, rows):
    """The points ``(X, Y)`` (units of ``w``) of half-columns ``q`` (right of the axis) in subpixel rows ``rows``."""
    return (lay.jc + q + 0.5 - 0.5 * lay.ws) / lay.px, lay.y[rows]


def _spans(parts, lay: Layout):
    """Half-columns ``lo, hi`` (arrays: part x row) of each part's points, ``xlo <= |x| < xhi``.

    ``parts``: :class:`pneunet_env.envs.scene.ScenePart` each. A column whose centre lies on a boundary (to
    rounding) is decided by the part's ``test`` at that point, the part's own definition, so that the picture does
    not depend on how the boundary was found.
    """
    v = np.array([x for xlo, xhi, _ in parts for x in (xlo, xhi)]) * lay.px - lay.off
    t = np.clip(np.ceil(v), 0, lay.nh).astype(lay.itype)
    c = np.rint(v)
    with np.errstate(invalid="ignore"):  # inf - inf
        near = (np.abs(v - c) < 1e-6) & (c >= 0) & (c < lay.nh)
    if near.any():
        for i in np.flatnonzero(near.any(axis=1)).tolist():
            rows = np.flatnonzero(near[i])
            cols = c[i, rows]
            inside = parts[i // 2].test(*_xy(lay, cols, rows))
            t[i, rows] = np.where(inside, cols, cols + 1) if i % 2 == 0 else np.where(inside, cols + 1, cols)
    return t[0::2], t[1::2]


def _safe_ratio(a, b) -> float:
    a, b = float(a), float(b)
    return a / b if b > 0.0 else 0.0


def _draw_scene(labels: np.ndarray, lay: Layout, state: RenderState, chambers: int):
    """Paint the object and the actuator (:func:`pneunet_env.envs.scene.scene_parts`) into ``labels``.

    Returns the rows painted (``(row0, row1)`` or ``None``) and the loaded zone's tint (or ``None``).
    """
    g = SceneGeometry(state, chambers)
    sp = scene_parts(g, lay.y, 0.6 / lay.px * lay.ss)
    parts, zone, film, dash, first_cell = sp.parts, sp.zone, sp.film, sp.dash, sp.first_cell
    lo, hi = _spans(parts, lay)
    width = np.maximum(hi - lo, 0).view(lay.utype)
    box = _boxes(lo, hi, lay)

    # ---- paint them (the right half, mirrored), each on its own box ----------------------------------
    scene = [box[i] for i in (BAND, BODY, film) if i is not None and box[i] is not None]
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
        if box[BAND] is not None:
            a, b, c, d = reg = region(BAND)
            bits[a - r0 : b - r0, c:d] = (mask(BAND, reg) & ~mask(DENT, reg)).view(np.uint8)
        if box[BODY] is not None:
            a, b, c, d = reg = region(BODY)
            planes = bits[a - r0 : b - r0, c:d]
            planes |= mask(BODY, reg).view(np.uint8) << 2
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
        if box[BODY] is not None:
            a, b, c, d = reg = region(BODY)
            sub = bits[a - r0 : b - r0, c:d]
            paint(reg, (sub >> 2).view(bool), _L_ELASTOMER)
            if box[BASE] is not None:
                rb = region(BASE)
                paint(rb, mask(BASE, rb), _L_BASE)
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


def _boxes(lo, hi, lay: Layout):
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


def _stamp(labels: np.ndarray, rect, label: int) -> None:
    a, b, c, d = rect
    labels[a:b, c:d] = label


def _draw_gauges(labels: np.ndarray, lay: Layout, state: RenderState) -> None:
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
    pal[_L_OBJECT_EDGE] = C.DAMAGED if state.damaged else C.OBJECT_EDGE
    pal[_L_DASH] = C.DAMAGED if state.crushed else C.OBJECT_EDGE
    pf = min(max(float(state.pressure_fraction), 0.0), 1.0)
    pal[_L_CAVITY] = C.CAVITY_LOW + pf * (C.CAVITY_HIGH - C.CAVITY_LOW)
    pal[_L_CAVITY_EDGE] = (1.0 - 0.6) * pal[_L_CAVITY] + 0.6 * C.OUTLINE
    F = float(state.contact_force)
    pal[_L_TRACTION] = C.DAMAGED if state.damaged else (C.GREEN if F >= float(state.grip_traction) else C.ORANGE)
    if state.damaged:
        pal[_L_LAMP] = C.DAMAGED
    elif state.dropped:
        pal[_L_LAMP] = C.ORANGE
    elif state.in_hold:
        pal[_L_LAMP] = C.GREEN
    return pal


def to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _tint_colours(tint, lay: Layout, xs, ys) -> np.ndarray:
    """The loaded zone's colour at points given in subpixel coordinates (float32, as painted)."""
    strength, kappa, hb, H = tint
    x = (xs - 0.5 * lay.ws) / lay.px
    y = (0.4 * lay.hs - ys) / lay.px
    n = normal_offset(kappa, x, y) if kappa > 1e-12 else y
    depth = np.clip((-0.5 * hb - n) / max(H, 1e-9), 0.0, 1.0)
    a = (strength * (1.0 - depth))[:, None]
    return ((1.0 - a) * C.OBJECT.astype(np.float32) + a * C.LOADED).astype(np.float32)


def _uniform_colours(pal: np.ndarray, s: int) -> np.ndarray:
    """The uint8 colour of a pixel whose ``s x s`` subpixels all have one label (summed as the supersampling sums)."""
    acc = np.zeros_like(pal)
    for _ in range(s * s):
        acc += pal
    return to_uint8(acc / (s * s))


_PAIRS = (np.arange(_N_LABELS)[:, None] + 256 * np.arange(_N_LABELS)[None, :]).ravel()


def _pair_colours(colours: np.ndarray) -> np.ndarray:
    """``(65536, 6)``: the colours of two pixels side by side, labels ``a, b`` at ``a + 256 b`` (the pair's
    two bytes read as one little-endian uint16); the entries of no pair of labels are left unset."""
    pairs = np.empty((65536, 6), np.uint8)
    pairs[_PAIRS, :3] = np.repeat(colours, _N_LABELS, axis=0)  # a, the left pixel
    pairs[_PAIRS, 3:] = np.tile(colours, (_N_LABELS, 1))  # b, the right one
    return pairs


def _resolve(img, labels, lay: Layout, pal, colours, pairs, tint, i0: int, i1: int, j0: int, j1: int) -> None:
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
            out[zi, zj] = to_uint8(c)
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
        img[i, j] = to_uint8(acc / (s * s))


def rasterise(state: RenderState, width: int, height: int, chambers: int, supersample: int) -> np.ndarray:
    """Draw one state (no text label) into a ``(height, width, 3)`` uint8 array; the sizes are checked by the
    caller (:func:`pneunet_env.envs.render.render_frame`)."""
    lay = layout(width, height, chambers, supersample)
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
    return img

