"""mikktspace.c's welding and neighbour search, ported so that their order effects agree.

Which corners count as one vertex is plain float equality, but the *index* each welded
vertex gets (the first corner its hash grid and kd-split meet) orders the edge sort, and
mikktspace.c's BuildNeighborsFast leaves the last run of each sorting pass unsorted, so
on non-manifold edges which triangles become neighbours depends on those indices and on
its seeded quicksort. Both are reproduced here exactly (as compiled for x86-64).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels import CACHE, run

_CELLS = 2048
_SORT_SEED = 39871946  # INTERNAL_RND_SORT_SEED


def corner_ids(p, n, uv, interpret: bool = False) -> np.ndarray:
    """int64 ``(C,)``: the welded index of every corner, as GenerateSharedVerticesIndexList.

    Identical corners (float ``==`` on position, normal and uv) share one index, that of
    the corner (``4 * face + vertex``) mikktspace.c's hash grid and kd-split meet first.
    The values matter beyond equality: the edge sort that finds neighbours depends on them.
    ``interpret``: run the kernel's Python source (:func:`csm_assets.kernels.run`).
    """
    key = np.ascontiguousarray(np.concatenate([p, n, uv], axis=1), dtype=np.float32)
    return run(_weld, key, interpret=interpret)


@njit(cache=CACHE, error_model="numpy")
def _grid_cell(fmin, fmax, val):
    """FindGridCell, float32; NaN and out-of-range go where x86's (int) conversion sends them."""
    fi = np.float32(_CELLS) * ((val - fmin) / (fmax - fmin))
    if not fi >= 0 or fi >= np.float32(2147483648.0):
        return 0
    return min(int(fi), _CELLS - 1)


@njit(cache=CACHE, error_model="numpy")
def _weld(key):
    """GenerateSharedVerticesIndexList on float32 ``(C, 8)`` corner keys (pos, normal, uv)."""
    c = key.shape[0]
    ids = np.empty(c, np.int64)
    for i in range(c):
        ids[i] = (i // 3) * 4 + i % 3
    vmin = key[0, :3].copy()
    vmax = key[0, :3].copy()
    for i in range(1, c):
        for a in range(3):
            if vmin[a] > key[i, a]:
                vmin[a] = key[i, a]
            elif vmax[a] < key[i, a]:
                vmax[a] = key[i, a]
    dim = vmax - vmin
    ch = 0
    if dim[1] > dim[0] and dim[1] > dim[2]:
        ch = 1
    elif dim[2] > dim[0]:
        ch = 2
    cell = np.empty(c, np.int64)
    count = np.zeros(_CELLS + 1, np.int64)
    for i in range(c):
        cell[i] = _grid_cell(vmin[ch], vmax[ch], key[i, ch])
        count[cell[i] + 1] += 1
    offs = np.cumsum(count)
    table = np.empty(c, np.int64)
    fill = offs[:-1].copy()
    for i in range(c):
        table[fill[cell[i]]] = i
        fill[cell[i]] += 1
    tmp_p = np.empty((c, 3), np.float32)
    tmp_i = np.empty(c, np.int64)
    stack = np.empty((2 * c + 2, 2), np.int64)
    for k in range(_CELLS):
        lo, hi = offs[k], offs[k + 1]
        if hi - lo < 2:
            continue
        for e in range(lo, hi):
            tmp_p[e] = key[table[e], :3]
            tmp_i[e] = table[e]
        _merge_verts(key, ids, tmp_p, tmp_i, lo, hi - 1, stack)
    return ids


@njit(cache=CACHE, error_model="numpy")
def _merge_verts(key, ids, tmp_p, tmp_i, left, right, stack):
    """MergeVertsFast: split at the middle of the widest axis until values stop differing."""
    stack[0, 0] = left
    stack[0, 1] = right
    sp = 1
    half = np.float32(0.5)
    while sp > 0:
        sp -= 1
        lo = stack[sp, 0]
        hi = stack[sp, 1]
        fmin = tmp_p[lo].copy()
        fmax = tmp_p[lo].copy()
        for e in range(lo + 1, hi + 1):
            for a in range(3):
                if fmin[a] > tmp_p[e, a]:
                    fmin[a] = tmp_p[e, a]
                if fmax[a] < tmp_p[e, a]:
                    fmax[a] = tmp_p[e, a]
        dx = fmax[0] - fmin[0]
        dy = fmax[1] - fmin[1]
        dz = fmax[2] - fmin[2]
        ch = 0
        if dy > dx and dy > dz:
            ch = 1
        elif dz > dx:
            ch = 2
        sep = half * (fmax[ch] + fmin[ch])
        if not np.isfinite(sep):
            continue
        if sep >= fmax[ch] or sep <= fmin[ch]:
            for e in range(lo, hi + 1):
                i = tmp_i[e]
                ki = key[i]
                for e2 in range(lo, e):
                    i2 = tmp_i[e2]
                    k2 = key[i2]
                    same = True
                    for a in range(8):
                        if ki[a] != k2[a]:
                            same = False
                            break
                    if same:
                        ids[i] = ids[i2]
                        break
            continue
        il = lo
        ir = hi
        while il < ir:
            ready_l = False
            ready_r = False
            while not ready_l and il < ir:
                ready_l = not (tmp_p[il, ch] < sep)
                if not ready_l:
                    il += 1
            while not ready_r and il < ir:
                ready_r = tmp_p[ir, ch] < sep
                if not ready_r:
                    ir -= 1
            if ready_l and ready_r:
                for a in range(3):
                    tmp_p[il, a], tmp_p[ir, a] = tmp_p[ir, a], tmp_p[il, a]
                tmp_i[il], tmp_i[ir] = tmp_i[ir], tmp_i[il]
                il += 1
                ir -= 1
        if il == ir:
            if tmp_p[ir, ch] < sep:
                il += 1
            else:
                ir -= 1
        if lo < ir:
            stack[sp, 0] = lo
            stack[sp, 1] = ir
            sp += 1
        if il < hi:
            stack[sp, 0] = il
            stack[sp, 1] = hi
            sp += 1


@njit(cache=CACHE, error_model="numpy")
def _quicksort_edges(edges, left, right, ch, seed):
    """QuickSortEdges on column ``ch`` of int64 ``(E, 3)`` rows, with its seeded pivots."""
    stack = np.empty((64 + 2 * (right - left + 1), 3), np.int64)
    stack[0, 0] = left
    stack[0, 1] = right
    stack[0, 2] = seed
    sp = 1
    mask = np.int64(0xFFFFFFFF)
    while sp > 0:
        sp -= 1
        lo = stack[sp, 0]
        hi = stack[sp, 1]
        s = stack[sp, 2]
        n = hi - lo + 1
        if n < 2:
            continue
        if n == 2:
            if edges[lo, ch] > edges[hi, ch]:
                for a in range(3):
                    edges[lo, a], edges[hi, a] = edges[hi, a], edges[lo, a]
            continue
        t = s & 31
        if t != 0:
            t = ((s << t) | (s >> (32 - t))) & mask
        else:
            t = s
        s = (s + t + 3) & mask
        mid = edges[lo + s % n, ch]
        il = lo
        ir = hi
        while True:
            while edges[il, ch] < mid:
                il += 1
            while edges[ir, ch] > mid:
                ir -= 1
            if il <= ir:
                for a in range(3):
                    edges[il, a], edges[ir, a] = edges[ir, a], edges[il, a]
                il += 1
                ir -= 1
            if il > ir:
                break
        if lo < ir:
            stack[sp, 0] = lo
            stack[sp, 1] = ir
            stack[sp, 2] = s
            sp += 1
        if il < hi:
            stack[sp, 0] = il
            stack[sp, 1] = hi
            stack[sp, 2] = s
            sp += 1


@njit(cache=CACHE, error_model="numpy")
def _get_edge(ids, f, i0, i1):
    """GetEdge: edge number of triangle f holding ids i0, i1, and its ordered ends."""
    if ids[f, 0] == i0 or ids[f, 0] == i1:
        if ids[f, 1] == i0 or ids[f, 1] == i1:
            return 0, ids[f, 0], ids[f, 1]
        return 2, ids[f, 2], ids[f, 0]
    return 1, ids[f, 1], ids[f, 2]


@njit(cache=CACHE, error_model="numpy")
def neighbours(ids):
    """int64 ``(T, 3)``: the triangle across edge i (corner i to i+1), or -1.

    BuildNeighborsFast: edges (min id, max id, triangle) sorted by mikktspace.c's own
    quicksort on the first key, then within runs on the second and third, where it leaves
    the last run of each pass unsorted (so its order, and which edges pair up there,
    depends on that quicksort); then each unpaired edge takes the first following
    unpaired edge of opposite winding in the same run.
    """
    nt = ids.shape[0]
    ne = nt * 3
    edges = np.empty((ne, 3), np.int64)
    for f in range(nt):
        for i in range(3):
            a = ids[f, i]
            b = ids[f, (i + 1) % 3]
            edges[f * 3 + i, 0] = min(a, b)
            edges[f * 3 + i, 1] = max(a, b)
            edges[f * 3 + i, 2] = f
    _quicksort_edges(edges, 0, ne - 1, 0, _SORT_SEED)
    start = 0
    for i in range(1, ne):
        if edges[start, 0] != edges[i, 0]:
            _quicksort_edges(edges, start, i - 1, 1, _SORT_SEED)
            start = i
    start = 0
    for i in range(1, ne):
        if edges[start, 0] != edges[i, 0] or edges[start, 1] != edges[i, 1]:
            _quicksort_edges(edges, start, i - 1, 2, _SORT_SEED)
            start = i
    nb = np.full((nt, 3), -1, np.int64)
    for k in range(ne):
        i0 = edges[k, 0]
        i1 = edges[k, 1]
        f = edges[k, 2]
        ea, a0, a1 = _get_edge(ids, f, i0, i1)
        if nb[f, ea] != -1:
            continue
        j = k + 1
        while j < ne and edges[j, 0] == i0 and edges[j, 1] == i1:
            t = edges[j, 2]
            eb, b1, b0 = _get_edge(ids, t, i0, i1)
            if a0 == b0 and a1 == b1 and nb[t, eb] == -1:
                nb[f, ea] = t
                nb[t, eb] = f
                break
            j += 1
    return nb
