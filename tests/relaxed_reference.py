"""Slow, obviously correct relaxed cone ratios straight from the definition in docs/reference/conventions.md.

:func:`relaxed_reference` is the definition of the library (the falling-direction rule,
cells split into sub-cells): every cell of the unrolled surface is visited on its own
(not through the texels of the library's search), split into ``split`` x ``split``
sub-cells, and each sub-cell is tested for a fall along a direction from p by sampling
its directional derivative at its corners. :func:`cell_falls` is the falling-edge test of
Bundas et al. 2024 (the library's pre-filter); :func:`continuous_upper` an upper bound of
the true continuous relaxed ratio (sampled points where the surface falls along the ray
from p, where a ray could leave it), which no safe cone may exceed.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from reference import brute_cone_ratios


def _at(h, row, col, tile_x, tile_y):
    """Height at texel (row, col), wrapped on a tiled axis, clamped on the others."""
    H, W = h.shape
    row = row % H if tile_y else min(max(row, 0), H - 1)
    col = col % W if tile_x else min(max(col, 0), W - 1)
    return float(h[row, col])


def _lerp2(z, u, v):
    """Bilinear surface of corner heights z = (z00, z10, z01, z11) at (u, v) in [0, 1]^2
    (exact for Fractions)."""
    return (z[0] * (1 - u) + z[1] * u) * (1 - v) + (z[2] * (1 - u) + z[3] * u) * v


def _cells(h, r, c, tile_x, tile_y, reach_y, reach_x):
    """Every cell [x0, x0+1] x [y0, y0+1] (texel units relative to p = (c, r)) with its
    corner heights. A tiled axis: every cell of the unrolled surface within reach; an axis
    that does not tile: the cells between texel centres plus one clamped (flat) cell
    beyond each edge, the margin the GPU samples there."""
    H, W = h.shape
    ys = range(r - reach_y, r + reach_y) if tile_y else range(-1, H)
    xs = range(c - reach_x, c + reach_x) if tile_x else range(-1, W)
    for j in ys:
        for i in xs:
            z = (_at(h, j, i, tile_x, tile_y), _at(h, j, i + 1, tile_x, tile_y),
                 _at(h, j + 1, i, tile_x, tile_y), _at(h, j + 1, i + 1, tile_x, tile_y))
            yield i - c, j - r, z


def _near(a, b):
    return min(max(0.0, a), b)


def _falls(z, u0, u1, v0, v1, xa, xb, ya, yb):
    """Is (gradient at a corner, from the two sub-cell edges there) . (corner - p) negative
    at one of the four corners of the sub-cell [u0, u1] x [v0, v1] of the cell with corner
    heights z (floats: evaluated in float64; Fractions: exactly)?"""
    a, b = _lerp2(z, u0, v0), _lerp2(z, u1, v0)
    cc, d = _lerp2(z, u0, v1), _lerp2(z, u1, v1)
    slopes = [((b - a), (cc - a), xa, ya), ((b - a), (d - b), xb, ya),
              ((d - cc), (cc - a), xa, yb), ((d - cc), (d - b), xb, yb)]
    return any(gx * x + gy * y < 0 for gx, gy, x, y in slopes)


def relaxed_bound(h, tile_x, tile_y, max_ratio, split, r, c, levels=0):
    """min over limiting sub-cells of (nearest distance, uv) / (highest corner - h(p)).
    levels (255, 65535): h holds codes / levels, and the falling test is exact, on the
    codes as fractions; 0: the test in float64."""
    H, W = h.shape
    hp = float(h[r, c])
    best = float(max_ratio)
    reach_y = int(math.ceil(max_ratio * H)) + 2
    reach_x = int(math.ceil(max_ratio * W)) + 2
    for x0, y0, z in _cells(h, r, c, tile_x, tile_y, reach_y, reach_x):
        zq = tuple(Fraction(round(v * levels), levels) for v in z) if levels else z
        for j in range(split):
            for i in range(split):
                u0, u1, v0, v1 = i / split, (i + 1) / split, j / split, (j + 1) / split
                a, b = _lerp2(z, u0, v0), _lerp2(z, u1, v0)
                cc, d = _lerp2(z, u0, v1), _lerp2(z, u1, v1)
                top = max(a, b, cc, d)
                if top <= hp:
                    continue
                xa, xb, ya, yb = x0 + u0, x0 + u1, y0 + v0, y0 + v1
                if levels:
                    fu = [Fraction(k, split) for k in (i, i + 1, j, j + 1)]
                    if not _falls(zq, *fu, x0 + fu[0], x0 + fu[1], y0 + fu[2], y0 + fu[3]):
                        continue
                elif not _falls(z, u0, u1, v0, v1, xa, xb, ya, yb):
                    continue
                dist = math.hypot(_near(xa, xb) / W, _near(ya, yb) / H)
                best = min(best, dist / (top - hp))
    return best


def relaxed_reference(h, tile_x=True, tile_y=True, max_ratio=1.0, split=2, levels=0):
    """Float64 (H, W) relaxed ratios of float64 unit heights h: the larger of the
    conservative cone and the falling-direction bound, at most max_ratio. levels: see
    :func:`relaxed_bound` (the library's for uint8 / uint16 input)."""
    h = np.asarray(h, np.float64)
    cons = brute_cone_ratios(h, tile_x, tile_y, max_ratio)
    out = np.empty(h.shape)
    for r in range(h.shape[0]):
        for c in range(h.shape[1]):
            out[r, c] = max(cons[r, c], relaxed_bound(h, tile_x, tile_y, max_ratio, split, r, c, levels))
    return out


def cell_falls(h, row, col, sx, sy, tile_x, tile_y):
    """The falling-edge rule: does the cell from texel (row, col) towards (sx, sy) have an
    edge that falls going away from it?"""
    a = _at(h, row, col, tile_x, tile_y)
    b = _at(h, row, col + sx, tile_x, tile_y)
    c = _at(h, row + sy, col, tile_x, tile_y)
    d = _at(h, row + sy, col + sx, tile_x, tile_y)
    return a > b or a > c or b > d or c > d


def continuous_upper(h, tile_x=True, tile_y=True, max_ratio=1.0, samples=8, eps=1e-12):
    """An upper bound of the continuous relaxed ratio at each texel centre: the minimum of
    |e - p|_uv / (h(e) - h(p)) over points e sampled on a (samples+1)^2 grid per cell where
    the bilinear surface falls along e - p (a ray from above p could leave it there) by
    more than ``eps`` (exact ties, such as 8-bit slopes whose products cancel, round
    either way)."""
    h = np.asarray(h, np.float64)
    H, W = h.shape
    out = np.full(h.shape, float(max_ratio))
    g = np.linspace(0.0, 1.0, samples + 1)
    u, v = np.meshgrid(g, g)
    reach = (int(math.ceil(max_ratio * H)) + 2, int(math.ceil(max_ratio * W)) + 2)
    for r in range(H):
        for c in range(W):
            hp = h[r, c]
            for x0, y0, z in _cells(h, r, c, tile_x, tile_y, *reach):
                he = _lerp2(z, u, v)
                gx = (z[1] - z[0]) * (1 - v) + (z[3] - z[2]) * v
                gy = (z[2] - z[0]) * (1 - u) + (z[3] - z[1]) * u
                ex, ey = x0 + u, y0 + v
                ok = (he > hp) & (gx * ex + gy * ey < -eps)
                if ok.any():
                    q = np.hypot(ex[ok] / W, ey[ok] / H) / (he[ok] - hp)
                    out[r, c] = min(out[r, c], q.min())
    return out
