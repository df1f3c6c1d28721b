"""Exact cone ratios by branch and bound over a max-height pyramid.

Level k of the pyramid holds the maximum height of each 2^k x 2^k block (blocks at
the right and bottom edges are cut short). For texel p, no texel of a block B can
give a ratio below ``dist(p, B) / (max(B) - h(p))``, so a depth-first search from
the single top block skips every block whose bound is no better than the best
ratio found so far, and the texels it reaches give the exact ratio. The search
starts from the texel that was best for p's left neighbour, so the bound is tight
early. Exact for any heights (float, 16-bit); its cost depends on how many blocks
come near the cone's surface, not on the cone's width as a ring search's does.

Distances are exact integers in float64 (``dx^2 H^2 + dy^2 W^2``, as in
:mod:`csm_assets.cones.levels`); block distances on a tiled axis are taken the short way
round. Memory: the pyramid, a float64 copy of the texture plus a third more.

Every exact method gives the same float64: the minimum of ``d / (dh * dh)`` over the
candidates (ring, levels and :mod:`csm_assets.cones.quadrant` too). A texel is compared by
that value, and a block is skipped only when its bound beats ``best`` by :data:`SLACK`
(relative), so float rounding never skips a texel that would lower ``best`` by an ulp.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..bands import each_band, unit_rows
from ..kernels import CACHE
from ..polling import row_chunk, run_chunks

SLACK = 1.0 + 1e-12  # a bound must beat ``best`` by this factor to skip a block


def build_pyramid(h: np.ndarray):
    """Max pyramid of float64 ``(H, W)`` ``h``: (flat values, offsets, rows, cols) per level;
    level 0, ``flat[:H * W]``, is a copy of ``h``."""
    return pyramid_heights(h)[1]


def pyramid_heights(a: np.ndarray):
    """(h, pyramid): float64 unit heights ``h`` of validated heights ``a`` (uint8/uint16 codes or
    float unit heights, ``(H, W)``) and the max pyramid of :func:`build_pyramid`, ``h`` being its
    level 0 (a view): one float64 buffer of 4/3 of the map, each level made from the one below
    without a padded copy."""
    H, W = a.shape
    shapes = [(H, W)]
    while shapes[-1] != (1, 1):
        rh, rw = shapes[-1]
        shapes.append(((rh + 1) // 2, (rw + 1) // 2))
    sizes = [r * c for r, c in shapes]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    flat = np.empty(int(sum(sizes)))
    h = flat[:H * W].reshape(H, W)

    def fill(r0, r1):
        h[r0:r1] = unit_rows(a, slice(r0, r1))

    each_band(H, W, fill)
    for k in range(1, len(shapes)):
        (rh, rw), (nh, nw) = shapes[k - 1], shapes[k]
        lo = flat[offsets[k - 1]:offsets[k - 1] + sizes[k - 1]].reshape(rh, rw)
        hi = flat[offsets[k]:offsets[k] + sizes[k]].reshape(nh, nw)
        hi[:rh // 2, :rw // 2] = np.maximum(np.maximum(lo[0:rh - 1:2, 0:rw - 1:2], lo[1::2, 0:rw - 1:2]),
                                            np.maximum(lo[0:rh - 1:2, 1::2], lo[1::2, 1::2]))
        if rw % 2:  # the last column of blocks: one texel wide
            hi[:rh // 2, -1] = np.maximum(lo[0:rh - 1:2, -1], lo[1::2, -1])
        if rh % 2:  # the last row of blocks: one texel high
            hi[-1, :rw // 2] = np.maximum(lo[-1, 0:rw - 1:2], lo[-1, 1::2])
        if rh % 2 and rw % 2:
            hi[-1, -1] = lo[-1, -1]
    rows = np.array([s[0] for s in shapes], np.int64)
    cols = np.array([s[1] for s in shapes], np.int64)
    return h, (flat, offsets, rows, cols)


@njit(cache=CACHE, inline="always")
def _gap(x, a, b, n, tile):
    """Texels from x to the nearest of a..b on an axis of n texels (short way round if tile)."""
    if x < a:
        d = a - x
        return min(d, n - b + x) if tile else d
    if x > b:
        d = x - b
        return min(d, n - x + a) if tile else d
    return 0


@njit(cache=CACHE, inline="always")
def _search(h, flat, offsets, prow, pcol, tile_x, tile_y, best, r, c, qr, qc, stack, cb, ci):
    """Best ratio^2 (W H)^2 of texel (r, c) below ``best``, starting from apex (qr, qc).

    Returns (best, apex row, apex col, blocks examined); the apex is -1, -1 when no
    texel beats the starting ``best``. ``stack`` (int64 (S, 3)), ``cb``/``ci``:
    scratch space.
    """
    H, W = h.shape
    H2 = float(H) * H
    W2 = float(W) * W
    hp = h[r, c]
    top = len(offsets) - 1
    seen = 0
    ar, ac = -1, -1
    if qr >= 0:  # the neighbour's apex: a tight start
        dh = h[qr, qc] - hp
        if dh > 0.0:
            dy = _gap(r, qr, qr, H, tile_y)
            dx = _gap(c, qc, qc, W, tile_x)
            d = dx * dx * H2 + dy * dy * W2
            if d / (dh * dh) < best:
                best = d / (dh * dh)
                ar, ac = qr, qc
    if hp >= flat[offsets[top]]:
        return best, ar, ac, seen
    stack[0, 0] = top
    stack[0, 1] = 0
    stack[0, 2] = 0
    sb = cb[4:]  # bounds of the stacked blocks; cb[:4] sorts the children
    sb[0] = 0.0
    sp = 1
    while sp > 0:
        sp -= 1
        if sb[sp] >= best * SLACK:
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
            dy = _gap(r, y0, min(y0 + size, H) - 1, H, tile_y)
            for b in range(2):
                jj = 2 * bj + b
                if jj >= nc:
                    continue
                seen += 1
                dh = flat[base + ii * nc + jj] - hp
                if dh <= 0.0:
                    continue
                x0 = jj * size
                dx = _gap(c, x0, min(x0 + size, W) - 1, W, tile_x)
                d = dx * dx * H2 + dy * dy * W2
                if d >= best * dh * dh * SLACK:
                    continue
                bound = d / (dh * dh)
                if kc == 0:  # a texel: its exact ratio
                    if bound < best:
                        best = bound
                        ar, ac = ii, jj
                    continue
                t = m  # insert, largest bound first: the nearest child is popped first
                while t > 0 and cb[t - 1] < bound:
                    cb[t] = cb[t - 1]
                    ci[t, 0] = ci[t - 1, 0]
                    ci[t, 1] = ci[t - 1, 1]
                    t -= 1
                cb[t] = bound
                ci[t, 0] = ii
                ci[t, 1] = jj
                m += 1
        for t in range(m):
            stack[sp, 0] = kc
            stack[sp, 1] = ci[t, 0]
            stack[sp, 2] = ci[t, 1]
            sb[sp] = cb[t]
            sp += 1
    return best, ar, ac, seen


@njit(cache=CACHE, nogil=True)
def search_texels(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2, start, stop, rows, cols,
                  out, seen, done):
    """Best ratio^2 (W H)^2 by the pyramid search, one kernel for a map and for samples.

    Whole map (``rows`` empty): texels ``start..stop`` in row-major order into the flat
    ``out`` (H*W), each search starting from the apex found for its left neighbour,
    ``done[r] = 1`` after row r. Samples: texels ``(rows[i], cols[i])`` into ``out[i]``,
    blocks examined into ``seen[i]`` (no neighbour hint: the cost of a cold search).
    """
    W = h.shape[1]
    depth = len(offsets) + 1
    stack = np.empty((4 * depth, 3), np.int64)
    cb = np.empty(4 + 4 * depth, np.float64)
    ci = np.empty((4, 2), np.int64)
    qr, qc = -1, -1
    for i in range(start, stop):
        if rows.size:
            r, c = np.int64(rows[i]), np.int64(cols[i])
        else:
            r, c = i // W, i % W
            if c == 0:
                qr, qc = -1, -1
        best, ar, ac, n = _search(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2,
                                  r, c, qr, qc, stack, cb, ci)
        out[i] = best
        if rows.size:
            seen[i] = n
        else:
            if ar >= 0:
                qr, qc = ar, ac
            if c == W - 1:
                done[r] = 1


_NONE = np.zeros(0, np.int64)
_NO_ROWS = np.zeros(0, np.uint8)


def sample_searches(h, pyramid, tile_x, tile_y, cap2, rows, cols):
    """(best ratio^2 (W H)^2, blocks examined) of texels (rows[i], cols[i]), cold searches."""
    flat, offsets, prow, pcol = pyramid
    best = np.empty(len(rows))
    seen = np.zeros(len(rows), np.int64)
    done = np.zeros(len(rows), np.uint8)
    rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
    run_chunks(lambda a, b: search_texels(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2,
                                          a, b, rows, cols, best, seen, _NO_ROWS),
               len(rows), done, None, chunk=64)
    return best, seen


def pyramid_ratios(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                   progress=None, pyramid=None, rows=None) -> np.ndarray:
    """Float64 ``(H, W)`` exact ratios of float64 unit heights ``h`` (C order).

    ``progress(done_rows, total_rows)`` is called now and then from this thread. pyramid:
    ``h``'s :func:`build_pyramid`, when made already (:func:`pyramid_heights`). rows: ``(r0, r1)``
    to search those rows only, returned as ``(r1 - r0, W)`` (the same values).
    """
    H, W = h.shape
    r0, r1 = rows or (0, H)
    wh = float(W) * float(H)
    if h.size == 1:  # nothing is higher
        return np.full((r1 - r0, W), max_ratio)
    flat, offsets, prow, pcol = pyramid or build_pyramid(h)
    out = np.empty(h.size)  # only rows r0..r1 are written (and take memory)
    marks = np.zeros(H, np.uint8)  # the kernel marks rows by their index in the map
    cap2 = (max_ratio * wh) ** 2
    run_chunks(lambda a, b: search_texels(h, flat, offsets, prow, pcol, tile_x, tile_y, cap2,
                                          (r0 + a) * W, (r0 + b) * W, _NONE, _NONE, out, _NONE, marks),
               r1 - r0, marks[r0:r1], progress, chunk=row_chunk(r1 - r0))
    out = out[r0 * W:r1 * W] if rows else out
    out = np.sqrt(out, out=out).reshape(r1 - r0, W)
    out /= wh
    return np.minimum(out, max_ratio, out=out)
