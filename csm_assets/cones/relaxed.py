"""Exact relaxed cone ratios (README's Conventions: *Relaxed cone ratio*).

A relaxed cone may let a ray step into the surface once, never out again. A ray that
leaves p's axis moves away from p; it can leave the bilinear surface only at a point e
where the surface falls along ``e - p``. So a cell limits the relaxed cone of p only
where it falls along some direction from p somewhere in it (the falling-direction rule,
exact per sub-cell: see :mod:`csm_assets.cones.relaxed_search`), bounded by its nearest point and
highest corner; the relaxed ratio is the larger of that bound and the conservative cone
(never narrower). The falling-edge rule of Bán et al. ("Robust Cone Step Mapping",
EGSR 2024) marks a texel q as limiting when any edge of its cell falls and bounds it by
q's own height: that cell can rise to a higher corner and fall there, inside the cone
(a test shows such a ray); this rule uses the falling-edge flags only as a pre-filter.

On a tiled axis cells range over the periodic surface (every image, each with its own
direction from p); on an axis that does not tile, cells clamp at the edge as
``CLAMP_TO_EDGE`` sampling does. The search visits square rings of blocks outward from
p, skipping blocks whose highest falling cell is too low or too far, and stops once no
farther ring can narrow the cone. Serial ``nogil`` numba, run on threads by :mod:`.polling`.
"""

from __future__ import annotations

import numpy as np

from .. import bands as band_rows
from ..bands import bands, halo
from ..heightfield import check_max_ratio, height_levels, tile_pair, unit_heights
from ..polling import row_chunk, run_chunks
from .exact import exact_ratios, kernel_cap, round_down_f32, safe_ratios
from .relaxed_cell import TOL
from .relaxed_search import relaxed_rows


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
    ``h(q+sy) > h(q+sx+sy)``. Neighbours wrap on a tiled axis, clamp otherwise. Made a band
    of rows at a time.
    """
    flags = np.zeros(h.shape, np.uint8)
    for r0, r1 in bands(*h.shape):
        for bit, falls, _ in _band_cells(h[halo(r0, r1, h.shape[0], tile_y)], tile_x):
            flags[r0:r1] |= (falls.astype(np.uint8) << np.uint8(bit))
    return flags


def _band_cells(hh: np.ndarray, tile_x: bool):
    """Per fall bit of rows ``hh[1:-1]`` (``hh``: their :func:`~csm_assets.bands.halo` rows):
    (bit, whether the cell has a falling edge, the cell's highest corner)."""
    for sy in (-1, 1):
        for sx in (-1, 1):
            bh = neighbour(hh, 1, sx, tile_x)
            a, b = hh[1:-1], bh[1:-1]
            c, d = (hh[2:], bh[2:]) if sy > 0 else (hh[:-2], bh[:-2])
            falls = (a > b) | (a > c) | (b > d) | (c > d)
            yield 2 * (sy > 0) + (sx > 0), falls, np.maximum(np.maximum(a, b), np.maximum(c, d))


CONE_KINDS = ("conservative", "relaxed")  # what a step map's G holds (its ``cones`` setting)
SPLIT = 2  # sub-cells per cell side (README: Relaxed cone ratio)


def cell_tops(h: np.ndarray, flags: np.ndarray, tile_x: bool, tile_y: bool, rows=None) -> np.ndarray:
    """float64 ``(4, H, W)``: per fall bit (see :func:`fall_flags`), the highest corner of
    the texel's cell towards that side where the cell has a falling edge, else -1; with
    ``rows`` ``(r0, r1)``, of those rows only ``(4, r1 - r0, W)``."""
    r0, r1 = rows or (0, h.shape[0])
    out = np.full((4, r1 - r0, h.shape[1]), -1.0)
    for bit, _, top in _band_cells(h[halo(r0, r1, h.shape[0], tile_y)], tile_x):
        out[bit] = np.where(flags[r0:r1] & np.uint8(1 << bit), top, -1.0)
    return out


def axis_blocks(n: int, size: int) -> np.ndarray:
    """int64 starts of the blocks of an axis of n texels (``size`` each, the last one
    takes the remainder, so every block has at least ``min(size, n)``), ending with n."""
    nb = max(1, n // size)
    return np.append(np.arange(nb, dtype=np.int64) * size, np.int64(n))


def block_max(values: np.ndarray, sy: np.ndarray, sx: np.ndarray) -> np.ndarray:
    """Maximum of ``values`` (..., H, W) over each block (rows ``sy[i]..``, columns ``sx[j]..``)."""
    rows = np.maximum.reduceat(values, sy[:-1], axis=-2)
    return np.ascontiguousarray(np.maximum.reduceat(rows, sx[:-1], axis=-1))


def block_tables(limit, fine: int = 8, group: int = 8, shape=None):
    """The two-level block tables :func:`csm_assets.cones.relaxed_search.relaxed_texel` reads, for
    limiting heights ``limit`` (4, H, W), one plane per fall bit (-1 where the texel's cell
    cannot fall), or a function ``limit(r0, r1)`` giving rows ``r0..r1`` of them, of a map of
    ``shape`` (the fine table is then made a band of its blocks at a time); the coarse table is
    the maximum of the fine one over its groups (the same values)."""
    H, W = limit.shape[1:] if isinstance(limit, np.ndarray) else shape
    rows = (lambda r0, r1: limit[:, r0:r1]) if isinstance(limit, np.ndarray) else limit
    fsy, fsx = axis_blocks(H, fine), axis_blocks(W, fine)
    cfy, cfx = axis_blocks(len(fsy) - 1, group), axis_blocks(len(fsx) - 1, group)
    csy, csx = fsy[cfy], fsx[cfx]
    step = max(1, (band_rows.BAND_TEXELS // 4) // max(W * fine, 1))  # fine block rows a band
    table = np.concatenate([block_max(rows(fsy[j], fsy[min(j + step, len(fsy) - 1)]),
                                      fsy[j:j + step + 1] - fsy[j], fsx)
                            for j in range(0, len(fsy) - 1, step)], axis=1)
    c0y = np.repeat(np.arange(len(csy) - 1), np.diff(csy)).astype(np.int64)
    c0x = np.repeat(np.arange(len(csx) - 1), np.diff(csx)).astype(np.int64)
    return ((fsy, fsx, table),
            (csy, csx, cfy, cfx, block_max(table, cfy, cfx), c0y, c0x,
             int(np.diff(csy).min()), int(np.diff(csx).min())))


def relaxed_exact(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                  progress=None, split: int = SPLIT, conservative=None, levels: int = 0) -> np.ndarray:
    """Float64 ``(H, W)`` relaxed ratios of validated float64 unit heights ``h``, each a lower
    bound within 1e-12 of the exact ratio (see :func:`~csm_assets.cones.safe_ratios`).

    ``progress(done_rows, total_rows)`` is called now and then from this thread.
    conservative: the float64 ``(H, W)`` :func:`~csm_assets.cones.exact.exact_ratios` of the same
    ``h``, tiling and ``max_ratio`` when already computed (the floor; None: computed here).
    levels: 255 or 65535 when ``h`` holds 8- or 16-bit codes / levels
    (:func:`~csm_assets.heightfield.height_levels`): the search then runs on the integer codes
    times ``split**2``, where float64 computes every sub-cell corner and every falling test
    exactly, and its ratios are scaled back; 0: on the float heights as they are, each
    falling test and rise decided exactly all the same (:mod:`.relaxed_cell`).
    """
    if levels:  # the codes, exactly: rint(h * levels) of unit heights, or the uint8/uint16 codes
        h = np.asarray(h)
        codes = np.rint(h * levels) if h.dtype.kind == "f" else h.astype(np.float64)
        codes *= split * split
    else:
        codes = h = np.ascontiguousarray(h, dtype=np.float64)
    flags = fall_flags(codes, tile_x, tile_y)  # the same on the codes: the order of heights
    if not flags.any():
        return np.full(codes.shape, max_ratio)
    if conservative is None:
        conservative = exact_ratios(h / levels if levels and h.dtype.kind != "f" else h, tile_x, tile_y,
                                    max_ratio)
    h = None
    cons = np.ascontiguousarray(conservative, dtype=np.float64)
    cap = kernel_cap(max_ratio)
    if not levels:  # where cons is capped already there is nothing to search (the kernel's floor: cap)
        out = relaxed_search(codes, flags, tile_x, tile_y, cap, cons, split, TOL, progress, (max_ratio, 1.0))
    else:
        scale = float(levels) * split * split
        out = relaxed_search(codes, flags, tile_x, tile_y, cap / scale, cons, split, 0.0, progress,
                             (max_ratio, scale))
        out *= scale
    return safe_ratios(out, max_ratio, floor=cons)


def relaxed_search(h: np.ndarray, flags: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                   cons: np.ndarray, split: int, tol: float, progress=None, floor=None) -> np.ndarray:
    """Float64 ``(H, W)`` relaxed ratios of float64 heights ``h`` (any scale: ratios are
    per unit of ``h``) with their :func:`fall_flags`, floored by the conservative ``cons``
    of the same scale; tol: see :mod:`.relaxed_cell` (0 for integer heights). floor:
    ``(top, scale)``: ``cons`` is per unit height instead, its floor ``cons / scale``, and
    ``kernel_cap(top) / scale`` where ``cons`` reaches ``top`` (read so, not copied)."""
    top, scale = floor or (np.inf, 1.0)
    cons_top = kernel_cap(top) if floor else np.inf
    H, W = h.shape
    out = np.full((H, W), max_ratio)
    fine, coarse = block_tables(lambda r0, r1: cell_tops(h, flags, tile_x, tile_y, (r0, r1)),
                                 shape=h.shape)
    lmax = float(fine[2].max())
    done = np.zeros(H, np.uint8)
    run_chunks(lambda r0, r1: relaxed_rows(h, flags, lmax, tile_x, tile_y, int(split), max_ratio,
                                           cons, fine, coarse, r0, r1, out, done, tol,
                                           top, cons_top, scale),
               H, done, progress, chunk=row_chunk(H))
    return out


def relaxed_cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact relaxed cone ratio of every texel (README: *Relaxed cone ratio*).

    Args:
        height (numpy.ndarray | Heightfield): as for :func:`~csm_assets.cone_ratios`.
        tile (bool | tuple[bool, bool]): True (default), False, or ``(tile_x, tile_y)``.
        max_ratio (float): the cap (> 0); a texel that nothing limits gets it.

    Returns:
        Float32 ``(H, W)``, rounded down from float64, never below
        :func:`~csm_assets.cone_ratios`.

    Raises:
        ValueError: bad heights or ``max_ratio``, as for :func:`~csm_assets.cone_ratios`.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(relaxed_exact(h, tx, ty, cap, levels=height_levels(height)))
