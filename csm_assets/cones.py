"""Exact cone ratios (DESIGN.md's definition) of a heightfield.

The cone ratio of texel p is ``min |q - p|_uv / (h(q) - h(p))`` over the texels q
strictly higher than p, with ``|.|_uv`` counting 1/W per column and 1/H per row (on
the torus when tiling), capped at ``max_ratio``. The kernel searches outward in
square rings of texels, as the paper's preprocessor does, but over the true torus
(no clamped corners) and stops only when no farther ring can give a narrower cone.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numba import njit, prange

from .heightfield import check_max_ratio, tile_pair, unit_heights

ProgressFn = Callable[[int, int], None]

_BAND_ROWS = 64


@njit(cache=True, inline="always")
def _wrap(i, n):
    if i < 0:
        return i + n
    if i >= n:
        return i - n
    return i


@njit(cache=True, parallel=True)
def _ring_search_rows(h, hmax, tile_x, tile_y, max_ratio, r0, r1, out):
    """Exact ratios of rows ``r0 .. r1-1`` of ``h`` (float64 (H, W)) into ``out``."""
    H, W = h.shape
    iw2 = 1.0 / (W * W)
    ih2 = 1.0 / (H * H)
    step = min(1.0 / W, 1.0 / H)
    for r in prange(r0, r1):
        if tile_y:
            ylo, yhi = -((H - 1) // 2), H // 2
        else:
            ylo, yhi = -r, H - 1 - r
        for c in range(W):
            hp = h[r, c]
            ceiling = hmax - hp
            if ceiling <= 0.0:
                out[r, c] = max_ratio
                continue
            if tile_x:
                xlo, xhi = -((W - 1) // 2), W // 2
            else:
                xlo, xhi = -c, W - 1 - c
            kmax = max(max(-xlo, xhi), max(-ylo, yhi))
            best2 = max_ratio * max_ratio
            for k in range(1, kmax + 1):
                # Every texel of ring k is at least k texels away on one axis.
                if k * step >= math.sqrt(best2) * ceiling:
                    break
                for dy in range(max(-k, ylo), min(k, yhi) + 1):
                    rr = _wrap(r + dy, H)
                    edge_row = dy == -k or dy == k
                    dx = max(-k, xlo)
                    dx_end = min(k, xhi)
                    while dx <= dx_end:
                        cc = _wrap(c + dx, W)
                        dh = h[rr, cc] - hp
                        if dh > 0.0:
                            d2 = dx * dx * iw2 + dy * dy * ih2
                            if d2 < best2 * dh * dh:
                                best2 = d2 / (dh * dh)
                        if edge_row or dx == k:
                            dx += 1
                        else:
                            dx = k  # inner rows of the ring: only the two side columns
            out[r, c] = math.sqrt(best2)


def exact_ratios(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                 progress: ProgressFn | None = None) -> np.ndarray:
    """Float64 ``(H, W)`` exact cone ratios of validated unit heights ``h`` (float64).

    ``progress(done_rows, total_rows)`` is called after each band of rows.
    """
    h = np.ascontiguousarray(h, dtype=np.float64)
    H = h.shape[0]
    out = np.empty_like(h)
    hmax = float(h.max())
    for r0 in range(0, H, _BAND_ROWS):
        r1 = min(H, r0 + _BAND_ROWS)
        _ring_search_rows(h, hmax, tile_x, tile_y, max_ratio, r0, r1, out)
        if progress is not None:
            progress(r1, H)
    return out


def cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact cone ratio of every texel.

    height: uint8 (/255), uint16 (/65535) or float ``(H, W)`` in ``[0, 1]``, any size
        from 1x1. A :class:`~csm_assets.Heightfield` is taken by its ``.data``.
    tile: True (the default: textures repeat), False, or a pair ``(tile_x, tile_y)``;
        a tiled axis measures distance the shortest way round.
    max_ratio: the cap (> 0); texels with no higher texel get it.

    Returns float32 ``(H, W)``, each value rounded down from the float64 ratio so a
    stored cone is never wider than the exact one. Raises ValueError on bad input.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(exact_ratios(h, tx, ty, cap))


def round_down_f32(x: np.ndarray) -> np.ndarray:
    """Cast float64 ``x`` (>= 0) to float32 without ever rounding up."""
    y = x.astype(np.float32)
    up = y.astype(np.float64) > x
    y[up] = np.nextafter(y[up], np.float32(0))
    return y
