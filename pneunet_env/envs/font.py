"""A 5 x 8 bitmap font for the frames' labels and the contact sheet's legend (numpy only: no PIL, no matplotlib).

:func:`text_mask` gives a line's pixels; :func:`draw_text` writes lines into an ``HxWx3`` uint8 image, clipped to
it, optionally ringed by a halo colour so that they read over a busy picture.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["FONT_WIDTH", "FONT_HEIGHT", "text_mask", "draw_text"]

_PIXEL = np.dtype((np.void, 3))

# The printable ASCII characters (32 to 126, in order), 5 x 8 pixels each: a 5 x 7 cell above the baseline (capitals
# and digits fill it) and one row of descent (g j p q y _). Each glyph is 40 bits, row by row from the top, the
# leftmost pixel the highest bit of its row of 5.
_FONT_BITS = (
    0x0000000000, 0x2108420080, 0x5294000000, 0x52BEAFA940, 0x23E8E2F880, 0xC644444C60, 0x64A88AC9A0,  #  !"#$%&
    0x2110000000, 0x1110841040, 0x4104211100, 0x012AEA9000, 0x0109F21000, 0x0000003088, 0x0000E00000,  # '()*+,-
    0x0000003180, 0x0044444000, 0x74675CC5C0, 0x23084211C0, 0x74422223E0, 0xF88820C5C0, 0x11952F8840,  # ./01234
    0xFC3C10C5C0, 0x3221E8C5C0, 0xF844442100, 0x7462E8C5C0, 0x7462F08980, 0x0318063000, 0x0318061100,  # 56789:;
    0x1111041040, 0x003E0F8000, 0x4104111100, 0x7442220080, 0x7442DAD5C0, 0x7463F8C620, 0xF463E8C7C0,  # <=>?@AB
    0x74610845C0, 0xE4A318CB80, 0xFC21E843E0, 0xFC21E84200, 0x746178C5E0, 0x8C63F8C620, 0x71084211C0,  # CDEFGHI
    0x3884214980, 0x8CA98A4A20, 0x84210843E0, 0x8EEB58C620, 0x8C7359C620, 0x746318C5C0, 0xF463E84200,  # JKLMNOP
    0x74631AC9A0, 0xF463EA4A20, 0x7C20E087C0, 0xF908421080, 0x8C6318C5C0, 0x8C6318A880, 0x8C635AD540,  # QRSTUVW
    0x8C54454620, 0x8C62A21080, 0xF8444443E0, 0x72108421C0, 0x0410410400, 0x70842109C0, 0x22A2000000,  # XYZ[\]^
    0x000000001F, 0x4104000000, 0x001C17C5E0, 0x842D98C7C0, 0x001D0845C0, 0x085B38C5E0, 0x001D1FC1C0,  # _`abcde
    0x3251C42100, 0x001F18BC2E, 0x842D98C620, 0x20184211C0, 0x100C210A4C, 0x84254C5240, 0x61084211C0,  # fghijkl
    0x00355AD6A0, 0x002D98C620, 0x001D18C5C0, 0x003D18FA10, 0x001F18BC21, 0x002D984200, 0x001D0707C0,  # mnopqrs
    0x42388424C0, 0x002318CDA0, 0x002318A880, 0x00231AD540, 0x0022A22A20, 0x002318BC2E, 0x003E2223E0,  # tuvwxyz
    0x1108821040, 0x2108421080, 0x4108221100, 0x0011510000,  # {|}~
)
FONT_WIDTH, FONT_HEIGHT = 5, 8
"""A glyph's pixels (at scale 1); characters are set ``FONT_WIDTH + 1`` apart, lines ``FONT_HEIGHT + 2`` apart."""
_FONT = (  # (95, 8, 6): each glyph with the blank column that follows it
    np.pad(((np.array(_FONT_BITS, np.int64)[:, None] >> np.arange(39, -1, -1)) & 1).astype(bool).reshape(95, 8, 5),
           ((0, 0), (0, 0), (0, 1)))
)
_FONT.flags.writeable = False


def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """The pixels of one line of ``text`` in the bitmap font: a boolean ``(8 s, (6 n - 1) s)`` array.

    ``n`` characters at integer scale ``s``; a character outside printable ASCII is drawn as ``?``.
    """
    return _text_mask(str(text), int(scale))


@functools.lru_cache(maxsize=512)
def _text_mask(text: str, scale: int) -> np.ndarray:
    if scale < 1:
        raise ValueError(f"text scale must be >= 1, got {scale}")
    if not text:
        return np.zeros((FONT_HEIGHT * scale, 0), bool)
    codes = np.frombuffer(text.encode("ascii", "replace"), np.uint8).astype(np.intp) - 32
    codes[(codes < 0) | (codes >= len(_FONT))] = ord("?") - 32
    m = _FONT[codes].transpose(1, 0, 2).reshape(FONT_HEIGHT, -1)[:, :-1]
    if scale > 1:
        m = np.repeat(np.repeat(m, scale, axis=0), scale, axis=1)
    m.flags.writeable = False
    return m


def draw_text(img: np.ndarray, lines, x: int, y: int, scale: int, halo=None) -> None:
    """Write ``lines`` (``(text, colour)`` each) into ``img`` (``HxWx3`` uint8, C-contiguous) from its pixel
    ``(x, y)`` (the top left corner), one under the other, clipped to the image. ``halo``: an RGB colour (uint8)
    that rings each glyph with a pixel, so that the text reads over a busy picture too (the lines are far enough apart
    that a line's ring never touches another's glyphs)."""
    h, w = img.shape[:2]
    if not img.flags.c_contiguous:
        raise ValueError("draw_text needs a C-contiguous image")
    ring_colour = None if halo is None else np.asarray(halo, np.uint8).view(_PIXEL)
    pixels = img.view(_PIXEL).reshape(-1)  # one 3-byte item per pixel: a pixel is set by one indexed store
    pitch = (FONT_HEIGHT + 2) * scale
    drawn = []
    for i, (text, colour) in enumerate(lines):
        y0 = y + i * pitch
        glyphs, ring, (r0, r1, c0, c1) = _line_pixels(str(text), int(scale), w)
        if y0 + r0 >= 0 and y0 + r1 < h and x + c0 >= 0 and x + c1 < w:  # inside: the offsets hold
            base = y0 * w + x
            if ring_colour is not None:
                pixels[ring + base] = ring_colour
            drawn.append((glyphs + base, colour))
        else:  # clipped: by rows and columns
            glyph_rc, ring_rc, _ = _line_rows_columns(str(text), int(scale))
            parts = ((ring_rc, ring_colour), (glyph_rc, colour)) if ring_colour is not None else ((glyph_rc, colour),)
            for (ys, xs), c in parts:
                ys, xs = ys + y0, xs + x
                keep = (ys >= 0) & (ys < h) & (xs >= 0) & (xs < w)
                if c is ring_colour:
                    pixels[ys[keep] * w + xs[keep]] = c
                else:
                    drawn.append((ys[keep] * w + xs[keep], c))
    for idx, colour in drawn:  # the glyphs after every ring
        pixels[idx] = np.asarray(colour, np.uint8).view(_PIXEL)




@functools.lru_cache(maxsize=16)
def _glyph_table(scale: int):
    """Each glyph's pixels and the 1-pixel ring (8 neighbours) around them at ``scale``, as rows and columns from
    its top left corner (the ring reaches row and column -1): ``(rows, columns, counts)`` for the glyphs and for
    the rings, the rows and columns a list over the glyphs, the counts an array."""
    table = []
    for code in range(len(_FONT)):
        on = np.pad(_text_mask(chr(code + 32), scale), 1)
        grown = on.copy()
        grown[1:] |= on[:-1]
        grown[:-1] |= on[1:]
        ring = grown.copy()
        ring[:, 1:] |= grown[:, :-1]
        ring[:, :-1] |= grown[:, 1:]
        ring &= ~on
        table.append([v - 1 for m in (on, ring) for v in np.nonzero(m)])
    return tuple(
        ([t[j] for t in table], [t[j + 1] for t in table], np.array([len(t[j]) for t in table])) for j in (0, 2)
    )


@functools.lru_cache(maxsize=1024)
def _line_rows_columns(text: str, scale: int):
    """One line's glyph pixels and the ring around them, as ``(rows, columns)`` from the line's top left corner (the
    glyphs' own, side by side: glyphs are at least a pixel apart, so that a glyph's ring never falls on the next
    glyph), and their bounds ``(row0, row1, col0, col1)`` (inclusive)."""
    codes = np.frombuffer(text.encode("ascii", "replace"), np.uint8).astype(np.intp) - 32
    codes[(codes < 0) | (codes >= len(_FONT))] = ord("?") - 32
    step = (FONT_WIDTH + 1) * scale
    out = []
    for rows, cols, counts in _glyph_table(scale):
        if not len(codes):
            ys = xs = np.zeros(0, np.intp)
        else:
            ys = np.concatenate([rows[c] for c in codes.tolist()])
            xs = np.concatenate([cols[c] for c in codes.tolist()])
            xs += np.repeat(np.arange(len(codes)) * step, counts[codes])
        ys.flags.writeable = xs.flags.writeable = False
        out.append((ys, xs))
    return out[0], out[1], (-1, FONT_HEIGHT * scale, -1, max(len(codes) * step - scale, 0))


@functools.lru_cache(maxsize=1024)
def _line_pixels(text: str, scale: int, width: int):
    """:func:`_line_rows_columns` as offsets ``row * width + column`` in an image ``width`` pixels wide (valid
    where the line lies inside the image), and the bounds."""
    glyphs, ring, bounds = _line_rows_columns(text, scale)
    out = []
    for ys, xs in (glyphs, ring):
        offsets = ys * width + xs
        offsets.flags.writeable = False
        out.append(offsets)
    return out[0], out[1], bounds
