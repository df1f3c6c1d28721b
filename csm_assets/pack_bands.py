"""The packed map (:mod:`csm_assets.packing`'s layout) made a band of rows at a time, the bands on threads.

Each band (:func:`csm_assets.bands.bands`) is numpy work on its own rows of the output (its
temporaries cost a band), so bands run on ``numba.get_num_threads()`` threads
(:func:`csm_assets.bands.each_band`; numpy releases the GIL over a band's arrays): the same
bytes whatever the thread count, as every band computes exactly what it computed alone.
"""

from __future__ import annotations

import warnings

import numpy as np

from .bands import each_band, halo, unit_rows
from .cone_codes import DTYPES, ConeCodes, cone_codes
from .warning_codes import NarrowCones


def axis_slope(h: np.ndarray, axis: int, wrap: bool) -> np.ndarray:
    """Height change per texel of float ``h`` along ``axis``: central differences, wrapped when
    ``wrap``, else one-sided at the edges (``np.gradient``); zero along an axis one texel long."""
    n = h.shape[axis]
    if n == 1:
        return np.zeros_like(h, dtype=np.float64)
    if wrap:
        return (np.roll(h, -1, axis) - np.roll(h, 1, axis)) / 2.0
    return np.gradient(h.astype(np.float64), axis=axis, edge_order=1)


def _row_slope(hh: np.ndarray, r0: int, n: int, wrap: bool) -> np.ndarray:
    """:func:`axis_slope` along rows of rows ``r0..`` from their :func:`~csm_assets.bands.halo` rows
    ``hh`` (one more row above and below), as ``np.roll`` or ``np.gradient`` gives it."""
    if n == 1:
        return np.zeros_like(hh[1:-1])
    s = (hh[2:] - hh[:-2]) / 2.0
    if not wrap:  # one-sided at the edges (np.gradient's edge_order=1)
        if r0 == 0:
            s[0] = hh[2] - hh[1]
        if r0 + len(s) == n:
            s[-1] = hh[-2] - hh[-3]
    return s


def pack_bands(h, ratios, max_ratio, tile_x, tile_y, bits, bilinear_safe, slopes=None):
    """(packed ``(H, W, 4)``, or ``(H, W, 8)`` for 4 cone channels, of the ``bits``' dtype; for each
    cone channel, whether the one-step floor widened some cone) of heights ``h`` (unit heights or
    their uint8/uint16 codes) and ``ratios``: float64 ``(H, W)`` ratios or
    :class:`~csm_assets.cone_codes.ConeCodes`, one per cone channel (see
    :func:`csm_assets.packing.pack_quadrant_maps` for 4). slopes: B and A as stored ``(H, W, 2)``
    of the ``bits``' dtype, put in as they are (a level of :mod:`csm_assets.step_levels`); None:
    the slopes of ``h``."""
    if bits not in DTYPES:
        raise ValueError(f"bits must be 8, 16 or 32, got {bits!r}")
    H, W = h.shape
    out = np.empty((H, W, 4 if len(ratios) == 1 else 8), DTYPES[bits])
    narrow = np.zeros(len(ratios), bool)  # only ever set, from any thread
    slots = [1] if len(ratios) == 1 else [1, 2, 3, 5]  # each cone's channel
    top = None if bits == 32 else float(np.iinfo(DTYPES[bits]).max)
    def band(r0, r1):
        rows = halo(r0, r1, H, tile_y)
        hh = unit_rows(h, rows)
        for k, ratio in enumerate(ratios):
            if isinstance(ratio, ConeCodes):
                g, low = ratio.rows(rows, bits), ratio.low[bits]
            else:
                g, low = cone_codes(ratio[rows], max_ratio, bits)
            if low:
                narrow[k] = True
            out[r0:r1, :, slots[k]] = _band_min(g, tile_x) if bilinear_safe else g[1:-1]
        hb = hh[1:-1]
        if slopes is None:
            b = 0.5 + axis_slope(hb, 1, tile_x)
            a = 0.5 - _row_slope(hh, r0, H, tile_y)
            if top is None:
                chans = (hb, b, a)
            else:
                chans = (np.rint(hb * top), np.rint(np.clip(b, 0, 1) * top), np.rint(np.clip(a, 0, 1) * top))
        else:
            out[r0:r1, :, -2:] = slopes[r0:r1]
            chans = (hb if top is None else np.rint(hb * top),)
        for c, v in zip((0, -2, -1), chans):
            out[r0:r1, :, c] = v
        if len(ratios) > 1:
            out[r0:r1, :, 4] = out[r0:r1, :, 0]

    each_band(H, W, band)
    return out, [bool(n) for n in narrow]


def warn_narrow(narrow, bits: int, max_ratio: float, stacklevel: int) -> None:
    """One :class:`~csm_assets.warning_codes.NarrowCones` for each cone channel in ``narrow``
    (:func:`pack_bands`' flags) that the one-step floor widened."""
    for low in narrow:
        if low:
            warnings.warn(f"some cones are narrower than one {bits}-bit step of max_ratio "
                          f"{max_ratio:g}; they are stored as one step (wider than exact): "
                          f"lower max_ratio or use more bits", NarrowCones, stacklevel=stacklevel + 1)


def _band_min(g: np.ndarray, tile_x: bool) -> np.ndarray:
    """:func:`csm_assets.packing.neighbourhood_min` of the band inside halo rows ``g`` (one more above and below)."""
    m = np.minimum(np.minimum(g[1:-1], g[:-2]), g[2:])
    if m.shape[1] == 1:
        return m
    out = m.copy()
    np.minimum(out[:, 1:], m[:, :-1], out=out[:, 1:])
    np.minimum(out[:, :-1], m[:, 1:], out=out[:, :-1])
    if tile_x:
        np.minimum(out[:, 0], m[:, -1], out=out[:, 0])
        np.minimum(out[:, -1], m[:, 0], out=out[:, -1])
    return out
