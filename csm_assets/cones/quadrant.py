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
once, one search per 2x2 group of texels: a block is skipped when, for every quadrant, its
nearest offset from the group in that quadrant's direction cannot beat the group's largest best
of that quadrant with the group's lowest height (by :data:`~.pyramid.SLACK`: every exact method
gives the same float64, the minimum of ``d / (dh * dh)``), and each texel that passes is
offered to every texel of the group exactly. A group whose texels start from very different
bests (a local peak beside a pit, on rough maps: :data:`SPREAD`) is searched texel by texel
instead, as the group's bound would pair its widest cone with its lowest height. Serial
``nogil`` numba over chunks of group rows, run on threads by :mod:`csm_assets.polling`.
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


GROUP = 2  # texels are searched in GROUP x GROUP groups, one traversal per group


@njit(cache=CACHE, inline="always")
def _gaps(x0, x1, a, b, n, tile, scale):
    """``scale * offset^2`` of the nearest of a..b from the nearest of x0..x1 going +, and
    going -, on an axis of n texels (a lower bound for every x of x0..x1; inf where no x can
    reach the block that way)."""
    if a > x1:
        g = float(a - x1)
        w = float(x0 - b + n)
        return g * g * scale, (w * w * scale if tile else np.inf)
    if b < x0:
        g = float(x0 - b)
        w = float(a - x1 + n)
        return (w * w * scale if tile else np.inf), g * g * scale
    return 0.0, 0.0


@njit(cache=CACHE, inline="always")
def _offer(best, apex, g, q, d, dh2, qr, qc):
    """Lower texel g's best of quadrant q to ``d / dh2`` if lower (the apex to (qr, qc))."""
    if d < best[g, q] * dh2 * SLACK and d / dh2 < best[g, q]:
        best[g, q] = d / dh2
        apex[g, q, 0] = qr
        apex[g, q, 1] = qc
        return True
    return False


@njit(cache=CACHE, inline="always")
def _leaf(h, qr, qc, v, r0, r1, c0, c1, tile_x, tile_y, best, apex, live):
    """Lower the four bests of each texel of the group ``r0..r1`` x ``c0..c1`` by texel
    (qr, qc) of height v, in the quadrants of the bit mask ``live``; True if any."""
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    gw = c1 - c0 + 1
    lowered = False
    for a in range(r1 - r0 + 1):
        yp, ym = _gaps(r0 + a, r0 + a, qr, qr, H, tile_y, W2)
        for b in range(gw):
            dh = v - h[r0 + a, c0 + b]
            if dh <= 0.0:
                continue
            xp, xm = _gaps(c0 + b, c0 + b, qc, qc, W, tile_x, H2)
            dh2 = dh * dh
            g = a * gw + b
            if live & 1 and _offer(best, apex, g, 0, xp + yp, dh2, qr, qc):
                lowered = True
            if live & 2 and _offer(best, apex, g, 1, xm + yp, dh2, qr, qc):
                lowered = True
            if live & 4 and _offer(best, apex, g, 2, xm + ym, dh2, qr, qc):
                lowered = True
            if live & 8 and _offer(best, apex, g, 3, xp + ym, dh2, qr, qc):
                lowered = True
    return lowered


@njit(cache=CACHE, inline="always")
def _group_bounds(best, n):
    """The largest best of each quadrant over the group's n texels, times :data:`SLACK`:
    a block whose bound in quadrant q is not below the q-th skips that quadrant."""
    m0 = m1 = m2 = m3 = 0.0
    for g in range(n):
        m0 = max(m0, best[g, 0])
        m1 = max(m1, best[g, 1])
        m2 = max(m2, best[g, 2])
        m3 = max(m3, best[g, 3])
    return m0 * SLACK, m1 * SLACK, m2 * SLACK, m3 * SLACK


@njit(cache=CACHE, inline="always")
def _search(h, flat, offsets, prow, pcol, tile_x, tile_y, r0, r1, c0, c1, best, apex,
            stack, sb, cb, ci):
    """Lower ``best`` (float64 (n, 4), ratio^2 (W H)^2 per texel and quadrant) of the texels
    ``r0..r1`` x ``c0..c1`` (inclusive, n of them, row-major) by one depth-first search of the
    pyramid for the whole group; ``apex`` (int64 (n, 4, 2)) gets the texel of each best.

    A block is bounded for the group by its nearest offset from the group's span and the
    group's lowest texel, against the group's largest best of each quadrant; a
    texel that passes is then offered to each texel of the group exactly. ``stack`` (int64
    (S, 3)), ``sb`` (float64 (S, 4)), ``cb`` (float64 (4, 5)), ``ci`` (int64 (4, 2)):
    scratch space. Returns the number of blocks examined.
    """
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    gw = c1 - c0 + 1
    n = (r1 - r0 + 1) * gw
    hp = np.inf
    for g in range(n):
        hp = min(hp, h[r0 + g // gw, c0 + g % gw])
    top = len(offsets) - 1
    seen = 0
    if hp >= flat[offsets[top]]:
        return seen
    g0, g1, g2, g3 = _group_bounds(best, n)
    stack[0, 0] = top
    stack[0, 1] = 0
    stack[0, 2] = 0
    for q in range(4):
        sb[0, q] = 0.0
    sp = 1
    while sp > 0:
        sp -= 1
        if sb[sp, 0] >= g0 and sb[sp, 1] >= g1 and sb[sp, 2] >= g2 and sb[sp, 3] >= g3:
            continue
        kc = stack[sp, 0] - 1
        bi = stack[sp, 1]
        bj = stack[sp, 2]
        size = 1 << kc
        nr, nc = prow[kc], pcol[kc]
        base = offsets[kc]
        m = 0
        x0 = 2 * bj * size  # the two columns of children: their gaps, once
        xp0, xm0 = _gaps(c0, c1, x0, min(x0 + size, W) - 1, W, tile_x, H2)
        xp1, xm1 = _gaps(c0, c1, x0 + size, min(x0 + 2 * size, W) - 1, W, tile_x, H2)
        for a in range(2):
            ii = 2 * bi + a
            if ii >= nr:
                continue
            y0 = ii * size
            yp, ym = _gaps(r0, r1, y0, min(y0 + size, H) - 1, H, tile_y, W2)
            for b in range(2):
                jj = 2 * bj + b
                if jj >= nc:
                    continue
                seen += 1
                v = flat[base + ii * nc + jj]
                dh = v - hp
                if dh <= 0.0:
                    continue
                xp, xm = (xp0, xm0) if b == 0 else (xp1, xm1)
                d0 = xp + yp
                d1 = xm + yp
                d2 = xm + ym
                d3 = xp + ym
                dh2 = dh * dh
                key = np.inf
                live = 0
                if d0 < g0 * dh2:
                    key = d0
                    live = 1
                if d1 < g1 * dh2:
                    key = min(key, d1)
                    live |= 2
                if d2 < g2 * dh2:
                    key = min(key, d2)
                    live |= 4
                if d3 < g3 * dh2:
                    key = min(key, d3)
                    live |= 8
                if live == 0:
                    continue
                if kc == 0:  # a texel: its exact ratio for each texel of the group
                    if _leaf(h, ii, jj, v, r0, r1, c0, c1, tile_x, tile_y, best, apex, live):
                        g0, g1, g2, g3 = _group_bounds(best, n)
                    continue
                inv = 1.0 / dh2  # bounds, a little low: the skip test has SLACK to spare
                cb[m, 0] = key * inv
                cb[m, 1] = d0 * inv
                cb[m, 2] = d1 * inv
                cb[m, 3] = d2 * inv
                cb[m, 4] = d3 * inv
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


SPREAD = 64.0  # a group whose starting bests (ratio^2) differ more is searched texel by texel


@njit(cache=CACHE, inline="always")
def _alike(best, n):
    """Whether the n texels' starting bests are within :data:`SPREAD` in every quadrant."""
    for q in range(4):
        lo = hi = best[0, q]
        for g in range(1, n):
            lo = min(lo, best[g, q])
            hi = max(hi, best[g, q])
        if hi > SPREAD * lo:
            return False
    return True


@njit(cache=CACHE, inline="always")
def _seed(h, r, c, qr, qc, tile_x, tile_y, q, best, apex, g):
    """Lower texel g's (at (r, c)) best of quadrant q by texel (qr, qc) (-1: none)."""
    if qr < 0:
        return
    H, W = h.shape
    dh = h[qr, qc] - h[r, c]
    if dh <= 0.0:
        return
    xp, xm = _gaps(c, c, qc, qc, W, tile_x, float(H) * H)
    yp, ym = _gaps(r, r, qr, qr, H, tile_y, float(W) * W)
    _offer(best, apex, g, q, (xp if q == 0 or q == 3 else xm) + (yp if q < 2 else ym), dh * dh,
           qr, qc)


@njit(cache=CACHE, nogil=True)
def quadrant_rows(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2, g0, g1, out, done, seen):
    """Best ratio^2 (W H)^2 per quadrant of the rows of groups ``g0..g1`` (rows
    ``GROUP * g0`` up to ``GROUP * g1``) into ``out`` (float64 (4, H, W)), ``done[g] = 1``
    and ``seen[g]`` the blocks examined after group row g. Each texel's search starts from
    the bests that the apexes of its left neighbour and of the texel above (in this chunk)
    give: a tight start."""
    H, W = h.shape
    depth = len(offsets) + 1
    stack = np.empty((4 * depth, 3), np.int64)
    sb = np.empty((4 * depth, 4), np.float64)
    cb = np.empty((4, 5), np.float64)
    ci = np.empty((4, 2), np.int64)
    n = GROUP * GROUP
    best = np.empty((n, 4), np.float64)
    apex = np.empty((n, 4, 2), np.int64)
    left = np.empty((GROUP, 4, 2), np.int64)  # apexes of the texel left of each row's group
    above = np.full((W, 4, 2), -1, np.int64)  # the apexes found for the row above
    for gr in range(g0, g1):
        r0 = GROUP * gr
        r1 = min(r0 + GROUP, H) - 1
        left[:] = -1
        for c0 in range(0, W, GROUP):
            c1 = min(c0 + GROUP, W) - 1
            gw = c1 - c0 + 1
            m = (r1 - r0 + 1) * gw
            best[:] = cap2
            apex[:] = -1
            for g in range(m):
                r, c = r0 + g // gw, c0 + g % gw
                for q in range(4):
                    _seed(h, r, c, left[g // gw, q, 0], left[g // gw, q, 1], tile_x, tile_y,
                          q, best, apex, g)
                    _seed(h, r, c, above[c, q, 0], above[c, q, 1], tile_x, tile_y, q, best,
                          apex, g)
            if _alike(best, m):
                seen[gr] += _search(h, flat, offsets, prow, pcol, tile_x, tile_y, r0, r1, c0,
                                    c1, best, apex, stack, sb, cb, ci)
            else:  # a search per texel: the group's bound would be as loose as its widest cone
                for g in range(m):
                    r, c = r0 + g // gw, c0 + g % gw
                    seen[gr] += _search(h, flat, offsets, prow, pcol, tile_x, tile_y, r, r, c, c,
                                        best[g:g + 1], apex[g:g + 1], stack, sb, cb, ci)
            for g in range(m):
                r, c = r0 + g // gw, c0 + g % gw
                for q in range(4):
                    out[q, r, c] = best[g, q]
                    above[c, q, 0] = apex[g, q, 0]
                    above[c, q, 1] = apex[g, q, 1]
                    if c == c1:
                        left[g // gw, q, 0] = apex[g, q, 0]
                        left[g // gw, q, 1] = apex[g, q, 1]
        done[gr] = 1


def quadrant_exact(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                   progress=None, seen: np.ndarray | None = None, pyramid=None) -> np.ndarray:
    """Float64 ``(4, H, W)`` exact quadrant ratios of float64 unit heights ``h`` (C order),
    lower bounds within 1e-12 as :func:`~csm_assets.cones.exact.exact_ratios`' are.

    ``progress(done_rows, total_rows)`` is called now and then from this thread. ``seen``
    (int64 (1,), optional) gets the number of pyramid blocks the searches examined (a
    measure of the work that does not depend on the machine's load). pyramid: ``h``'s max
    pyramid when made already (:func:`~.pyramid.pyramid_heights`).
    """
    h = np.ascontiguousarray(h, dtype=np.float64)
    H, W = h.shape
    if h.size == 1:  # nothing is higher
        return np.full((4, H, W), max_ratio)
    wh = float(W) * float(H)
    flat, offsets, prow, pcol = pyramid or build_pyramid(h)
    out = np.empty((4, H, W))
    groups = -(-H // GROUP)  # rows of groups
    done = np.zeros(groups, np.uint8)
    counts = np.zeros(groups, np.int64)
    cap = kernel_cap(max_ratio)
    cap2 = (cap * wh) ** 2
    run_chunks(lambda g0, g1: quadrant_rows(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2,
                                            g0, g1, out, done, counts),
               groups, done, progress, chunk=row_chunk(groups))
    if seen is not None:
        seen[0] = counts.sum()
    out = np.sqrt(out, out=out)
    out /= wh
    return safe_ratios(np.minimum(out, cap, out=out), max_ratio)


def quadrant_cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact conservative cone ratio of every texel in each quadrant of directions.

    Args:
        height (numpy.ndarray | Heightfield): as for :func:`~csm_assets.cone_ratios`.
        tile (bool | tuple[bool, bool]): True (default), False, or ``(tile_x, tile_y)``.
        max_ratio (float): the cap (> 0); a quadrant with no higher texel gets it.

    Returns:
        Float32 ``(4, H, W)`` in the order of :data:`QUADRANTS` (+u+v, -u+v, -u-v, +u-v; u
        along columns, v down the rows), rounded down from float64. The minimum over the first
        axis is :func:`csm_assets.cone_ratios` exactly.

    Raises:
        ValueError: bad heights or ``max_ratio``, as for :func:`~csm_assets.cone_ratios`.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(quadrant_exact(h, tx, ty, cap))
