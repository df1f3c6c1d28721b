"""Exact cone ratios (DESIGN.md's definition) of a heightfield.

The cone ratio of texel p is ``min |q - p|_uv / (h(q) - h(p))`` over the texels q
strictly higher than p, with ``|.|_uv`` counting 1/W per column and 1/H per row (on
the torus when tiling), capped at ``max_ratio``. Three exact strategies compute it
(each agrees with the brute force to float64 rounding):

- ``"ring"`` (:mod:`csm_assets.cones.ring`): the paper's outward search; quickest for
  narrow cones, O(N^4) for maps of wide cones.
- ``"pyramid"`` (:mod:`csm_assets.cones.pyramid`): branch and bound over a max pyramid;
  fast on wide cones too, for any data.
- ``"levels"`` (:mod:`csm_assets.cones.levels`): one distance transform per distinct
  height; cost O(levels * N^2), for maps with few levels.

``"auto"`` estimates the cost of each from the data (the number of distinct
heights, and the exact cones of a random sample of texels) and runs the cheapest.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from .. import bands
from ..heightfield import check_max_ratio, tile_pair, unit_heights
from .levels import distinct_heights, level_ratios
from .pyramid import build_pyramid, pyramid_ratios, sample_searches
from .ring import ring_ratios, ring_texels

ProgressFn = Callable[[int, int], None]

METHODS = {"ring": ring_ratios, "pyramid": pyramid_ratios, "levels": level_ratios}

# Rough seconds per unit of work on one core (measured on a 2-core x86 VM): a texel
# visited by the ring search, a block examined by a cold pyramid search (a search
# started from a neighbour's apex examines fewer), a texel of one level's transform.
_COST_RING = 1.0e-9
_COST_PYRAMID = 4.0e-9
_COST_LEVEL = 8.0e-9
_SAMPLE = 512
_PROBE, _PROBE_RINGS, _RING_SURE = 256, 12, 150  # narrow cones: ring without estimates
_RING_QUICK = 0.05  # seconds: a ring search this quick is run without estimates
_NO_ROWS = np.zeros(0, np.uint8)


def estimate_costs(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                   seed: int = 0, pyramid=None) -> dict[str, float]:
    """Estimated seconds of each method on float64 unit heights ``h`` (H, W).

    Runs the pyramid search on up to 512 random texels (exact cones) and counts
    what each method would do for them. The levels estimate is a lower bound when
    it already exceeds the others. pyramid: ``h``'s max pyramid if made already.
    """
    H, W = h.shape
    n = h.size
    rng = np.random.default_rng(seed)
    idx = rng.choice(n, size=min(n, _SAMPLE), replace=False)
    rows, cols = (idx // W).astype(np.int64), (idx % W).astype(np.int64)
    flat, offsets, prow, pcol = pyramid or build_pyramid(h)
    wh = float(W) * H
    if len(offsets) > 1:
        best, seen = sample_searches(h, (flat, offsets, prow, pcol), tile_x, tile_y,
                                     (max_ratio * wh) ** 2, rows, cols)
        ratio = np.minimum(np.sqrt(best) / wh, max_ratio)
    else:
        ratio, seen = np.full(len(idx), max_ratio), np.zeros(len(idx), np.int64)
    # ring: it stops at the first ring k with k * step >= ratio * (hmax - h)
    step = min(1.0 / W, 1.0 / H)
    k = np.ceil(ratio * (float(h.max()) - h[rows, cols]) / step)
    span = 2 * k + 1
    ring_visits = np.minimum(span, H) * np.minimum(span, W)
    costs = {"ring": float(ring_visits.mean()) * n * _COST_RING,
             "pyramid": float(seen.mean()) * n * _COST_PYRAMID}
    # levels: a sample's distinct heights bound the count from below; count them
    # all only if the levels method might win
    some = np.unique(h.ravel()[rng.choice(n, size=min(n, 4096), replace=False)])
    if (len(some) - 1) * n * _COST_LEVEL < min(costs.values()):
        costs["levels"] = max(len(distinct_heights(h)) - 1, 0) * n * _COST_LEVEL
    else:
        costs["levels"] = (len(some) - 1) * n * _COST_LEVEL  # at least this
    return costs


def choose_method(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float, pyramid=None) -> str:
    """The method :func:`estimate_costs` finds cheapest.

    Ring, without estimating the others, for tiny maps, where a quick probe finds
    narrow cones (a sample of texels needs few rings), and where the probe shows the
    whole ring search takes under ``_RING_QUICK`` seconds (no other method could save
    more than that, and a first run would pay seconds compiling it).
    """
    n = h.size
    if n <= 64 * 64:
        return "ring"
    H, W = h.shape
    rng = np.random.default_rng(1)
    idx = rng.choice(n, size=min(n, _PROBE), replace=False)
    sure = _RING_QUICK / (n * _COST_RING)  # mean texels visited that is quick enough
    if sure > _RING_SURE:  # a sample texel beyond kcap rings alone pushes the mean past sure
        kcap = max(_PROBE_RINGS, int((math.sqrt(sure * len(idx)) - 1) // 2))
    else:
        sure, kcap = _RING_SURE, _PROBE_RINGS
    rings = np.zeros(len(idx), np.int64)
    if ring_texels(h, float(h.max()), tile_x, tile_y, max_ratio, 0, len(idx), idx // W,
                   idx % W, kcap, np.empty(len(idx)), rings, _NO_ROWS):
        span = 2 * rings + 1
        if float((np.minimum(span, H) * np.minimum(span, W)).mean()) <= sure:
            return "ring"
    costs = estimate_costs(h, tile_x, tile_y, max_ratio, pyramid=pyramid)
    return min(costs, key=costs.get)


# The kernels' float64 ratios err by a few units in the last place (1e-14 at most, relaxed
# cones'); they search against a cap raised by far more, and their results are lowered by
# far more, so that what they give is never above the exact ratio (README: Conventions).
_CAP_UP = 1.0 + 2.0 ** -40
_DOWN = 1.0 - 2.0 ** -42


def kernel_cap(max_ratio: float) -> float:
    """The cap a kernel searches against: ``max_ratio`` raised above its rounding."""
    return max_ratio * _CAP_UP


def safe_ratios(x: np.ndarray, max_ratio: float, floor: np.ndarray | None = None) -> np.ndarray:
    """Float64 lower bounds of the exact ratios from a kernel's ratios ``x`` (searched against
    :func:`kernel_cap`): ``max_ratio`` where ``x`` reached that cap (no texel came within
    rounding of ``max_ratio``), else ``x`` lowered below its rounding, at most ``max_ratio``;
    never below ``floor`` (lower bounds already) where given. In place: a C-ordered float64
    ``x`` is overwritten and returned (a band of temporaries at a time, bands on threads)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    flat = x.reshape(-1)
    low = None if floor is None else np.ascontiguousarray(floor, dtype=np.float64).reshape(-1)
    top = kernel_cap(max_ratio)

    def band(s0, s1):
        v = flat[s0:s1]
        v[:] = np.where(v >= top, max_ratio, np.minimum(v * _DOWN, max_ratio))
        if low is not None:
            np.maximum(v, low[s0:s1], out=v)

    bands.each_band(flat.size, 1, band)  # runs of BAND_TEXELS values, on threads
    return x


def exact_ratios(h: np.ndarray, tile_x: bool, tile_y: bool, max_ratio: float,
                 progress: ProgressFn | None = None, method: str = "auto", pyramid=None,
                 rows=None) -> np.ndarray:
    """Float64 exact cone ratios of validated unit heights (the kernel under :func:`cone_ratios`).

    Args:
        h: float64 ``(H, W)`` heights in ``[0, 1]``, already checked.
        tile_x: distances wrap round the columns.
        tile_y: distances wrap round the rows.
        max_ratio: the cap (> 0).
        progress: ``progress(done, total)``, called as the work goes (rows or levels).
        method: ``"auto"`` (default), ``"ring"``, ``"pyramid"`` or ``"levels"``; all give
            the same ratios (to float64 rounding).
        pyramid: ``h``'s max pyramid when made already (:func:`~.pyramid.pyramid_heights`).
        rows (tuple[int, int] | None): ``(r0, r1)``: those rows only, ``(r1 - r0, W)``, the same
            values (the ring and pyramid searches search those rows only; the levels method
            makes the whole map).

    Returns:
        Float64 ``(H, W)`` (or the rows asked for), each a lower bound within 1e-12 of the exact ratio (``max_ratio``
        exactly where nothing limits).

    Raises:
        ValueError: an unknown ``method``.
    """
    h = np.ascontiguousarray(h, dtype=np.float64)
    if method == "auto":
        method = choose_method(h, tile_x, tile_y, max_ratio, pyramid)
    if method not in METHODS:
        raise ValueError(f"method must be 'auto' or one of {sorted(METHODS)}, got {method!r}")
    more = {"pyramid": pyramid} if method == "pyramid" and pyramid else {}
    if method != "levels" and rows is not None:
        more["rows"] = rows
    out = METHODS[method](h, tile_x, tile_y, kernel_cap(max_ratio), progress, **more)
    if method == "levels" and rows is not None:
        out = out[rows[0]:rows[1]]
    return safe_ratios(out, max_ratio)


def cone_ratios(height, *, tile=True, max_ratio=1.0) -> np.ndarray:
    """Exact cone ratio of every texel.

    Args:
        height (numpy.ndarray | Heightfield): uint8 (/255), uint16 (/65535) or float
            ``(H, W)`` in ``[0, 1]``, any size from 1x1. A :class:`~csm_assets.Heightfield`
            is taken by its ``.data``.
        tile (bool | tuple[bool, bool]): True (the default: textures repeat), False, or a pair
            ``(tile_x, tile_y)``; a tiled axis measures distance the shortest way round.
        max_ratio (float): the cap (> 0); texels with no higher texel get it.

    Returns:
        Float32 ``(H, W)``, each value rounded down from a float64 lower bound of the ratio,
        so a stored cone is never wider than the exact one (the heights taken exactly as the
        rationals they are).

    Raises:
        ValueError: NaN or out-of-range heights, not 2-D, empty, another dtype, or
            ``max_ratio`` not > 0.
    """
    h = unit_heights(height)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    return round_down_f32(exact_ratios(h, tx, ty, cap))


def round_down_f32(x: np.ndarray) -> np.ndarray:
    """Cast float64 ``x`` (>= 0) to float32 without ever rounding up."""
    y = x.astype(np.float32)
    up = y.astype(np.float64) > x
    y[up] = np.nextafter(y[up], np.float32(0))
    return y
