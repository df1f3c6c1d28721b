"""Exact cone ratios by searching outward in square rings, as the paper does.

Unlike the paper's preprocessor the search covers the true torus (no clamped
corners) and stops only when no farther ring can give a narrower cone: ring k is
at least k texels away on one axis, so it cannot beat ``best`` once
``k * min(1/W, 1/H) >= best * (hmax - h(p))``. Quick for narrow cones; for a texel
with a wide cone it visits O(N^2) texels (O(N^4) for a map of wide cones).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels import CACHE
from ..polling import row_chunk, run_chunks
from .pyramid import SLACK


@njit(cache=CACHE)
def _span(i, n, tile):
    """Offsets lo..hi that reach every texel of an axis of n once from texel i."""
    if tile:
        return -((n - 1) // 2), n // 2
    return -i, n - 1 - i


@njit(cache=CACHE, inline="always", error_model="numpy")
def _scan_row(h, rr, c, xa, xb, W, dyterm, hp, best, H2):
    """Lower ``best`` by texels (rr, c + dx mod W), dx in xa..xb (|dx| < W)."""
    dx = xa
    while dx <= xb:
        cc = c + dx
        if cc < 0:
            shift, end = W, min(xb, -c - 1)
        elif cc >= W:
            shift, end = -W, xb
        else:
            shift, end = 0, min(xb, W - 1 - c)
        for d in range(dx, end + 1):
            dh = h[rr, c + d + shift] - hp
            dh2 = dh * dh if dh > 0.0 else 0.0  # branch free: x / 0 is inf (numpy errors)
            best = min(best, (d * d * H2 + dyterm) / dh2)
        dx = end + 1
    return best


@njit(cache=CACHE, inline="always", error_model="numpy")
def _scan_col(h, cc, r, ya, yb, H, dxterm, hp, best, W2):
    """Lower ``best`` by texels (r + dy mod H, cc), dy in ya..yb (|dy| < H)."""
    dy = ya
    while dy <= yb:
        rr = r + dy
        if rr < 0:
            shift, end = H, min(yb, -r - 1)
        elif rr >= H:
            shift, end = -H, yb
        else:
            shift, end = 0, min(yb, H - 1 - r)
        for d in range(dy, end + 1):
            dh = h[r + d + shift, cc] - hp
            dh2 = dh * dh if dh > 0.0 else 0.0
            best = min(best, (d * d * W2 + dxterm) / dh2)
        dy = end + 1
    return best


@njit(cache=CACHE, inline="always", error_model="numpy")
def _ring_texel(h, r, c, hmax, tile_x, tile_y, max_ratio, kcap):
    """(exact ratio of texel (r, c), rings searched); gives up after ``kcap`` rings
    (then the ratio is NaN).

    Works in ``dist = dx^2 H^2 + dy^2 W^2`` (exact integers in float64) and
    ``best = ratio^2 (W H)^2``.
    """
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    wh = float(W) * H
    mn2 = float(min(H, W)) ** 2  # ring k is >= k texels away on one axis: dist >= k^2 mn2
    hp = h[r, c]
    ceiling = hmax - hp
    if ceiling <= 0.0:
        return max_ratio, 0
    ylo, yhi = _span(r, H, tile_y)
    xlo, xhi = _span(c, W, tile_x)
    kmax = max(max(-xlo, xhi), max(-ylo, yhi))
    ceil2 = ceiling * ceiling
    best = (max_ratio * wh) ** 2
    for k in range(1, kmax + 1):
        if k * k * mn2 >= best * ceil2 * SLACK:
            return min(math.sqrt(best) / wh, max_ratio), k - 1
        if k > kcap:
            return np.nan, k - 1
        xa, xb = max(-k, xlo), min(k, xhi)
        if -k >= ylo:
            best = _scan_row(h, r - k + (H if r - k < 0 else 0), c, xa, xb, W,
                             k * k * W2, hp, best, H2)
        if k <= yhi:
            best = _scan_row(h, r + k - (H if r + k >= H else 0), c, xa, xb, W,
                             k * k * W2, hp, best, H2)
        ya, yb = max(-k + 1, ylo), min(k - 1, yhi)
        if -k >= xlo:
            best = _scan_col(h, c - k + (W if c - k < 0 else 0), r, ya, yb, H,
                             k * k * H2, hp, best, W2)
        if k <= xhi:
            best = _scan_col(h, c + k - (W if c + k >= W else 0), r, ya, yb, H,
                             k * k * H2, hp, best, W2)
    return min(math.sqrt(best) / wh, max_ratio), kmax


@njit(cache=CACHE, nogil=True, error_model="numpy")
def ring_texels(h, hmax, tile_x, tile_y, max_ratio, start, stop, rows, cols, kcap, out, rings,
                done):
    """Exact ratios by the ring search, one kernel for a whole map and for samples.

    Whole map (``rows`` empty): texels ``start..stop`` in row-major order into the flat
    ``out`` (H*W), ``done[r] = 1`` after the last texel of row r. Samples: texels
    ``(rows[i], cols[i])`` for i in ``start..stop`` into ``out[i]``, rings searched
    into ``rings[i]``. False as soon as a texel needs more than ``kcap`` rings (the
    rest are then not filled).
    """
    W = h.shape[1]
    for i in range(start, stop):
        if rows.size:
            r, c = np.int64(rows[i]), np.int64(cols[i])
        else:
            r, c = i // W, i % W
        ratio, k = _ring_texel(h, r, c, hmax, tile_x, tile_y, max_ratio, kcap)
        if np.isnan(ratio):
            return False
        out[i] = ratio
        if rings.size:
            rings[i] = k
        if done.size and c == W - 1:
            done[r] = 1
    return True


_NONE = np.zeros(0, np.int64)


def ring_ratios(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                progress=None, rows=None) -> np.ndarray:
    """Float64 ``(H, W)`` exact cone ratios of float64 unit heights ``h`` (C order).

    ``progress(done_rows, total_rows)`` is called now and then from this thread. rows:
    ``(r0, r1)`` to search those rows only, returned as ``(r1 - r0, W)`` (the same values).
    """
    H, W = h.shape
    r0, r1 = rows or (0, H)
    out = np.empty(h.size)  # only rows r0..r1 are written (and take memory)
    marks = np.zeros(H, np.uint8)  # the kernel marks rows by their index in the map
    hmax = float(h.max())
    kcap = max(H, W)
    run_chunks(lambda a, b: ring_texels(h, hmax, tile_x, tile_y, max_ratio, (r0 + a) * W, (r0 + b) * W,
                                        _NONE, _NONE, kcap, out, _NONE, marks),
               r1 - r0, marks[r0:r1], progress, chunk=row_chunk(r1 - r0))
    return out[r0 * W:r1 * W].reshape(r1 - r0, W)
