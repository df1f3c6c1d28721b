"""The search kernel of :mod:`csm_assets.cones.relaxed`: per texel, the nearest falling (sub-)cell.

Texel p at the origin (texel units), the bilinear cell of texel q towards ``(sx, sy)``
(each +1 or -1, the side away from p; both sides on p's own row or column) spans
q .. q + (sx, sy); q is its nearest corner to p. The cell is split into ``split`` x
``split`` sub-cells (each again bilinear); a sub-cell *limits* p when its surface falls
along some direction from p somewhere in it: the directional derivative
``grad h(e) . (e - p)`` is bilinear in e over a sub-cell, so it is negative somewhere
exactly when it is negative at one of the four corners, where the gradient is the
slopes of the sub-cell's two edges meeting there. A limiting sub-cell bounds the
relaxed ratio by (its nearest point's distance from p) / (its highest corner - h(p)).

Units: ``best`` is ``ratio^2 (W H)^2``, a distance of (ox, oy) texels counts
``ox^2 H^2 + oy^2 W^2``. Serial ``nogil`` numba, run on threads by :mod:`.polling`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels import CACHE

_FLOOR = 1.0 + 1e-12  # float64 rounding between two computations of one cone


@njit(cache=CACHE, inline="always")
def _wrap(i, n, tile):
    """Map index of a neighbour index i on an axis of n texels: wrapped or clamped."""
    if tile:
        return i % n
    return min(max(i, 0), n - 1)


@njit(cache=CACHE, inline="always")
def _near(a, b):
    """The point of [a, b] nearest to 0."""
    return min(max(0.0, a), b)


@njit(cache=CACHE, inline="always")
def bilerp(z00, z10, z01, z11, u, v):
    """The bilinear surface at (u, v) in [0, 1]^2 (exact at the corners)."""
    return (z00 * (1.0 - u) + z10 * u) * (1.0 - v) + (z01 * (1.0 - u) + z11 * u) * v


@njit(cache=CACHE, inline="always")
def falls(a, b, c, d, xa, xb, ya, yb):
    """Does the bilinear patch with corner heights a (xa, ya), b (xb, ya), c (xa, yb),
    d (xb, yb) (p at the origin) fall along some direction from p somewhere? Its
    directional derivative ``grad h(e) . (e - p)`` is bilinear in e, so it is negative
    somewhere exactly when it is at a corner (the gradient there: the slopes of the
    patch's two edges meeting there; the sign does not depend on the patch's size)."""
    return ((b - a) * xa + (c - a) * ya < 0.0 or (b - a) * xb + (d - b) * ya < 0.0
            or (d - c) * xa + (c - a) * yb < 0.0 or (d - c) * xb + (d - b) * yb < 0.0)


@njit(cache=CACHE, inline="always")
def _sub_bound(a, b, c, d, xa, xb, ya, yb, H2, W2, hp, best, top):
    """Lower ``best`` by the sub-cell with corner heights a (xa, ya), b (xb, ya),
    c (xa, yb), d (xb, yb) if it limits p; ``top``: a bound of the cell's heights."""
    nx = _near(xa, xb)
    ny = _near(ya, yb)
    dist = nx * nx * H2 + ny * ny * W2
    if dist >= best * top * top:
        return best
    dh = max(max(a, b), max(c, d)) - hp
    if dh <= 0.0 or dist >= best * dh * dh:
        return best
    if falls(a, b, c, d, xa, xb, ya, yb):
        return dist / (dh * dh)
    return best


@njit(cache=CACHE)
def cell_bound(z00, z10, z01, z11, x0, y0, split, H2, W2, hp, best):
    """Lower ``best`` by the limiting sub-cells of the cell ``[x0, x0+1] x [y0, y0+1]``
    (texel units, p at the origin) whose corners have heights z00 (x0, y0), z10 (x0+1, y0),
    z01 (x0, y0+1), z11 (x0+1, y0+1). Returns the new best."""
    top = max(max(z00, z10), max(z01, z11)) - hp
    if split == 2:  # the common case: nine heights, four sub-cells, nearest to p first
        m0 = bilerp(z00, z10, z01, z11, 0.5, 0.0)
        m1 = bilerp(z00, z10, z01, z11, 0.0, 0.5)
        m2 = bilerp(z00, z10, z01, z11, 0.5, 0.5)
        m3 = bilerp(z00, z10, z01, z11, 1.0, 0.5)
        m4 = bilerp(z00, z10, z01, z11, 0.5, 1.0)
        xm = x0 + 0.5
        ym = y0 + 0.5
        x1 = x0 + 1.0
        y1 = y0 + 1.0
        for k in range(4):
            i = k & 1 if x0 >= 0.0 else 1 - (k & 1)
            j = k >> 1 if y0 >= 0.0 else 1 - (k >> 1)
            if j == 0:
                if i == 0:
                    best = _sub_bound(z00, m0, m1, m2, x0, xm, y0, ym, H2, W2, hp, best, top)
                else:
                    best = _sub_bound(m0, z10, m2, m3, xm, x1, y0, ym, H2, W2, hp, best, top)
            elif i == 0:
                best = _sub_bound(m1, m2, z01, m4, x0, xm, ym, y1, H2, W2, hp, best, top)
            else:
                best = _sub_bound(m2, m3, m4, z11, xm, x1, ym, y1, H2, W2, hp, best, top)
        return best
    inv = 1.0 / split
    for jj in range(split):  # the sub-cells nearest to p first
        j = jj if y0 >= 0.0 else split - 1 - jj
        v0 = j * inv
        v1 = (j + 1) * inv
        for ii in range(split):
            i = ii if x0 >= 0.0 else split - 1 - ii
            u0 = i * inv
            u1 = (i + 1) * inv
            best = _sub_bound(bilerp(z00, z10, z01, z11, u0, v0), bilerp(z00, z10, z01, z11, u1, v0),
                              bilerp(z00, z10, z01, z11, u0, v1), bilerp(z00, z10, z01, z11, u1, v1),
                              x0 + u0, x0 + u1, y0 + v0, y0 + v1, H2, W2, hp, best, top)
    return best


@njit(cache=CACHE, inline="always")
def texel_cells(h, fmask, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best):
    """Lower ``best`` by the cells of the texel at unrolled (ty, tx) towards the sides in
    ``fmask`` (bits ``2 * (sy > 0) + (sx > 0)``: the cells that can fall seen from p)."""
    H, W = h.shape
    rr = ty % H
    cc = tx % W
    ox = tx - c
    oy = ty - r
    for bit in range(4):
        if not fmask & (1 << bit):
            continue
        sx = 1 if bit & 1 else -1
        sy = 1 if bit & 2 else -1
        cx = _wrap(cc + sx, W, tile_x)
        cy = _wrap(rr + sy, H, tile_y)
        qa, qb, qc, qd = h[rr, cc], h[rr, cx], h[cy, cc], h[cy, cx]
        # tops[bit, rr, cc] holds this maximum too (the same value); reading it was measured no
        # faster (README: Relaxed cones, exact): the corners are read for falls() anyway
        dh = max(max(qa, qb), max(qc, qd)) - hp
        if dh <= 0.0 or ox * ox * H2 + oy * oy * W2 >= best * dh * dh:
            continue  # the whole cell is too low or too far
        if sx < 0:
            qa, qb, qc, qd = qb, qa, qd, qc
        if sy < 0:
            qa, qb, qc, qd = qc, qd, qa, qb
        xa = float(ox if sx > 0 else ox - 1)
        ya = float(oy if sy > 0 else oy - 1)
        if not falls(qa, qb, qc, qd, xa, xa + 1.0, ya, ya + 1.0):
            continue  # the cell's directional derivative is bilinear: no sub-cell falls
        best = cell_bound(qa, qb, qc, qd, xa, ya, split, H2, W2, hp, best)
    return best


@njit(cache=CACHE, inline="always")
def _side_bits(d, neg, pos):
    """Mask bits for an offset ``d`` on one axis: its side's bits, both on the axis."""
    if d > 0:
        return pos
    if d < 0:
        return neg
    return neg | pos


@njit(cache=CACHE, inline="always")
def _texel(h, flags, tops, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best, boy, box):
    """Lower ``(best, boy, box)`` by the texel at unrolled position (ty, tx)."""
    oy = ty - r
    ox = tx - c
    rr = ty % h.shape[0]
    cc = tx % h.shape[1]
    fmask = flags[rr, cc] & _side_bits(ox, 5, 10) & _side_bits(oy, 3, 12)
    if fmask:
        dh = _top(tops, fmask, rr, cc) - hp
        if dh <= 0.0 or ox * ox * H2 + oy * oy * W2 >= best * dh * dh:
            return best, boy, box
        v = texel_cells(h, fmask, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best)
        if v < best:
            return v, oy, ox
    return best, boy, box


@njit(cache=CACHE, inline="always")
def _gap(a, b, p):
    """Texels from p to the nearest of the unrolled span a..b (0 when p lies in it)."""
    if p < a:
        return a - p
    if p > b:
        return p - b
    return 0


@njit(cache=CACHE, inline="always")
def _span(u, n, nb, starts):
    """Unrolled texel span (first, last) of block ``u`` of an axis of n texels, nb blocks
    a period, block j covering ``starts[j]..starts[j+1]-1``."""
    period = u // nb
    j = u - period * nb
    return period * n + starts[j], period * n + starts[j + 1] - 1


@njit(cache=CACHE, inline="always")
def _side_span(a, b, p, neg, pos):
    """Mask bits of the side(s) of p that the unrolled span a..b lies on."""
    if a > p:
        return pos
    if b < p:
        return neg
    return neg | pos


@njit(cache=CACHE, inline="always")
def _top(m, mask, i, j):
    """Highest of ``m[bit, i, j]`` over the bits set in ``mask``."""
    t = -1.0
    for b in range(4):
        if mask & (1 << b):
            t = max(t, m[b, i, j])
    return t


@njit(cache=CACHE, inline="always")
def _block(h, flags, tops, hp, r, c, uy, ux, fine, coarse, tile_x, tile_y, split, H2, W2, best, oy, ox, stop):
    """Lower ``(best, oy, ox)`` by the cells of unrolled coarse block (uy, ux), skipping it
    (or its fine blocks) when their highest falling cell cannot narrow it; done as soon as
    ``best`` reaches ``stop``."""
    H, W = h.shape
    fsy, fsx, fmax = fine
    csy, csx, cfy, cfx, cmax = coarse[:5]
    nfy, nfx = len(fsy) - 1, len(fsx) - 1
    ncy, ncx = len(csy) - 1, len(csx) - 1
    py = uy // ncy
    ky = uy - py * ncy
    px = ux // ncx
    kx = ux - px * ncx
    cy0, cy1 = _span(uy, H, ncy, csy)
    cx0, cx1 = _span(ux, W, ncx, csx)
    mask = _side_span(cx0, cx1, c, 5, 10) & _side_span(cy0, cy1, r, 3, 12)
    dh = _top(cmax, mask, ky, kx) - hp
    if dh <= 0.0:
        return best, oy, ox
    gy = _gap(cy0, cy1, r)
    gx = _gap(cx0, cx1, c)
    if gx * gx * H2 + gy * gy * W2 >= best * dh * dh:
        return best, oy, ox
    for fy in range(py * nfy + cfy[ky], py * nfy + cfy[ky + 1]):
        fy0, fy1 = _span(fy, H, nfy, fsy)
        gy = _gap(fy0, fy1, r)
        ymask = _side_span(fy0, fy1, r, 3, 12)
        for fx in range(px * nfx + cfx[kx], px * nfx + cfx[kx + 1]):
            fx0, fx1 = _span(fx, W, nfx, fsx)
            mask = _side_span(fx0, fx1, c, 5, 10) & ymask
            if best <= stop:
                return best, oy, ox
            dh = _top(fmax, mask, fy - py * nfy, fx - px * nfx) - hp
            if dh <= 0.0:
                continue
            gx = _gap(fx0, fx1, c)
            if gx * gx * H2 + gy * gy * W2 >= best * dh * dh:
                continue
            for ty in range(fy0, fy1 + 1):
                for tx in range(fx0, fx1 + 1):
                    best, oy, ox = _texel(h, flags, tops, hp, r, c, ty, tx, tile_x, tile_y,
                                          split, H2, W2, best, oy, ox)
    return best, oy, ox


@njit(cache=CACHE, error_model="numpy")
def relaxed_texel(h, flags, tops, lmax, r, c, tile_x, tile_y, split, cap2, lo2, fine, coarse, seeds):
    """``(best, oy, ox)`` of texel (r, c): ``best = ratio^2 (W H)^2`` (at most ``cap2``) and
    the offset of the texel whose cell sets it (0, 0 when none does).

    ``lo2``: the conservative cone in the same units, a floor: the search ends as soon as
    it reaches it (to float64 rounding) and gives it exactly. ``fine``/``coarse``: the
    block tables of :func:`csm_assets.cones.relaxed.block_tables` (the highest corner of
    each texel's cells that can fall, per side). Seeds with the texels at offsets
    ``seeds`` (int64 pairs dy, dx: the neighbours' answers; (0, 0) is none), then searches
    rings of coarse blocks on the unrolled surface, skipping a block (coarse, then fine)
    whose highest falling cell is too low or too far to narrow the cone.
    """
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    hp = h[r, c]
    best = cap2
    top = lmax - hp
    if top <= 0.0 or lo2 >= cap2:
        return best, 0, 0
    top2 = top * top
    csy, csx = coarse[0], coarse[1]
    c0y, c0x, bminy, bminx = coarse[5], coarse[6], coarse[7], coarse[8]
    ncy, ncx = len(csy) - 1, len(csx) - 1
    oy = 0
    ox = 0
    for i in range(len(seeds) // 2):
        sy, sx = seeds[2 * i], seeds[2 * i + 1]
        if sy != 0 or sx != 0:
            ty, tx = r + sy, c + sx
            if (tile_y or 0 <= ty < H) and (tile_x or 0 <= tx < W):
                best, oy, ox = _texel(h, flags, tops, hp, r, c, ty, tx, tile_x, tile_y, split,
                                      H2, W2, best, oy, ox)
    u0y = c0y[r]
    u0x = c0x[c]
    k = 0
    while True:
        if best <= lo2 * _FLOOR:
            return lo2, oy, ox
        lb = np.inf
        ya, yb = u0y - k, u0y + k
        xa, xb = u0x - k, u0x + k
        if not tile_y:
            ya, yb = max(ya, 0), min(yb, ncy - 1)
        if not tile_x:
            xa, xb = max(xa, 0), min(xb, ncx - 1)
        if k == 0:
            lb = 0.0
        else:
            if tile_x or xa == u0x - k or xb == u0x + k:
                lb = min(lb, ((k - 1) * bminx + 1.0) ** 2 * H2)
            if tile_y or ya == u0y - k or yb == u0y + k:
                lb = min(lb, ((k - 1) * bminy + 1.0) ** 2 * W2)
        if lb == np.inf or lb >= best * top2:
            break
        for uy in range(ya, yb + 1):
            edge = uy == u0y - k or uy == u0y + k
            ux = xa if edge else u0x - k
            while ux <= xb:
                if ux >= xa:
                    best, oy, ox = _block(h, flags, tops, hp, r, c, uy, ux, fine, coarse, tile_x,
                                          tile_y, split, H2, W2, best, oy, ox, lo2 * _FLOOR)
                if edge:
                    ux += 1
                elif ux < u0x + k and k > 0:
                    ux = u0x + k  # inside the ring: only its two side blocks
                else:
                    break
        k += 1
    return best, oy, ox


@njit(cache=CACHE, nogil=True, error_model="numpy")
def relaxed_rows(h, flags, tops, lmax, tile_x, tile_y, split, max_ratio, cons, fine, coarse, r0, r1,
                 out, done):
    """Relaxed ratios of rows ``r0..r1`` into ``out`` (H, W) float64, never below the
    conservative ``cons`` (H, W); ``done[r] = 1`` after row r."""
    H, W = h.shape
    wh = float(W) * H
    cap2 = (max_ratio * wh) ** 2
    above = np.zeros((W, 2), np.int64)  # offsets that set the row above's cones
    seeds = np.zeros(4, np.int64)
    for r in range(r0, r1):
        oy, ox = 0, 0
        for c in range(W):
            seeds[0], seeds[1] = oy, (ox - 1 if (oy or ox) else 0)
            ay, ax = above[c, 0], above[c, 1]
            seeds[2], seeds[3] = ((ay - 1, ax) if (ay or ax) and r > r0 else (0, 0))
            lo = cons[r, c]
            best, oy, ox = relaxed_texel(h, flags, tops, lmax, r, c, tile_x, tile_y, split, cap2,
                                         (lo * wh) ** 2, fine, coarse, seeds)
            above[c, 0], above[c, 1] = oy, ox
            out[r, c] = min(max(math.sqrt(best) / wh, lo), max_ratio)
        done[r] = 1
