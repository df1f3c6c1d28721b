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
