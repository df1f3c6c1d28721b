"""The level chain of a step map: levels 1..n below the packed map (level 0), as GL mip levels.

Sizes follow GL's mip rule: each axis ``max(1, n // 2)``, down to 1x1 (:func:`level_shapes`).
A level is packed as level 0 is (R height, G cones, B/A slopes; :mod:`csm_assets.packing`), from
the **stored** level above it:

- ``"average"``: R and B/A are the box-filtered (area-weighted) means of the level above
  (:func:`mean_weights`: on an even axis exactly the 2x2 mean; on an odd axis of 2m+1 texels each
  of the m texels averages the 2 + 1/m texels its footprint covers), rounded to the nearest code
  (``np.rint``, ties to even; float32 maps: the float64 mean rounded to float32).
- ``"max"``: R is the maximum of the level above over :func:`max_support` (on an even axis: the
  2x2 block after a one-texel dilation), so the level's bilinear surface is nowhere below the
  level above's, and by induction nowhere below level 0's; B/A averaged as above.

Each level's cones (every kind: conservative, relaxed, quadrant) are the exact cones of that
level's own stored heights (:func:`csm_assets.packing.cone_ratio_maps`), stored as level 0 stores
them (rounded down, with the bilinear safety pass when the map has it), ``max_ratio`` the same.
B/A stay in slope per **level-0** texel (a mean of slopes), so a shader reads every level's slopes
as it reads level 0's. Memory: the level being made, its cones as level 0's are made (float64
ratios, quadrant cones as their codes: :class:`~csm_assets.cone_codes.ConeCodes`) and the max pyramid
of its heights, each a quarter of the level above's; the float64 means and every packing temporary a
band of rows at a time (:mod:`csm_assets.bands`).
"""

from __future__ import annotations

import warnings

import numpy as np

from .bands import each_band
from .pack_bands import pack_bands, warn_narrow
from .packing import DTYPES, cone_ratio_maps
from .warning_codes import NarrowCones

LEVEL_MODES = ("none", "average", "max")  # StepMapSettings.levels


def level_shapes(shape) -> list[tuple[int, int]]:
    """The ``(H, W)`` of levels 1..n below a level-0 ``shape``, GL's rule down to 1x1
    ([] for a 1x1 map)."""
    h, w = shape
    out = []
    while h > 1 or w > 1:
        h, w = max(1, h // 2), max(1, w // 2)
        out.append((h, w))
    return out


def mean_weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices and weights ``(m, 3)`` of the area-weighted box filter from an axis of ``n`` texels
    to ``m = max(1, n // 2)``: coarse texel i averages the fine texels its footprint
    ``[i n/m, (i+1) n/m]`` (in fine texels) covers, each by its covered length. Rows sum to 1."""
    m = max(1, n // 2)
    idx = np.zeros((m, 3), np.int64)
    wts = np.zeros((m, 3))
    for i in range(m):  # in units of 1/m fine texel: coarse i covers [i n, (i+1) n], fine j [j m, (j+1) m]
        lo, hi = i * n, (i + 1) * n
        js = range(lo // m, min(n, -(-hi // m)))
        for k, j in enumerate(js):
            idx[i, k] = j
            wts[i, k] = (min(hi, (j + 1) * m) - max(lo, j * m)) / n
        idx[i, len(js):] = idx[i, 0]
    return idx, wts


def max_support(n: int, tile: bool) -> np.ndarray:
    """Indices ``(m, K)`` of the fine texels each coarse texel of an axis of ``n`` -> ``m = max(1,
    n // 2)`` takes the maximum of, so that the coarse level's bilinear surface (GL's LINEAR,
    REPEAT when ``tile`` else CLAMP_TO_EDGE) is nowhere below the fine one's.

    Between the union of both levels' texel centres both surfaces are bilinear, so their
    difference is least at those knots; at each knot every fine texel sampled there must be at
    most every coarse texel sampled there. Coarse texel i takes the fine texels sampled at the
    knots where it is sampled: on an even axis 2i-1..2i+2 (a one-texel dilation of the 2x2 block),
    cut at the edges of an axis that does not tile. Rows repeat their first index as padding."""
    m = max(1, n // 2)
    period = 2 * n * m  # positions in units of 1/(2nm) of the texture: centres are integers

    def sampled(x, size, tile):
        spacing = period // size
        t, rem = divmod(x - spacing // 2, spacing)
        near = (t,) if rem == 0 else (t, t + 1)
        return {i % size if tile else min(max(i, 0), size - 1) for i in near}

    knots = {(2 * j + 1) * m for j in range(n)} | {(2 * i + 1) * n for i in range(m)} | {0, period}
    cover = [set() for _ in range(m)]
    for x in knots:
        fine = sampled(x % period if tile else x, n, tile)
        for i in sampled(x % period if tile else x, m, tile):
            cover[i] |= fine
    width = max(len(c) for c in cover)
    return np.array([sorted(c) + [min(c)] * (width - len(c)) for c in cover], np.int64)


def reduce_mean(a: np.ndarray) -> np.ndarray:
    """float64 ``(m_y, m_x)``: :func:`mean_weights` applied along both axes of ``a`` ``(H, W)``
    (one weighted term at a time: the temporaries are float64 of the output's rows)."""
    return _mean_rows(a, *mean_weights(a.shape[0]), *mean_weights(a.shape[1]))


def _mean_rows(a, iy, wy, ix, wx) -> np.ndarray:
    """float64 ``(len(iy), len(ix))``: the coarse rows of :func:`mean_weights` rows ``iy, wy`` and
    columns ``ix, wx`` of ``a`` (a band of :func:`reduce_mean`'s rows, each value computed as the
    whole map's is: the same bits)."""
    lo, hi = int(iy.min()), int(iy.max()) + 1
    part = a[lo:hi]
    t = np.zeros((hi - lo, len(ix)))
    for k in range(ix.shape[1]):
        t += part[:, ix[:, k]] * wx[:, k]
    out = np.zeros((len(iy), len(ix)))
    for k in range(iy.shape[1]):
        out += t[iy[:, k] - lo] * wy[:, k, None]
    return out


def reduce_max(a: np.ndarray, tile_x: bool, tile_y: bool) -> np.ndarray:
    """``(m_y, m_x)`` of ``a``'s dtype: the maximum of ``a`` ``(H, W)`` over
    :func:`max_support` along both axes (codes stay codes: no rounding)."""
    ix, iy = max_support(a.shape[1], tile_x), max_support(a.shape[0], tile_y)
    t = a[:, ix[:, 0]]
    for k in range(1, ix.shape[1]):
        np.maximum(t, a[:, ix[:, k]], out=t)
    out = t[iy[:, 0]]
    for k in range(1, iy.shape[1]):
        np.maximum(out, t[iy[:, k]], out=out)
    return out


def _stored(values: np.ndarray, dtype) -> np.ndarray:
    """float64 means as a level stores them: nearest code (integers, clipped) or float32."""
    if dtype == np.float32:
        return values.astype(np.float32)
    top = np.iinfo(dtype).max
    return np.clip(np.rint(values), 0, top).astype(dtype)


def next_level(heights: np.ndarray, slopes: np.ndarray, mode: str, tile) -> tuple[np.ndarray, np.ndarray]:
    """(R ``(m_y, m_x)``, B/A ``(m_y, m_x, 2)``) of the level below stored heights ``heights``
    ``(H, W)`` and stored slopes ``slopes`` ``(H, W, 2)`` (uint8, uint16 or float32 codes), by
    ``mode`` ("average" or "max"; the module docstring says how each is filtered and rounded).
    The means are made a band of rows at a time (:func:`~csm_assets.bands.each_band`)."""
    if mode not in LEVEL_MODES[1:]:
        raise ValueError(f"levels must be one of {', '.join(LEVEL_MODES[1:])}, got {mode!r}")
    (iy, wy), (ix, wx) = mean_weights(heights.shape[0]), mean_weights(heights.shape[1])
    r = reduce_max(heights, *tile) if mode == "max" else np.empty((len(iy), len(ix)), heights.dtype)
    s = np.empty((len(iy), len(ix), 2), slopes.dtype)

    def band(r0, r1):
        rows = (iy[r0:r1], wy[r0:r1], ix, wx)
        if mode == "average":
            r[r0:r1] = _stored(_mean_rows(heights, *rows), heights.dtype)
        for k in (0, 1):
            s[r0:r1, :, k] = _stored(_mean_rows(slopes[..., k], *rows), slopes.dtype)

    each_band(len(iy), len(ix), band)
    return r, s


def level_chain(pixels: np.ndarray, kinds, *, mode: str, tile, max_ratio: float, bilinear_safe: bool,
                progress=None) -> dict[str, list[np.ndarray]]:
    """Levels 1..n of packed level-0 ``pixels`` ``(H, W, 4)`` (or a quadrant map's pair ``(H, W, 8)``)
    for each cone kind in ``kinds``, by kind: a list of ``(h, w, 4)`` arrays (quadrant: ``(h, w, 8)``,
    its two images side by side as :func:`csm_assets.packing.pack_quadrant_maps` lays them out), in
    ``pixels``' dtype.

    Only R (channel 0) and B/A (the last two channels) of ``pixels`` are read (every kind's map
    holds the same); the cones of each level come from its own stored heights (one cone pass per
    level for all ``kinds``), packed as level 0's (:func:`~csm_assets.pack_bands.pack_bands`).
    progress: ``progress(done_levels, total_levels)``. Cones narrower than one stored step warn
    once for the whole chain (:class:`~csm_assets.warning_codes.NarrowCones`), not once a level."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NarrowCones)
        out = _chain(pixels, tuple(kinds), mode, tuple(tile), max_ratio, bilinear_safe, progress)
    for w in {str(w.message): w for w in caught}.values():
        words = f"levels 1-{len(next(iter(out.values())))}: {w.message}" if w.category is NarrowCones else w.message
        warnings.warn(words, w.category, stacklevel=2)
    return out


def _chain(pixels, kinds, mode, tile, max_ratio, bilinear_safe, progress) -> dict[str, list[np.ndarray]]:
    """:func:`level_chain`'s levels."""
    bits = {v: k for k, v in DTYPES.items()}[pixels.dtype.type]
    shapes = level_shapes(pixels.shape[:2])
    out = {kind: [] for kind in kinds}
    heights, slopes = pixels[..., 0], pixels[..., -2:]
    for done, shape in enumerate(shapes, 1):
        heights, slopes = next_level(heights, slopes, mode, tile)
        _, ratios, cap, tx, ty = cone_ratio_maps(heights, tile=tile, max_ratio=max_ratio, cones=kinds,
                                                 keep=(bits,))
        for kind in kinds:
            cones = ratios.pop(kind)
            level, narrow = pack_bands(heights, cones if kind == "quadrant" else [cones], cap, tx, ty, bits,
                                       bilinear_safe, slopes=slopes)
            warn_narrow(narrow, bits, cap, stacklevel=3)
            out[kind].append(level)
        heights, slopes = level[..., 0], level[..., -2:]  # the level's own arrays go
        if progress is not None:
            progress(done, len(shapes))
    return out


def atlas(levels) -> np.ndarray:
    """Levels 1..n ``[(h_k, w_k, C)]`` in one image ``(h_1, w_1 + ... + w_n, C)``: level 1 at
    (0, 0), level k at column ``w_1 + ... + w_(k-1)``, row 0; the texels no level covers are 0."""
    h = levels[0].shape[0]
    w = sum(lv.shape[1] for lv in levels)
    out = np.zeros((h, w, levels[0].shape[2]), levels[0].dtype)
    x = 0
    for lv in levels:
        out[:lv.shape[0], x:x + lv.shape[1]] = lv
        x += lv.shape[1]
    return out


def atlas_shape(shape) -> tuple[int, int]:
    """The ``(H, W)`` of :func:`atlas` for a level-0 ``shape`` ((0, 0) for a 1x1 map)."""
    shapes = level_shapes(shape)
    return (shapes[0][0], sum(w for _, w in shapes)) if shapes else (0, 0)


def split_atlas(image: np.ndarray, shape) -> list[np.ndarray]:
    """The levels 1..n of a level-0 ``shape`` cut out of an :func:`atlas` ``image`` (views)."""
    out, x = [], 0
    for h, w in level_shapes(shape):
        out.append(image[:h, x:x + w])
        x += w
    return out
