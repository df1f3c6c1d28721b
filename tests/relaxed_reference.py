"""A slow, obviously correct relaxed cone ratio straight from README's definition."""

from __future__ import annotations

import math

import numpy as np


def _at(h, row, col, tile_x, tile_y):
    """Height at texel (row, col), wrapped on a tiled axis, clamped on the others."""
    H, W = h.shape
    row = row % H if tile_y else min(max(row, 0), H - 1)
    col = col % W if tile_x else min(max(col, 0), W - 1)
    return h[row, col]


def cell_falls(h, row, col, sx, sy, tile_x, tile_y):
    """Does the bilinear cell from texel (row, col) towards (sx, sy) fall anywhere going away?"""
    a = _at(h, row, col, tile_x, tile_y)
    b = _at(h, row, col + sx, tile_x, tile_y)
    c = _at(h, row + sy, col, tile_x, tile_y)
    d = _at(h, row + sy, col + sx, tile_x, tile_y)
    return a > b or a > c or b > d or c > d


def _sides(d):
    return (1,) if d > 0 else (-1,) if d < 0 else (-1, 1)


def relaxed_reference(h, tile_x=True, tile_y=True, max_ratio=1.0):
    """Float64 (H, W) relaxed ratios of float64 unit heights h, by brute force over every
    texel q of the unrolled surface within reach (all images on a tiled axis)."""
    H, W = h.shape
    out = np.full((H, W), float(max_ratio))
    # a cone never reaches farther than max_ratio in uv (heights differ by at most 1)
    ry = int(math.ceil(max_ratio * H)) + 1 if tile_y else H
    rx = int(math.ceil(max_ratio * W)) + 1 if tile_x else W
    for r in range(H):
        for c in range(W):
            best = float(max_ratio)
            rows = range(r - ry, r + ry + 1) if tile_y else range(H)
            cols = range(c - rx, c + rx + 1) if tile_x else range(W)
            for qr in rows:
                for qc in cols:
                    dy, dx = qr - r, qc - c
                    if dy == 0 and dx == 0:
                        continue
                    dh = _at(h, qr, qc, tile_x, tile_y) - h[r, c]
                    if dh <= 0:
                        continue
                    if not any(cell_falls(h, qr, qc, sx, sy, tile_x, tile_y)
                               for sx in _sides(dx) for sy in _sides(dy)):
                        continue
                    dist = math.hypot(dx / W, dy / H)
                    best = min(best, dist / float(dh) if dh > 1e-300 else math.inf)
            out[r, c] = best
    return out
