"""Slow, obviously correct references the kernels are tested against."""

from __future__ import annotations

import numpy as np


def brute_cone_ratios(h, tile_x=True, tile_y=True, max_ratio=1.0, rows=None, columns=None):
    """Cone ratios by checking every pair of texels (float64, O(N^2) memory per row).

    h: float64 (H, W) unit heights. rows, columns: the rows and columns to compute
    (default all); the others stay NaN.
    """
    h = np.asarray(h, dtype=np.float64)
    H, W = h.shape
    cols = np.arange(W)
    rws = np.arange(H)
    out = np.full(h.shape, np.nan)
    for r in range(H) if rows is None else rows:
        for c in range(W) if columns is None else columns:
            dx = np.abs(cols - c)
            dy = np.abs(rws - r)
            if tile_x:
                dx = np.minimum(dx, W - dx)
            if tile_y:
                dy = np.minimum(dy, H - dy)
            d = np.sqrt((dx[None, :] / W) ** 2 + (dy[:, None] / H) ** 2)
            dh = h - h[r, c]
            higher = dh > 0
            with np.errstate(over="ignore"):  # a subnormal rise: the ratio is inf, capped below
                best = (d[higher] / dh[higher]).min() if higher.any() else max_ratio
            out[r, c] = min(best, max_ratio)
    return out


def brute_quadrant_ratios(h, tile_x=True, tile_y=True, max_ratio=1.0):
    """Per-quadrant cone ratios ``(4, H, W)`` by checking every texel of every quadrant.

    Quadrant k has signs ``(su, sv)`` = (+,+), (-,+), (-,-), (+,-) (u along columns, v
    along rows). From texel p the ray going ``su`` reaches column offsets
    ``su * (col(q) - col(p))``: on a tiled axis taken modulo the axis (the ray wraps), on
    another only those >= 0 (q on that side, the axis itself included). Same for rows.
    """
    h = np.asarray(h, dtype=np.float64)
    H, W = h.shape
    out = np.full((4, H, W), np.nan)
    signs = ((1, 1), (-1, 1), (-1, -1), (1, -1))
    for r in range(H):
        for c in range(W):
            for k, (su, sv) in enumerate(signs):
                dx = su * (np.arange(W) - c)
                dy = sv * (np.arange(H) - r)
                if tile_x:
                    dx = dx % W
                if tile_y:
                    dy = dy % H
                reach = (dy[:, None] >= 0) & (dx[None, :] >= 0)
                d = np.sqrt((dx[None, :] / W) ** 2 + (dy[:, None] / H) ** 2)
                dh = h - h[r, c]
                ok = reach & (dh > 0)
                with np.errstate(over="ignore"):
                    best = (d[ok] / dh[ok]).min() if ok.any() else max_ratio
                out[k, r, c] = min(best, max_ratio)
    return out
