"""PNG's row filters (the PNG specification, section 9), one chosen for each row as libpng
chooses by default: the filter whose bytes, read as signed, have the least sum of magnitudes.

A pure kernel over bytes: no paths, no zlib (:mod:`.png_write` compresses what it gives).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels import CACHE

NONE, SUB, UP, AVERAGE, PAETH = range(5)  # the filter-type byte that starts each filtered row


@njit(cache=CACHE, nogil=True)
def filter_rows(raw, above, bpp, out):
    """Filter rows of an image's bytes for PNG.

    Args:
        raw: ``(rows, n)`` uint8, each row's bytes as PNG stores them (samples big-endian).
        above: ``(n,)`` uint8, the row before ``raw[0]`` (zeros for an image's first row).
        bpp: bytes a pixel (1 to 8), the distance the Sub, Average and Paeth filters look back.
        out: ``(rows, n + 1)`` uint8, written: each row's filter type, then its filtered bytes.
    """
    rows, n = raw.shape
    sums = np.zeros(5, np.int64)
    for y in range(rows):
        r = raw[y]
        up = above if y == 0 else raw[y - 1]
        sums[:] = 0
        for i in range(n):  # every filter's sum of |signed byte|, in one pass
            x = np.int32(r[i])
            b = np.int32(up[i])
            a = np.int32(r[i - bpp]) if i >= bpp else np.int32(0)
            c = np.int32(up[i - bpp]) if i >= bpp else np.int32(0)
            sums[0] += _magnitude(x)
            sums[1] += _magnitude(x - a)
            sums[2] += _magnitude(x - b)
            sums[3] += _magnitude(x - ((a + b) >> 1))
            sums[4] += _magnitude(x - _paeth(a, b, c))
        kind = np.argmin(sums)  # the first of equal sums: None before the others
        out[y, 0] = kind
        for i in range(n):
            x = np.int32(r[i])
            b = np.int32(up[i])
            a = np.int32(r[i - bpp]) if i >= bpp else np.int32(0)
            c = np.int32(up[i - bpp]) if i >= bpp else np.int32(0)
            if kind == SUB:
                x -= a
            elif kind == UP:
                x -= b
            elif kind == AVERAGE:
                x -= (a + b) >> 1
            elif kind == PAETH:
                x -= _paeth(a, b, c)
            out[y, i + 1] = x & 255


@njit(cache=CACHE, nogil=True, inline="always")
def _magnitude(v):
    """|v| of the byte ``v mod 256`` read as signed (0 to 128)."""
    v &= 255
    return v if v < 128 else 256 - v


@njit(cache=CACHE, nogil=True, inline="always")
def _paeth(a, b, c):
    """The Paeth predictor of left ``a``, above ``b`` and upper left ``c``."""
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c
