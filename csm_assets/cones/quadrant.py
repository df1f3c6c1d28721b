"""Exact per-quadrant conservative cone ratios: four cones per texel, one per quadrant of
directions a ray can travel into.

A ray travels one way. Started anywhere in texel p's cell towards ``(+u, +v)`` it only
reaches texels q with ``dx = col(q) - col(p) >= 0`` and ``dy = row(q) - row(p) >= 0``
(v grows downward, along rows, as in DESIGN.md's conventions), so its cone needs only
those texels: the quadrant's cone ratio is

    min over texels q of the quadrant with h(q) > h(p) of |(dx, dy)|_uv / (h(q) - h(p)),

capped at ``max_ratio``, where each quadrant includes its two bounding axes (dx = 0 or
dy = 0). Quadrants, in the order of the output's first axis (u along columns, v along
rows, downward):

    0: +u +v    1: -u +v    2: -u -v    3: +u -v

On a tiled axis the ray wraps: the offset is taken in the quadrant's direction, modulo the
axis (``dx = (col(q) - col(p)) mod W`` for +u), which is exact on the torus (a farther image
of q gives a wider cone); on an axis that does not tile, q must lie on the quadrant's side.
The minimum over the four quadrants is :func:`csm_assets.cone_ratios` exactly (the
shortest way round is one of the two directions); each quadrant's cone is at least as wide.

The kernel is the branch and bound of :mod:`csm_assets.cones.pyramid` with four bests at
once: a block is skipped when, for every quadrant that reaches it, its nearest offset in
that quadrant's direction cannot beat that quadrant's best (by :data:`~.pyramid.SLACK`: every
exact method gives the same float64, the minimum of ``d / (dh * dh)``). Serial ``nogil`` numba over row
chunks, run on threads by :mod:`csm_assets.polling`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..heightfield import check_max_ratio, tile_pair, unit_heights
from ..kernels import CACHE
from ..polling import row_chunk, run_chunks
from .exact import kernel_cap, round_down_f32, safe_ratios
from .pyramid import SLACK, build_pyramid

QUADRANTS = ((1, 1), (-1, 1), (-1, -1), (1, -1))  # (sign of u = columns, sign of v = rows)


@njit(cache=CACHE, inline="always")
def _gaps(x, a, b, n, tile, scale):
    """``scale * offset^2`` of the nearest of a..b from x going +, and going -, on an axis
    of n texels; inf where that direction cannot reach the block (no tiling)."""
    if x < a:
        g = float(a - x)
        return g * g * scale, (float(x - b + n) ** 2 * scale if tile else np.inf)
    if x > b:
        g = float(x - b)
        return (float(a - x + n) ** 2 * scale if tile else np.inf), g * g * scale
    return 0.0, 0.0


@njit(cache=CACHE, inline="always")
def _quad_dists(xp, xm, yp, ym, d):
    """``d[q] = dx^2 H^2 + dy^2 W^2`` in quadrant q (inf where it cannot reach)."""
    d[0] = xp + yp
    d[1] = xm + yp
    d[2] = xm + ym
    d[3] = xp + ym


@njit(cache=CACHE, inline="always")
def _offer(h, r, c, qr, qc, hp, tile_x, tile_y, best, apex, d):
    """Lower the four bests by texel (qr, qc), recording it as the apex of those it lowers."""
    H, W = h.shape
    dh = h[qr, qc] - hp
    if dh <= 0.0:
        return
    xp, xm = _gaps(c, qc, qc, W, tile_x, float(H) * H)
    yp, ym = _gaps(r, qr, qr, H, tile_y, float(W) * W)
    _quad_dists(xp, xm, yp, ym, d)
    for q in range(4):
        if d[q] / (dh * dh) < best[q]:
            best[q] = d[q] / (dh * dh)
            apex[q, 0] = qr
            apex[q, 1] = qc


@njit(cache=CACHE, inline="always")
def _search(h, flat, offsets, prow, pcol, tile_x, tile_y, r, c, best, apex, stack, sb, cb, ci, d):
    """Lower ``best`` (float64 (4,), ratio^2 (W H)^2 per quadrant) for texel (r, c) by a
    depth-first search of the pyramid; ``apex`` (int64 (4, 2)) gets the texel of each best.

    ``stack`` (int64 (S, 3)), ``sb`` (float64 (S, 4): the stacked blocks' bounds per
    quadrant), ``cb`` (float64 (4, 5): each child's key, then its bounds), ``ci`` (int64
    (4, 2)), ``d`` (float64 (4,)): scratch space. Returns the number of blocks examined.
    """
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    hp = h[r, c]
    top = len(offsets) - 1
    seen = 0
    if hp >= flat[offsets[top]]:
        return seen
    stack[0, 0] = top
    stack[0, 1] = 0
    stack[0, 2] = 0
    for q in range(4):
        sb[0, q] = 0.0
    sp = 1
    while sp > 0:
        sp -= 1
        if (sb[sp, 0] >= best[0] * SLACK and sb[sp, 1] >= best[1] * SLACK
                and sb[sp, 2] >= best[2] * SLACK and sb[sp, 3] >= best[3] * SLACK):
            continue
        kc = stack[sp, 0] - 1
        bi = stack[sp, 1]
        bj = stack[sp, 2]
        size = 1 << kc
        nr, nc = prow[kc], pcol[kc]
        base = offsets[kc]
        m = 0
        for a in range(2):
            ii = 2 * bi + a
            if ii >= nr:
                continue
            y0 = ii * size
            yp, ym = _gaps(r, y0, min(y0 + size, H) - 1, H, tile_y, W2)
            for b in range(2):
                jj = 2 * bj + b
                if jj >= nc:
                    continue
                seen += 1
                dh = flat[base + ii * nc + jj] - hp
                if dh <= 0.0:
                    continue
                x0 = jj * size
                xp, xm = _gaps(c, x0, min(x0 + size, W) - 1, W, tile_x, H2)
                _quad_dists(xp, xm, yp, ym, d)
                dh2 = dh * dh
                if kc == 0:  # a texel: its exact ratio in each quadrant
                    for q in range(4):
                        if d[q] < best[q] * dh2 * SLACK and d[q] / dh2 < best[q]:
                            best[q] = d[q] / dh2
                            apex[q, 0] = ii
                            apex[q, 1] = jj
                    continue
                key = np.inf
                for q in range(4):
                    if d[q] < best[q] * dh2 * SLACK:
                        key = min(key, d[q])
                if key < np.inf:
                    inv = 1.0 / dh2  # bounds, a little low: the skip test has SLACK to spare
                    for q in range(4):
                        cb[m, q + 1] = d[q] * inv
                    key *= inv
                    cb[m, 0] = key
                    ci[m, 0] = ii
                    ci[m, 1] = jj
                    m += 1
        for _ in range(m):  # largest key first, so the nearest child is popped first
            t = 0
            for k in range(1, m):
                if cb[k, 0] > cb[t, 0]:
                    t = k
            stack[sp, 0] = kc
            stack[sp, 1] = ci[t, 0]
            stack[sp, 2] = ci[t, 1]
            for q in range(4):
                sb[sp, q] = cb[t, q + 1]
            cb[t, 0] = -1.0  # taken
            sp += 1
    return seen


@njit(cache=CACHE, nogil=True)
def quadrant_rows(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2, r0, r1, out, done):
    """Best ratio^2 (W H)^2 per quadrant of rows ``r0..r1`` into ``out`` (float64 (4, H, W)),
    ``done[r] = 1`` after row r. Each search starts from the bests that the apexes of its
    left neighbour and of the texel above (in this chunk) give: a tight start."""
    W = h.shape[1]
    depth = len(offsets) + 1
    stack = np.empty((4 * depth, 3), np.int64)
    sb = np.empty((4 * depth, 4), np.float64)
    cb = np.empty((4, 5), np.float64)
    ci = np.empty((4, 2), np.int64)
    d = np.empty(4, np.float64)
    best = np.empty(4, np.float64)
    apex = np.full((4, 2), -1, np.int64)
    prev = np.full((4, 2), -1, np.int64)
    above = np.full((W, 4, 2), -1, np.int64)  # the apexes found for the row above
    for r in range(r0, r1):
        prev[:] = -1
        for c in range(W):
            best[:] = cap2
            apex[:] = -1
            hp = h[r, c]
            for k in range(4):
                if prev[k, 0] >= 0:
                    _offer(h, r, c, prev[k, 0], prev[k, 1], hp, tile_x, tile_y, best, apex, d)
                if above[c, k, 0] >= 0:
                    _offer(h, r, c, above[c, k, 0], above[c, k, 1], hp, tile_x, tile_y, best,
                           apex, d)
            _search(h, flat, offsets, prow, pcol, tile_x, tile_y, r, c, best, apex, stack, sb,
                    cb, ci, d)
            for q in range(4):
                out[q, r, c] = best[q]
                if apex[q, 0] >= 0:
                    prev[q, 0] = apex[q, 0]
                    prev[q, 1] = apex[q, 1]
                above[c, q, 0] = apex[q, 0]
                above[c, q, 1] = apex[q, 1]
        done[r] = 1


def quadrant_exact(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                   progress=None) -> np.ndarray:
    """Float64 ``(4, H, W)`` exact quadrant ratios of float64 unit heights ``h`` (C order),
    lower bounds within 1e-12 as :func:`~csm_assets.cones.exact.exact_ratios`' are.

    ``progress(done_rows, total_rows)`` is called now and then from this thread.
    """
    h = np.ascontiguousarray(h, dtype=np.float64)
    H, W = h.shape
    if h.size == 1:  # nothing is higher
        return np.full((4, H, W), max_ratio)
    wh = float(W) * float(H)
    flat, offsets, prow, pcol = build_pyramid(h)
    out = np.empty((4, H, W))
    done = np.zeros(H, np.uint8)
    cap = kernel_cap(max_ratio)
    cap2 = (cap * wh) ** 2
    run_chunks(lambda r0, r1: quadrant_rows(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2,
                                            r0, r1, out, done),
               H, done, progress, chunk=row_chunk(H))
    return safe_ratios(np.minimum(np.sqrt(out) / wh, cap), max_ratio)


def quadrant_cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact conservative cone ratio of every texel in each quadrant of directions.

    height: uint8 (/255), uint16 (/65535) or float ``(H, W)`` in ``[0, 1]``, any size
        from 1x1. A :class:`~csm_assets.Heightfield` is taken by its ``.data``.
    tile: True (the default), False, or ``(tile_x, tile_y)``: a ray wraps round a tiled axis.
    max_ratio: the cap (> 0); a quadrant with no higher texel gets it.

    Returns float32 ``(4, H, W)`` in the order of :data:`QUADRANTS` (+u+v, -u+v, -u-v, +u-v;
    u along columns, v along rows downward), each value rounded down from the float64 ratio
    so a stored cone is never wider than the exact one. The minimum over the first axis is
    :func:`csm_assets.cone_ratios` exactly. Raises ValueError on bad input.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(quadrant_exact(h, tx, ty, cap))
