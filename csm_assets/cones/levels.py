"""Exact cone ratios by one distance transform per height level.

For a level L, let D_L(p) be the distance from texel p to the nearest texel with
h >= L. Then ``ratio(p) = min over levels L > h(p) of D_L(p) / (L - h(p))``, the
minimum taken over the distinct heights of the map (each higher texel q is seen
at its own level L = h(q), where D_L(p) <= |q - p| and the nearest texel at or
above L is at least as good). So the result is exact for any data; the cost is
O(levels * H * W), which suits quantized maps (8-bit: at most 255 transforms).

Distances use exact integer arithmetic in float64: ``I = dx^2 H^2 + dy^2 W^2``
(so ``|q - p|_uv = sqrt(I) / (W H)``), exact while ``I < 2^53`` (textures up to
about 60000 texels a side). The transform is Felzenszwalb-Huttenlocher's:
a column pass (nearest feature row, wrapping round when tiling) and a row pass
(lower envelope of parabolas; when tiling, sources are repeated one period to
each side, only in the row buffer). Levels run in parallel, up to 2 at a time;
memory: the texture plus, per level running, one int32 and one float64 array
of its size.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..bands import each_band
from ..kernels import CACHE
from ..polling import run_chunks, thread_count

_INF_ROWS = 1 << 30
# levels run in parallel, each slot with its own (H, W) buffers (12 bytes a texel): two keep a
# step map within 40 bytes a texel on any machine (a 4096^2 terrain: 25 with one, 36 with two)
_MAX_SLOTS = 2


_FEW = 4096  # distinct heights that distinct_heights() counts in one pass; more: a sort


def distinct_heights(h: np.ndarray) -> np.ndarray:
    """``np.unique(h)`` of float64 heights ``h``: the sorted distinct values, in one pass over the map
    while there are at most :data:`_FEW` of them (a quantized map: tens of times quicker than its
    sort), else by ``np.unique``."""
    few, n = _distinct(np.ascontiguousarray(h, dtype=np.float64).reshape(-1), _FEW)
    return few[:n].copy() if n <= _FEW else np.unique(h)


@njit(cache=CACHE, nogil=True)
def _distinct(flat, cap):
    """(sorted distinct values of ``flat``, their count; ``cap + 1`` once it passes ``cap``)."""
    seen = np.empty(cap + 1)
    n = 0
    last = np.nan  # the value met last: runs of one height cost a comparison
    for x in flat:
        if x == last:
            continue
        last = x
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) // 2
            if seen[mid] < x:
                lo = mid + 1
            else:
                hi = mid
        if lo < n and seen[lo] == x:
            continue
        if n == cap:
            return seen, cap + 1
        seen[lo + 1:n + 1] = seen[lo:n].copy()
        seen[lo] = x
        n += 1
    return seen, n


@njit(cache=CACHE)
def _column_pass(h, level, tile_y, g, carry, first, last):
    """``g[r, c]``: rows from (r, c) to the nearest texel of column c with h >= level.

    Sweeps whole rows (cache friendly); ``carry``, ``first``, ``last``: int64 (W,) scratch.
    """
    H, W = h.shape
    carry[:] = _INF_ROWS
    first[:] = -1
    last[:] = -1
    for r in range(H):  # downward: distance to the nearest feature at or above
        for c in range(W):
            if h[r, c] >= level:
                carry[c] = 0
                if first[c] < 0:
                    first[c] = r
                last[c] = r
            elif carry[c] < _INF_ROWS:
                carry[c] += 1
            g[r, c] = carry[c]
    for c in range(W):  # upward, entering from below the last row
        carry[c] = first[c] if tile_y and first[c] >= 0 else _INF_ROWS
    for r in range(H - 1, -1, -1):
        for c in range(W):
            if g[r, c] == 0:
                carry[c] = 0
                continue
            if carry[c] < _INF_ROWS:
                carry[c] += 1
            d = carry[c]
            if tile_y and last[c] >= 0:
                d = min(d, r + H - last[c])  # upward round the top edge
            if d < g[r, c]:
                g[r, c] = d


@njit(cache=CACHE, error_model="numpy")
def _row_pass(h, level, tile_x, g, rowmin, best, v, fv, gv, z):
    """Lower envelope per row; lowers ``best`` (ratio^2 (W H)^2) where level helps.

    ``v``, ``fv`` (float64), ``gv`` (int64) of 2W + 1 and ``z`` of 2W + 2: scratch.
    """
    H, W = h.shape
    wh2 = float(W) * W / (float(H) * H)  # f of a source = dy^2 (W/H)^2, x in texels
    H2 = float(H) * H
    W2 = float(W) * W
    if tile_x:
        lo, hi = W // 2 - W, W + W // 2 + 1  # copies c' - W and c' + W where nearer
    else:
        lo, hi = 0, W
    for r in range(H):
        if rowmin[r] >= level:
            continue
        k = -1
        s = 0.0
        for qi in range(lo, hi):
            c = qi + W if qi < 0 else (qi - W if qi >= W else qi)
            gy = g[r, c]
            if gy >= _INF_ROWS:
                continue
            q = float(qi)
            fq = float(gy) * float(gy) * wh2
            while k >= 0:
                s = ((fq + q * q) - (fv[k] + v[k] * v[k])) / (2.0 * (q - v[k]))
                if s <= z[k]:
                    k -= 1
                else:
                    break
            k += 1
            v[k] = q
            fv[k] = fq
            gv[k] = gy
            z[k] = -np.inf if k == 0 else s
        if k < 0:
            continue  # no texel at or above level in reach of this row
        z[k + 1] = np.inf
        j = 0
        for c in range(W):
            hp = h[r, c]
            if hp >= level:
                continue
            while z[j + 1] < c:
                j += 1
            dx = c - v[j]
            dy = float(gv[j])
            dist = dx * dx * H2 + dy * dy * W2
            dh = level - hp
            ratio2 = dist / (dh * dh)  # the same float64 as every exact method's
            if ratio2 < best[r, c]:
                best[r, c] = ratio2


@njit(cache=CACHE, nogil=True, error_model="numpy")
def _slot(h, levels, t, nslots, tile_x, tile_y, rowmin, best, g, done):
    """Levels t, t + nslots, ... into ``best`` (this slot's own), ``done[i] = 1`` each."""
    W = h.shape[1]
    carry = np.empty(W, np.int64)
    first = np.empty(W, np.int64)
    last = np.empty(W, np.int64)
    v = np.empty(2 * W + 1, np.float64)
    fv = np.empty(2 * W + 1, np.float64)
    gv = np.empty(2 * W + 1, np.int64)
    z = np.empty(2 * W + 2, np.float64)
    for i in range(t, len(levels), nslots):
        _column_pass(h, levels[i], tile_y, g, carry, first, last)
        _row_pass(h, levels[i], tile_x, g, rowmin, best, v, fv, gv, z)
        done[i] = 1


def level_ratios(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                 progress=None) -> np.ndarray:
    """Float64 ``(H, W)`` exact ratios of float64 unit heights ``h`` (C order).

    Runs up to 2 levels at once (numba's thread count), each with a float64 and an
    int32 buffer of the texture's size. ``progress(done_levels, total_levels)`` is
    called now and then from this thread.
    """
    H, W = h.shape
    wh = float(W) * float(H)
    levels = distinct_heights(h)[1:]  # the lowest level has nothing below it
    slots = max(1, min(_MAX_SLOTS, thread_count(), len(levels)))
    best = np.empty((slots, H, W))
    each_band(H, W, lambda r0, r1: best[:, r0:r1].fill((max_ratio * wh) ** 2))
    g = np.empty((slots, H, W), np.int32)
    done = np.zeros(max(len(levels), 1), np.uint8)
    if len(levels) == 0:
        done[:] = 1
    rowmin = h.min(axis=1)
    run_chunks(lambda t, _, best=best, g=g: _slot(h, levels, t, slots, tile_x, tile_y, rowmin, best[t], g[t], done),
               slots, done, progress, threads=slots)
    del g  # the lambda that held it is gone too
    out = best[0] if slots == 1 else np.empty((H, W))  # the slots' minimum, a band at a time on threads

    def finish(r0, r1):
        o = np.minimum.reduce(best[:, r0:r1], axis=0, out=out[r0:r1])
        np.sqrt(o, out=o)
        o /= wh
        np.minimum(o, max_ratio, out=o)

    each_band(H, W, finish)
    return out
