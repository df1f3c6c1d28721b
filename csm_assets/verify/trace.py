"""Exact ray / heightfield intersection on the CPU: the reference the shaders are checked against.

The surface is the one a GPU samples with bilinear filtering: heights sit at texel
centres, ``uv = ((col + 0.5) / W, (row + 0.5) / H)`` (v grows downward, DESIGN.md),
and between four neighbouring centres the surface is their bilinear interpolation.
Beyond the outer centres, ``tile=True`` wraps (GL ``REPEAT``): the field repeats
forever in u and v. ``tile=False`` clamps (GL ``CLAMP_TO_EDGE``): the last half
texel is flat, and only ``uv`` in ``[0, 1]`` belongs to the field, which is a solid
block there (POV-Ray's box): a ray that leaves it through a side misses, one that
enters through a side below the surface hits at the entry.

The walk is POV-Ray's: clip the ray to the field's bounding box (heights between
the map's min and max; uv in ``[0, 1]`` without tiling), then a digital
differential analyzer visits the cells between texel centres in ray order, and in
each cell the bilinear patch meets the ray where a quadratic in ``t`` vanishes,
solved in closed form. The first root is the exact first hit (float64).

Cost: a ray visits at most the cells between where it enters the box and where it leaves
it: ``W + H + 2`` without tiling, and with tiling its run until it falls under the lowest
height, ``depth * W * cot(elevation)`` texels for a ray from the top at ``elevation`` over a
relief ``depth`` uv units deep, unbounded as the ray turns horizontal. A call spends at most
``budget`` cells on its rays in all (besides :data:`MIN_CELLS` a ray, that every ray gets):
each ray first gets an equal share, and the rays still going then share what is left, in
passes that at least double their allowance. A ray still going when the budget
(or ``max_cells``) is spent is unresolved: ``t`` NaN, not a hit, so a caller leaves it out of
what it compares rather than call it a miss.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..heightfield import tile_pair, unit_heights
from ..kernels import CACHE

DEFAULT_MAX_CELLS = 1 << 20
CELL_BUDGET = 1 << 25  # cells one call visits in all (besides MIN_CELLS a ray): about 2 s
MIN_CELLS = 64  # cells every ray may visit whatever the budget (rays from the top mostly hit within a few)


def trace_heightfield(height, origins, directions, *, tile=True, max_cells=DEFAULT_MAX_CELLS, budget=CELL_BUDGET):
    """The first hit of each ray with the bilinear heightfield (texture space).

    A ray whose origin is under the surface hits at ``t = 0`` (or where it enters the
    clipped box). A ray still going after ``max_cells`` or the ``budget`` (only a nearly
    horizontal one in a tiled field) is unresolved: ``t`` NaN.

    Args:
        height (numpy.ndarray | Heightfield): ``(H, W)`` uint8, uint16 or float in ``[0, 1]``
            (image order, 1 = top).
        origins (numpy.ndarray): ``(N, 3)`` (or ``(3,)``) as ``(u, v, z)``; z is height.
        directions (numpy.ndarray): the same shape; need not be unit length (``t`` is
            measured in their length); non-zero.
        tile (bool | tuple[bool, bool]): wrap (repeat) or clamp at the edges.
        max_cells (int): the most cells one ray visits (>= 1).
        budget (int): the most cells all rays visit together, beyond :data:`MIN_CELLS` each.

    Returns:
        ``(hit_uv, t, hit_mask)``: float64 ``(N, 2)`` hit positions (not wrapped into
        ``[0, 1]`` when tiling; NaN on a miss), float64 ``(N,)`` ray parameters (inf on a
        miss, NaN when unresolved) and bool ``(N,)``.

    Raises:
        ValueError: bad heights, rays not ``(N, 3)``, not finite, of different shapes, a zero
            direction, or ``max_cells`` < 1.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    o = _rays(origins, "origins")
    d = _rays(directions, "directions")
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} must have the same shape")
    if not (np.abs(d).sum(axis=1) > 0).all():
        raise ValueError("every direction must be non-zero")
    if int(max_cells) < 1:
        raise ValueError(f"max_cells must be >= 1, got {max_cells!r}")
    return trace_unit(np.ascontiguousarray(h), o, d, tx, ty, max_cells=max_cells, budget=budget)


def trace_unit(h, o, d, tx: bool, ty: bool, *, max_cells=DEFAULT_MAX_CELLS, budget=CELL_BUDGET):
    """:func:`trace_heightfield` of C-ordered float64 unit heights ``h`` and float64 rays ``o``, ``d``
    ``(N, 3)`` already checked, tiled along x and y as ``tx``, ``ty`` say (no copy of ``h``: one map's
    heights can serve many calls, from several threads: the kernel releases the GIL)."""
    n = len(o)
    cap = min(int(max_cells), max(int(budget) // max(n, 1), MIN_CELLS))
    uv, t, hit, cells = _trace(h, o, d, tx, ty, cap)
    left = int(budget) - int(cells.sum())
    todo = np.flatnonzero(np.isnan(t))
    while todo.size and cap < int(max_cells):
        more = min(int(max_cells), left // todo.size)
        if more < 2 * cap:  # a pass walks its rays again from the start: only worth it at twice the cells
            break
        cap = more
        uv[todo], t[todo], hit[todo], spent = _trace(h, o[todo], d[todo], tx, ty, cap)
        left -= int(spent.sum())
        todo = todo[np.isnan(t[todo])]
    return uv, t, hit


def rays_to_field(origins, directions, field_to_world):
    """World rays into the field's texture space ``(u, v, z)``.

    field_to_world: ``(4, 4)`` affine matrix taking ``(u, v, z, 1)`` to world.
    Points get its full inverse; directions only the inverse of its linear part
    (no translation), and are not renormalized, so a ray parameter ``t`` names
    the same point in both spaces. (POV-Ray's height field, which also moves
    rays into the field's space, reported rotated fields losing parts.)
    Returns float64 ``(N, 3)`` origins and directions.
    """
    m = np.asarray(field_to_world, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"field_to_world must be a finite (4, 4) matrix, got shape {m.shape}")
    if not np.allclose(m[3], [0, 0, 0, 1]):
        raise ValueError("field_to_world must be affine (last row 0, 0, 0, 1)")
    inv = np.linalg.inv(m)
    o = _rays(origins, "origins")
    d = _rays(directions, "directions")
    return o @ inv[:3, :3].T + inv[:3, 3], d @ inv[:3, :3].T


def trace_heightfield_world(height, origins, directions, field_to_world, *, tile=True,
                            max_cells=DEFAULT_MAX_CELLS, budget=CELL_BUDGET):
    """:func:`trace_heightfield` for world-space rays and a placed field.

    Args:
        height (numpy.ndarray | Heightfield): as for :func:`trace_heightfield`.
        origins (numpy.ndarray): world ``(N, 3)`` (or ``(3,)``).
        directions (numpy.ndarray): world, the same shape; not renormalized.
        field_to_world (numpy.ndarray): ``(4, 4)`` affine matrix taking ``(u, v, z, 1)`` to
            world.
        tile (bool | tuple[bool, bool]): as for :func:`trace_heightfield`.
        max_cells (int): as for :func:`trace_heightfield`.
        budget (int): as for :func:`trace_heightfield`.

    Returns:
        ``(hit_uv, t, hit_mask)`` with ``t`` along the world directions as given (the world
        hit is ``origin + t * direction``).

    Raises:
        ValueError: as :func:`trace_heightfield`, or ``field_to_world`` not a finite
            ``(4, 4)`` matrix.
    """
    o, d = rays_to_field(origins, directions, field_to_world)
    return trace_heightfield(height, o, d, tile=tile, max_cells=max_cells, budget=budget)


def _rays(a, name):
    r = np.asarray(a, dtype=np.float64)
    if r.ndim == 1:
        r = r[None, :]
    if r.ndim != 2 or r.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {np.shape(a)}")
    if not np.isfinite(r).all():
        raise ValueError(f"{name} contain NaN or infinite values")
    return np.ascontiguousarray(r)


@njit(cache=CACHE, nogil=True)
def _trace(h, o, d, tx, ty, max_cells):
    n = o.shape[0]
    uv = np.full((n, 2), np.nan)
    tt = np.full(n, np.inf)
    hit = np.zeros(n, dtype=np.bool_)
    cells = np.zeros(n, dtype=np.int64)
    hmin = h.min()
    hmax = h.max()
    rows, cols = h.shape
    for k in range(n):
        # cell space: x = u*W - 0.5 so that texel centres sit on integers
        ox = o[k, 0] * cols - 0.5
        oy = o[k, 1] * rows - 0.5
        oz = o[k, 2]
        dx = d[k, 0] * cols
        dy = d[k, 1] * rows
        dz = d[k, 2]
        t, cells[k] = _ray_cells(h, ox, oy, oz, dx, dy, dz, hmin, hmax, tx, ty, max_cells)
        if np.isnan(t):
            tt[k] = np.nan
        elif t < np.inf:
            tt[k] = t
            hit[k] = True
            uv[k, 0] = (ox + dx * t + 0.5) / cols
            uv[k, 1] = (oy + dy * t + 0.5) / rows
    return uv, tt, hit, cells


@njit(cache=CACHE)
def _slab(o, dd, lo, hi, t0, t1):
    """Clip [t0, t1] to lo <= o + dd*t <= hi; returns (t0, t1), empty when t0 > t1."""
    if dd == 0.0:
        if o < lo or o > hi:
            return 1.0, 0.0
        return t0, t1
    a = (lo - o) / dd
    b = (hi - o) / dd
    if a > b:
        a, b = b, a
    return max(t0, a), min(t1, b)


@njit(cache=CACHE)
def _ray_cells(h, ox, oy, oz, dx, dy, dz, hmin, hmax, tx, ty, max_cells):
    """(first hit parameter of one ray in cell space, inf for none, NaN when still going after
    ``max_cells``; the cells visited)."""
    rows, cols = h.shape
    t0, t1 = 0.0, np.inf
    # the box: above hmax nothing is hit, and at hmin everything is under the surface
    if dz < 0.0:
        t0 = max(t0, (hmax - oz) / dz)
        t1 = max((hmin - oz) / dz, 0.0)  # an origin under hmin hits at once
    elif oz > hmax:
        return np.inf, 0
    elif dz > 0.0:
        t1 = (hmax - oz) / dz
    if not tx:
        t0, t1 = _slab(ox, dx, -0.5, cols - 0.5, t0, t1)
    if not ty:
        t0, t1 = _slab(oy, dy, -0.5, rows - 0.5, t0, t1)
    if t0 > t1:
        return np.inf, 0
    px = ox + dx * t0
    py = oy + dy * t0
    i = int(np.floor(px))
    j = int(np.floor(py))
    if dx < 0.0 and px == i:
        i -= 1
    if dy < 0.0 and py == j:
        j -= 1
    if not tx:  # rounding at the box's faces must not leave the clamped domain
        i = min(max(i, -1), cols - 1)
    if not ty:
        j = min(max(j, -1), rows - 1)
    ta = t0
    for k in range(max_cells):
        if dx > 0.0:
            nx = (i + 1 - ox) / dx
        elif dx < 0.0:
            nx = (i - ox) / dx
        else:
            nx = np.inf
        if dy > 0.0:
            ny = (j + 1 - oy) / dy
        elif dy < 0.0:
            ny = (j - oy) / dy
        else:
            ny = np.inf
        tb = min(nx, ny, t1)
        if tb < ta:
            tb = ta
        s = _cell_hit(h, i, j, ox + dx * ta - i, oy + dy * ta - j, oz + dz * ta, dx, dy, dz,
                      tb - ta, tx, ty)
        if s >= 0.0:
            return ta + s, k + 1
        if tb >= t1:
            return np.inf, k + 1
        if nx <= ny:
            i += 1 if dx > 0.0 else -1
        else:
            j += 1 if dy > 0.0 else -1
        ta = tb
    return np.nan, max_cells


@njit(cache=CACHE)
def _index(k, n, wrap):
    if wrap:
        return k % n
    return min(max(k, 0), n - 1)


@njit(cache=CACHE)
def _cell_hit(h, i, j, ax, ay, az, dx, dy, dz, length, tx, ty):
    """Smallest s in [0, length] where the ray meets cell (i, j)'s bilinear patch, or -1.

    The ray in the cell: fx = ax + dx*s, fy = ay + dy*s, z = az + dz*s. With the
    patch S = c00 + e1 fx + e2 fy + e3 fx fy, g(s) = z - S = A s^2 + B s + C.
    """
    rows, cols = h.shape
    i0, i1 = _index(i, cols, tx), _index(i + 1, cols, tx)
    j0, j1 = _index(j, rows, ty), _index(j + 1, rows, ty)
    c00, c10, c01, c11 = h[j0, i0], h[j0, i1], h[j1, i0], h[j1, i1]
    e1 = c10 - c00
    e2 = c01 - c00
    e3 = c00 - c10 - c01 + c11
    c = az - (c00 + e1 * ax + e2 * ay + e3 * ax * ay)
    if c <= 0.0:
        return 0.0
    b = dz - (e1 * dx + e2 * dy + e3 * (ax * dy + ay * dx))
    a = -e3 * dx * dy
    best = np.inf
    disc = b * b - 4.0 * a * c
    if disc >= 0.0:
        q = -0.5 * (b + np.copysign(np.sqrt(disc), b))
        if q != 0.0:
            best = _first_in(c / q, best, length)
        if a != 0.0:
            best = _first_in(q / a, best, length)
    if best < np.inf:
        return best
    if (a * length + b) * length + c <= 0.0:  # under at the exit: a crossing rounding hid
        lo, hi = 0.0, length
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if (a * mid + b) * mid + c <= 0.0:
                hi = mid
            else:
                lo = mid
        return hi
    return -1.0


@njit(cache=CACHE)
def _first_in(r, best, length):
    tol = 1e-12 * (1.0 + length)
    if -tol <= r <= length + tol:
        return min(best, min(max(r, 0.0), length))
    return best
