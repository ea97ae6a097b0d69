"""8-bit RGB PNG files with zlib alone: :func:`save_png` writes one (atomically), :func:`read_png` reads one back."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from pneunet_env.files import atomic_write_bytes

__all__ = ["save_png", "read_png"]


def _chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an ``HxWx3`` uint8 array as an 8-bit RGB PNG (zlib only); returns the path.

    Written atomically (:func:`pneunet_env.files.atomic_write_bytes`): a reader never sees half a file."""
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
    return atomic_write_bytes(path, png)


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
