"""Exact relaxed cone ratios (README's Conventions: *Relaxed cone ratio*).

A relaxed cone may let a ray step into the surface once, never out again: texel q
limits the relaxed cone of p only where the bilinear cell beyond q, seen from p,
is not monotone (one of its four edges falls going away from p), so a ray inside the
cone could leave the surface there (the falling-edge rule of Bundas et al., "Robust
Cone Step Mapping", EGSR 2024). Limiting texels are a subset of the higher texels,
so a relaxed cone is never narrower than the conservative one.

On a tiled axis q ranges over the periodic surface (every image of a texel, each
with its own direction from p), not only the nearest image; on an axis that does not
tile, cells clamp at the edge as ``CLAMP_TO_EDGE`` sampling does.

The kernel searches square rings outward from p (as :mod:`.cones_ring`), testing
per texel a 4-bit mask of which of its cells fall, and stops once no farther ring
can narrow the cone. Serial ``nogil`` numba, run on threads by :mod:`.polling`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cones import exact_ratios, round_down_f32
from .heightfield import check_max_ratio, tile_pair, unit_heights
from .kernels import CACHE
from .polling import row_chunk, run_chunks


def neighbour(h: np.ndarray, axis: int, step: int, tile: bool) -> np.ndarray:
    """``h`` shifted so that ``out[i] = h[i + step]`` along ``axis``, wrapped or clamped."""
    if tile:
        return np.roll(h, -step, axis=axis)
    n = h.shape[axis]
    idx = np.clip(np.arange(n) + step, 0, n - 1)
    return np.take(h, idx, axis=axis)


def fall_flags(h: np.ndarray, tile_x: bool, tile_y: bool) -> np.ndarray:
    """uint8 ``(H, W)``: bit ``2 * (sy > 0) + (sx > 0)`` is set where the bilinear cell of
    texel q towards ``(sx, sy)`` (columns, rows; each +1 or -1) has an edge that falls
    going away from q: ``h(q) > h(q+sx)``, ``h(q) > h(q+sy)``, ``h(q+sx) > h(q+sx+sy)`` or
    ``h(q+sy) > h(q+sx+sy)``. Neighbours wrap on a tiled axis, clamp otherwise.
    """
    flags = np.zeros(h.shape, np.uint8)
    for sy in (-1, 1):
        for sx in (-1, 1):
            a = h
            b = neighbour(h, 1, sx, tile_x)
            c = neighbour(h, 0, sy, tile_y)
            d = neighbour(b, 0, sy, tile_y)
            falls = (a > b) | (a > c) | (b > d) | (c > d)
            flags |= (falls.astype(np.uint8) << np.uint8(2 * (sy > 0) + (sx > 0)))
    return flags


CONE_KINDS = ("conservative", "relaxed")  # what a step map's G holds (its ``cones`` setting)
_FLOOR = 1.0 + 1e-12  # float64 rounding between two computations of one cone


@njit(cache=CACHE, inline="always")
def _side_bits(d, neg, pos):
    """Mask bits for an offset ``d`` on one axis: its side's bits, both on the axis."""
    if d > 0:
        return pos
    if d < 0:
        return neg
    return neg | pos


@njit(cache=CACHE, inline="always")
def _texel_bound(h, flags, hp, r, c, ty, tx, rr, cc, H2, W2, best, boy, box):
    """Lower ``(best, boy, box)`` by the texel at unrolled position (ty, tx), texel (rr, cc)
    of the map, if it limits p."""
    oy = ty - r
    ox = tx - c
    mask = _side_bits(ox, 5, 10) & _side_bits(oy, 3, 12)
    if flags[rr, cc] & mask:
        dh = h[rr, cc] - hp
        if dh > 0.0:
            v = (ox * ox * H2 + oy * oy * W2) / (dh * dh)
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
def _block(h, flags, hp, r, c, uy, ux, fine, coarse, H, W, H2, W2, best, oy, ox):
    """Lower ``(best, oy, ox)`` by the limiting texels of unrolled coarse block (uy, ux),
    skipping it (or its fine blocks) when their highest limiting texel cannot narrow it."""
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
            dh = _top(fmax, mask, fy - py * nfy, fx - px * nfx) - hp
            if dh <= 0.0:
                continue
            gx = _gap(fx0, fx1, c)
            if gx * gx * H2 + gy * gy * W2 >= best * dh * dh:
                continue
            for ty in range(fy0, fy1 + 1):
                for tx in range(fx0, fx1 + 1):  # a fine block lies inside one period
                    best, oy, ox = _texel_bound(h, flags, hp, r, c, ty, tx, ty - py * H,
                                                tx - px * W, H2, W2, best, oy, ox)
    return best, oy, ox


@njit(cache=CACHE, error_model="numpy")
def _relaxed_texel(h, flags, lmax, r, c, tile_x, tile_y, cap2, lo2, fine, coarse, seeds):
    """``(best, oy, ox)`` of texel (r, c): ``best = ratio^2 (W H)^2`` (at most ``cap2``) and
    the offset of the texel that sets it (0, 0 when none does).

    ``lo2``: the conservative cone in the same units, a floor: the search ends as soon as
    it reaches it (to float64 rounding) and gives it exactly.
    ``fine``/``coarse``: per axis (y then x) the block tables from :func:`block_tables`.
    Seeds with the texels at offsets ``seeds`` (int64 pairs dy, dx: the neighbours'
    answers; (0, 0) is none), then searches rings
    of coarse blocks, skipping a block (coarse, then fine) whose highest limiting texel is
    too low or too far to narrow the cone.
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
                best, oy, ox = _texel_bound(h, flags, hp, r, c, ty, tx, ty % H, tx % W, H2,
                                            W2, best, oy, ox)
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
                    best, oy, ox = _block(h, flags, hp, r, c, uy, ux, fine, coarse, H, W, H2,
                                          W2, best, oy, ox)
                if edge:
                    ux += 1
                elif ux < u0x + k and k > 0:
                    ux = u0x + k  # inside the ring: only its two side blocks
                else:
                    break
        k += 1
    return best, oy, ox


@njit(cache=CACHE, nogil=True, error_model="numpy")
def relaxed_rows(h, flags, lmax, tile_x, tile_y, max_ratio, cons, fine, coarse, r0, r1, out,
                 done):
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
            best, oy, ox = _relaxed_texel(h, flags, lmax, r, c, tile_x, tile_y, cap2,
                                          (lo * wh) ** 2, fine, coarse, seeds)
            above[c, 0], above[c, 1] = oy, ox
            out[r, c] = min(max(math.sqrt(best) / wh, lo), max_ratio)
        done[r] = 1


def axis_blocks(n: int, size: int) -> np.ndarray:
    """int64 starts of the blocks of an axis of n texels (``size`` each, the last one
    takes the remainder, so every block has at least ``min(size, n)``), ending with n."""
    nb = max(1, n // size)
    return np.append(np.arange(nb, dtype=np.int64) * size, np.int64(n))


def block_max(values: np.ndarray, sy: np.ndarray, sx: np.ndarray) -> np.ndarray:
    """Maximum of ``values`` (..., H, W) over each block (rows ``sy[i]..``, columns ``sx[j]..``)."""
    rows = np.maximum.reduceat(values, sy[:-1], axis=-2)
    return np.ascontiguousarray(np.maximum.reduceat(rows, sx[:-1], axis=-1))


def block_tables(limit: np.ndarray, fine: int = 8, group: int = 8):
    """The two-level block tables :func:`_relaxed_texel` reads, for limiting heights
    ``limit`` (4, H, W), one plane per fall bit (-1 where the texel's cell does not fall)."""
    H, W = limit.shape[1:]
    fsy, fsx = axis_blocks(H, fine), axis_blocks(W, fine)
    cfy, cfx = axis_blocks(len(fsy) - 1, group), axis_blocks(len(fsx) - 1, group)
    csy, csx = fsy[cfy], fsx[cfx]
    c0y = np.repeat(np.arange(len(csy) - 1), np.diff(csy)).astype(np.int64)
    c0x = np.repeat(np.arange(len(csx) - 1), np.diff(csx)).astype(np.int64)
    return ((fsy, fsx, block_max(limit, fsy, fsx)),
            (csy, csx, cfy, cfx, block_max(limit, csy, csx), c0y, c0x,
             int(np.diff(csy).min()), int(np.diff(csx).min())))


def relaxed_exact(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                  progress=None) -> np.ndarray:
    """Float64 ``(H, W)`` relaxed ratios of validated float64 unit heights ``h``.

    ``progress(done_rows, total_rows)`` is called now and then from this thread.
    """
    h = np.ascontiguousarray(h, dtype=np.float64)
    H, W = h.shape
    flags = fall_flags(h, tile_x, tile_y)
    out = np.full((H, W), max_ratio)
    limiting = flags != 0
    if not limiting.any():
        return out
    cons = np.ascontiguousarray(exact_ratios(h, tile_x, tile_y, max_ratio), dtype=np.float64)
    lmax = float(h[limiting].max())
    bits = (flags[None] >> np.arange(4, dtype=np.uint8)[:, None, None]) & 1
    fine, coarse = block_tables(np.where(bits != 0, h[None], -1.0))
    done = np.zeros(H, np.uint8)
    run_chunks(lambda r0, r1: relaxed_rows(h, flags, lmax, tile_x, tile_y, max_ratio, cons,
                                           fine, coarse, r0, r1, out, done),
               H, done, progress, chunk=row_chunk(H))
    return out


def relaxed_cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact relaxed cone ratio of every texel (README: *Relaxed cone ratio*).

    height: uint8 (/255), uint16 (/65535) or float ``(H, W)`` in ``[0, 1]``, any size
        from 1x1; a :class:`~csm_assets.Heightfield` is taken by its ``.data``.
    tile: True (default), False, or ``(tile_x, tile_y)``.
    max_ratio: the cap (> 0); a texel that nothing limits gets it.

    Returns float32 ``(H, W)``, rounded down from float64, never below
    :func:`~csm_assets.cone_ratios`. Raises ValueError on bad input.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(relaxed_exact(h, tx, ty, cap))
