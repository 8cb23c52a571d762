"""16-bit grey or RGB PNG (the bark's crack map, :mod:`wooddecay.export.bark_texture`), written atomically.

A PNG is a signature, an IHDR chunk (width, height, bit depth 16, colour type 0 = grey or 2 =
RGB), IDAT (the zlib-compressed rows, each prefixed by filter type 0, samples big-endian) and
IEND, each chunk with its CRC-32.
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

from ..atomic import write_bytes


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png16(image: np.ndarray) -> bytes:
    """The PNG bytes of an (H, W) grey or (H, W, 3) RGB uint16 image."""
    h, w = image.shape[:2]
    channels = 1 if image.ndim == 2 else 3
    rows = np.ascontiguousarray(image.astype(">u2")).view(np.uint8).reshape(h, w * 2 * channels)
    raw = np.concatenate([np.zeros((h, 1), dtype=np.uint8), rows], axis=1).tobytes()
    colour = 0 if channels == 1 else 2
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, colour, 0, 0, 0))
            + _chunk(b"IDAT", zlib.compress(raw, 6)) + _chunk(b"IEND", b""))


def write_png16(path, image: np.ndarray, what: str = "image"):
    """Write ``image`` ((H, W) or (H, W, 3) uint16) to ``path`` atomically."""
    return write_bytes(path, png16(image), what)
