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
The per-cell tests are :mod:`.relaxed_cell`'s, every decision exact.

Units: ``best`` is ``ratio^2 (W H)^2``, a distance of (ox, oy) texels counts
``ox^2 H^2 + oy^2 W^2``. Serial ``nogil`` numba, run on threads by :mod:`.polling`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels import CACHE
from .relaxed_cell import cell_bound, filter_bound, quad_falls

_FLOOR = 1.0 + 1e-12  # float64 rounding between two computations of one cone


@njit(cache=CACHE, inline="always")
def _wrap(i, n, tile):
    """Map index of a neighbour index i on an axis of n texels: wrapped or clamped."""
    if tile:
        return i % n
    return min(max(i, 0), n - 1)


@njit(cache=CACHE, inline="always")
def texel_cells(h, fmask, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best, tol):
    """Lower ``best`` by the cells of the texel at unrolled (ty, tx) towards the sides in
    ``fmask`` (bits ``2 * (sy > 0) + (sx > 0)``: the cells that can fall seen from p)."""
    H, W = h.shape
    rr = ty % H
    cc = tx % W
    ox = tx - c
    oy = ty - r
    d2 = ox * ox * H2 + oy * oy * W2
    for bit in range(4):
        if not fmask & (1 << bit):
            continue
        sx = 1 if bit & 1 else -1
        sy = 1 if bit & 2 else -1
        cx = _wrap(cc + sx, W, tile_x)
        cy = _wrap(rr + sy, H, tile_y)
        qa, qb, qc, qd = h[rr, cc], h[rr, cx], h[cy, cc], h[cy, cx]
        # tops[bit, rr, cc] holds this maximum too (the same value); reading it was measured no
        # faster (README: Relaxed cones, exact): the corners are read for quad_falls() anyway
        dh = max(max(qa, qb), max(qc, qd)) - hp
        if dh <= 0.0 or (d2 > 0.0 and d2 >= best * dh * dh):
            continue  # the whole cell is too low or too far
        if sx < 0:
            qa, qb, qc, qd = qb, qa, qd, qc
        if sy < 0:
            qa, qb, qc, qd = qc, qd, qa, qb
        xa = float(ox if sx > 0 else ox - 1)
        ya = float(oy if sy > 0 else oy - 1)
        z = (qa, qb, qc, qd)
        dz = (qb - qa, qd - qc, qc - qa, qd - qb)
        b = filter_bound(dz, tol, xa, ya)
        if not quad_falls(z, b, 1.0, 0, 0, xa, ya, dz[0], dz[1], dz[2], dz[3]):
            continue  # the cell's directional derivative is bilinear: no sub-cell falls
        best = cell_bound(z, dz, b, xa, ya, split, H2, W2, hp, best, tol == 0.0)
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
def _texel(h, flags, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best, boy, box, tol):
    """Lower ``(best, boy, box)`` by the texel at unrolled position (ty, tx)."""
    oy = ty - r
    ox = tx - c
    rr = ty % h.shape[0]
    cc = tx % h.shape[1]
    fmask = flags[rr, cc] & _side_bits(ox, 5, 10) & _side_bits(oy, 3, 12)
    if fmask:
        dh = _cell_top(h, fmask, rr, cc, tile_x, tile_y) - hp
        d2 = ox * ox * H2 + oy * oy * W2
        if dh <= 0.0 or (d2 > 0.0 and d2 >= best * dh * dh):
            return best, boy, box
        v = texel_cells(h, fmask, hp, r, c, ty, tx, tile_x, tile_y, split, H2, W2, best, tol)
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
def _cell_top(h, mask, i, j, tile_x, tile_y):
    """Highest corner of texel (i, j)'s cells towards the sides in ``mask`` (bits as in
    :func:`~csm_assets.cones.relaxed.fall_flags`; the cells :func:`~csm_assets.cones.relaxed.cell_tops`
    holds, computed here rather than stored: four float64 a texel saved)."""
    H, W = h.shape
    t = -1.0
    for b in range(4):
        if mask & (1 << b):
            jx = _wrap(j + (1 if b & 1 else -1), W, tile_x)
            iy = _wrap(i + (1 if b & 2 else -1), H, tile_y)
            t = max(t, max(max(h[i, j], h[i, jx]), max(h[iy, j], h[iy, jx])))
    return t


@njit(cache=CACHE, inline="always")
def _block(h, flags, hp, r, c, uy, ux, fine, coarse, tile_x, tile_y, split, H2, W2, best, oy, ox, stop,
           tol):
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
    g2 = gx * gx * H2 + gy * gy * W2
    if g2 > 0.0 and g2 >= best * dh * dh:
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
            g2 = gx * gx * H2 + gy * gy * W2
            if g2 > 0.0 and g2 >= best * dh * dh:
                continue
            for ty in range(fy0, fy1 + 1):
                for tx in range(fx0, fx1 + 1):
                    best, oy, ox = _texel(h, flags, hp, r, c, ty, tx, tile_x, tile_y,
                                          split, H2, W2, best, oy, ox, tol)
    return best, oy, ox


@njit(cache=CACHE, error_model="numpy")
def relaxed_texel(h, flags, lmax, r, c, tile_x, tile_y, split, cap2, lo2, fine, coarse, seeds, tol):
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
                best, oy, ox = _texel(h, flags, hp, r, c, ty, tx, tile_x, tile_y, split,
                                      H2, W2, best, oy, ox, tol)
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
                    best, oy, ox = _block(h, flags, hp, r, c, uy, ux, fine, coarse, tile_x,
                                          tile_y, split, H2, W2, best, oy, ox, lo2 * _FLOOR, tol)
                if edge:
                    ux += 1
                elif ux < u0x + k and k > 0:
                    ux = u0x + k  # inside the ring: only its two side blocks
                else:
                    break
        k += 1
    return best, oy, ox


@njit(cache=CACHE, nogil=True, error_model="numpy")
def relaxed_rows(h, flags, lmax, tile_x, tile_y, split, max_ratio, cons, fine, coarse, r0, r1,
                 out, done, tol, cons_cap, cons_top, scale):
    """Relaxed ratios of rows ``r0..r1`` into ``out`` (H, W) float64, never below the
    conservative ``cons`` (H, W: per unit height; ``cons_top`` where it reaches ``cons_cap``,
    nothing to search there; divided by ``scale``, the units of ``h``); ``done[r] = 1`` after
    row r. tol: the per-cell filters' bound (:data:`.relaxed_cell.TOL` for float heights, 0
    for integer codes)."""
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
            lo = (cons_top if lo >= cons_cap else lo) / scale
            best, oy, ox = relaxed_texel(h, flags, lmax, r, c, tile_x, tile_y, split, cap2,
                                         (lo * wh) ** 2, fine, coarse, seeds, tol)
            above[c, 0], above[c, 1] = oy, ox
            out[r, c] = min(max(math.sqrt(best) / wh, lo), max_ratio)
        done[r] = 1
