"""Slow, obviously correct relaxed cone ratios straight from the definition in docs/reference/conventions.md.

:func:`relaxed_reference` is the definition of the library (the falling-direction rule,
cells split into sub-cells): every cell of the unrolled surface is visited on its own
(not through the texels of the library's search), split into ``split`` x ``split``
sub-cells, and each sub-cell is tested for a fall along a direction from p by sampling
its directional derivative at its corners, in exact rational arithmetic on the heights
as they are (float64 only picks the order of the sub-cells and skips those that surely
cannot fall or bound p, with margins far above its rounding). :func:`cell_falls` is the falling-edge test of
Bán et al. 2024 (the library's pre-filter); :func:`continuous_upper` an upper bound of
the true continuous relaxed ratio (sampled points where the surface falls along the ray
from p, where a ray could leave it), which no safe cone may exceed.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from exact_reference import exact_cone_squares, exact_heights


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
    """The point of [a, b] nearest to 0 (exact for Fractions)."""
    return min(max(0, a), b)


def _falls(z, u0, u1, v0, v1, xa, xb, ya, yb):
    """Is (gradient at a corner, from the two sub-cell edges there) . (corner - p) negative
    at one of the four corners of the sub-cell [u0, u1] x [v0, v1] of the cell with corner
    heights z (floats: evaluated in float64; Fractions: exactly)?"""
    a, b = _lerp2(z, u0, v0), _lerp2(z, u1, v0)
    cc, d = _lerp2(z, u0, v1), _lerp2(z, u1, v1)
    slopes = [((b - a), (cc - a), xa, ya), ((b - a), (d - b), xb, ya),
              ((d - cc), (cc - a), xa, yb), ((d - cc), (d - b), xb, yb)]
    return any(gx * x + gy * y < 0 for gx, gy, x, y in slopes)


def _wrap(i, n, tile):
    """Index of texel i on an axis of n: wrapped when tiled, clamped otherwise (numpy arrays)."""
    return i % n if tile else np.clip(i, 0, n - 1)


def _subcells(hf, r, c, tile_x, tile_y, max_ratio, split):
    """Every sub-cell that could bound p = (r, c) (cells as :func:`_cells` visits them), as
    arrays: corner texel indices (N, 4, 2) of its cell, its place (x0, y0, i, j), and float
    estimates: its squared nearest distance (uv) and a lower bound of its squared ratio
    (its highest corner estimated in float64, plus a margin far above float64 rounding)."""
    H, W = hf.shape
    reach_y, reach_x = int(math.ceil(max_ratio * H)) + 2, int(math.ceil(max_ratio * W)) + 2
    ys = np.arange(r - reach_y, r + reach_y) if tile_y else np.arange(-1, H)
    xs = np.arange(c - reach_x, c + reach_x) if tile_x else np.arange(-1, W)
    J, I = (a.ravel() for a in np.meshgrid(ys, xs, indexing="ij"))
    r0, r1, c0, c1 = _wrap(J, H, tile_y), _wrap(J + 1, H, tile_y), _wrap(I, W, tile_x), _wrap(I + 1, W, tile_x)
    idx = np.stack([np.stack([r0, c0], -1), np.stack([r0, c1], -1),
                    np.stack([r1, c0], -1), np.stack([r1, c1], -1)], 1)
    z = hf[idx[..., 0], idx[..., 1]]  # (N, 4)
    g = np.arange(split + 1) / split
    U, V = g[None, None, :], g[None, :, None]
    grid = (z[:, 0, None, None] * (1 - U) + z[:, 1, None, None] * U) * (1 - V) + \
        (z[:, 2, None, None] * (1 - U) + z[:, 3, None, None] * U) * V  # (N, v, u)
    rows = []
    for j in range(split):
        for i in range(split):
            a, b = grid[:, j, i], grid[:, j, i + 1]
            cc, d = grid[:, j + 1, i], grid[:, j + 1, i + 1]
            xa, xb = I - c + i / split, I - c + (i + 1) / split
            ya, yb = J - r + j / split, J - r + (j + 1) / split
            nx, ny = np.clip(0.0, xa, xb), np.clip(0.0, ya, yb)
            d2 = (nx / W) ** 2 + (ny / H) ** 2
            rise = np.maximum.reduce([a, b, cc, d]) - hf[r, c] + 1e-9
            with np.errstate(divide="ignore"):
                lb = np.where(rise > 0, d2 / np.maximum(rise, 1e-300) ** 2, np.inf)
            # float64 directional derivatives at the corners, and how far rounding could move them
            slack = np.minimum.reduce([
                v - 1e-9 * (abs(gx * x) + abs(gy * y) + abs(x) + abs(y))
                for v, gx, gy, x, y in (((b - a) * xa + (cc - a) * ya, b - a, cc - a, xa, ya),
                                        ((b - a) * xb + (d - b) * ya, b - a, d - b, xb, ya),
                                        ((d - cc) * xa + (cc - a) * yb, d - cc, cc - a, xa, yb),
                                        ((d - cc) * xb + (d - b) * yb, d - cc, d - b, xb, yb))])
            keep = np.flatnonzero(slack <= 0)  # the others surely do not fall
            rows += [(lb[n], n, i, j) for n in keep]
    rows.sort()
    return idx, I - c, J - r, rows


def relaxed_bound_square(hf, hq, tile_x, tile_y, cap2, split, r, c):
    """Exact squared bound of texel (r, c): min over limiting sub-cells of
    (nearest distance, uv)^2 / (highest corner - h(p))^2 (a Fraction), None when no sub-cell
    bounds p below ``cap2``. ``hf``: float64 heights (for estimates, to skip cells), ``hq``:
    the same as Fractions (every decision and the value are exact)."""
    H, W = hf.shape
    hp = hq[r, c]
    best = None
    idx, X0, Y0, rows = _subcells(hf, r, c, tile_x, tile_y, math.sqrt(float(cap2)), split)
    for lb, n, i, j in rows:
        if lb >= float(cap2) * (1 + 1e-9) or (best is not None and lb >= float(best) * (1 + 1e-9)):
            break
        z = tuple(hq[k0, k1] for k0, k1 in idx[n])
        u0, u1, v0, v1 = (Fraction(k, split) for k in (i, i + 1, j, j + 1))
        top = max(_lerp2(z, u, v) for u in (u0, u1) for v in (v0, v1))
        if top <= hp:
            continue
        x0, y0 = int(X0[n]), int(Y0[n])
        xa, xb, ya, yb = x0 + u0, x0 + u1, y0 + v0, y0 + v1
        if not _falls(z, u0, u1, v0, v1, xa, xb, ya, yb):
            continue
        d2 = (Fraction(_near(xa, xb)) / W) ** 2 + (Fraction(_near(ya, yb)) / H) ** 2
        q = d2 / (top - hp) ** 2
        if q < cap2 and (best is None or q < best):
            best = q
    return best


def relaxed_squares(h, tile_x=True, tile_y=True, max_ratio=1.0, split=2, levels=0):
    """Object (H, W) of Fractions: the exact squared relaxed ratio of every texel, the larger
    of the conservative cone's and the falling-direction bound's, at most max_ratio^2.
    Heights are taken exactly (:func:`exact_reference.exact_heights`): a float as the
    dyadic rational it is, an 8/16-bit level as code / levels (levels 255, 65535)."""
    hq = exact_heights(h, levels)
    hf = np.asarray(h, np.float64)
    cons = exact_cone_squares(h, tile_x, tile_y, max_ratio, levels)
    cap2 = Fraction(float(max_ratio)) ** 2
    out = np.empty(hf.shape, object)
    for r in range(hf.shape[0]):
        for c in range(hf.shape[1]):
            b = relaxed_bound_square(hf, hq, tile_x, tile_y, cap2, split, r, c)
            out[r, c] = cap2 if b is None else min(cap2, max(cons[r, c], b))
    return out


def relaxed_reference(h, tile_x=True, tile_y=True, max_ratio=1.0, split=2, levels=0):
    """Float64 (H, W) relaxed ratios (:func:`relaxed_squares`, rounded to nearest)."""
    sq = relaxed_squares(h, tile_x, tile_y, max_ratio, split, levels)
    return np.vectorize(lambda q: math.sqrt(float(q)), otypes=[np.float64])(sq)


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
