"""Row bands: whole-map steps that run a band of rows at a time, so that their float64
temporaries cost a band (about :data:`BAND_TEXELS` texels), not the map; :func:`each_band` runs
the bands on threads.

A band of rows ``r0..r1`` often needs its neighbour rows too (a slope, a 3x3 minimum):
:func:`halo` gives their indices, wrapped round on a tiled axis and clamped at the edges of
the others (an edge row is its own neighbour there).
"""

from __future__ import annotations

import numpy as np

from .heightfield import height_levels
from .polling import run_chunks

BAND_TEXELS = 1 << 16  # texels a band: each float64 temporary of a band is 512 KiB


def bands(rows: int, cols: int, texels: int | None = None):
    """``(r0, r1)`` ranges of rows covering 0..rows, about ``texels`` (:data:`BAND_TEXELS`) texels each."""
    step = max(1, (texels or BAND_TEXELS) // max(cols, 1))
    for r0 in range(0, rows, step):
        yield r0, min(rows, r0 + step)


def each_band(rows: int, cols: int, work, texels: int | None = None) -> None:
    """``work(r0, r1)`` for every band of :func:`bands`, on ``numba.get_num_threads()`` threads
    (:func:`~csm_assets.polling.run_chunks`): numpy work on the band's own rows, during which numpy
    releases the GIL (the first error is raised here)."""
    todo = list(bands(rows, cols, texels))
    run_chunks(lambda i, _: work(*todo[i]), len(todo), np.zeros(len(todo), np.uint8), None)


def halo(r0: int, r1: int, n: int, wrap: bool) -> np.ndarray:
    """int64 indices of rows ``r0 - 1 .. r1`` (inclusive) of an axis of n: wrapped or clamped."""
    idx = np.arange(r0 - 1, r1 + 1)
    return idx % n if wrap else np.clip(idx, 0, n - 1)


def unit_rows(a: np.ndarray, rows) -> np.ndarray:
    """Float64 unit heights of rows ``rows`` (a slice or an index array) of validated heights
    ``a``: uint8 codes / 255, uint16 / 65535, floats as they are (as
    :func:`~csm_assets.heightfield.unit_heights` gives them)."""
    levels = height_levels(a)
    part = a[rows].astype(np.float64)
    if levels:
        part /= levels
    return part
