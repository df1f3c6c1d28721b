"""A cone channel's stored codes (G of DESIGN.md's packed map), and a plane of them kept small.

:func:`cone_codes` turns float64 ratios into what the G channel stores at 8, 16 or 32 bits.
:class:`ConeCodes` holds one ``(H, W)`` plane of them for a few bit depths without its float64
ratios (8 bytes a texel): the codes of the finest depth asked for (uint16: 2 bytes a texel, or
float32: 4), the coarser depths derived from them, and the texels where a derived code differs
from :func:`cone_codes`' (a short list, near code boundaries), so that every depth gives exactly
:func:`cone_codes`' codes. It is filled a band of rows at a time, as a cone search finishes them
(from several threads: bands do not overlap).
"""

from __future__ import annotations

import threading

import numpy as np

DTYPES = {8: np.uint8, 16: np.uint16, 32: np.float32}


def cone_codes(ratio: np.ndarray, max_ratio: float, bits: int):
    """(G of float64 ``ratio`` before the bilinear-safe 3x3 minimum, whether any code was raised to
    the one-step floor): sqrt(ratio / max_ratio) as float32 rounded down (bits 32), or integer codes
    (float64) rounded down and at least 1."""
    g = np.sqrt(ratio / max_ratio)
    if bits == 32:
        return float_g(g, ratio / max_ratio), False
    top = float(np.iinfo(DTYPES[bits]).max)
    gq = np.floor(g * top)
    gq -= (gq / top) ** 2 > ratio / max_ratio  # float rounding must not widen a cone
    low = bool((gq < 1).any())
    return np.maximum(gq, 1.0, out=gq), low


def float_g(g: np.ndarray, x: np.ndarray) -> np.ndarray:
    """float32 sqrt(x) rounded so that its square never exceeds ``x``."""
    g32 = g.astype(np.float32)
    over = g32.astype(np.float64) ** 2 > x
    g32[over] = np.nextafter(g32[over], np.float32(0))
    return g32


def _derive(base: np.ndarray, bits: int) -> np.ndarray:
    """Codes at ``bits`` guessed from finer codes ``base`` (uint16 or float32 G): usually right."""
    top = np.iinfo(DTYPES[bits]).max
    if base.dtype == np.float32:
        return np.maximum(np.floor(base.astype(np.float64) * top), 1).astype(DTYPES[bits])
    return np.maximum(base.astype(np.int64) * top // np.iinfo(base.dtype).max, 1).astype(DTYPES[bits])


class ConeCodes:
    """The :func:`cone_codes` of an ``(H, W)`` ratio plane at each of ``bits`` (8, 16, 32), in
    2 (finest 16) or 4 (finest 32) bytes a texel plus a list of corrections. Fill every row
    once with :meth:`add`, then read with :meth:`rows`; ``low[bits]``: whether :func:`cone_codes`
    raised some code to the one-step floor."""

    def __init__(self, shape, max_ratio: float, bits):
        self.bits = tuple(sorted(set(bits)))
        if not self.bits or any(b not in DTYPES for b in self.bits):
            raise ValueError(f"bits must be some of 8, 16, 32, got {bits!r}")
        self.max_ratio = max_ratio
        self.base = np.empty(shape, DTYPES[self.bits[-1]])
        self.low = dict.fromkeys(self.bits, False)
        self._parts = {b: [] for b in self.bits[:-1]}  # (flat indices, codes) per band, any order
        self._fix = {}  # bits -> (sorted flat indices, codes): where :func:`_derive` is wrong
        self._lock = threading.Lock()  # rows() is read from several threads: the list is made once

    @property
    def shape(self):
        return self.base.shape

    def add(self, r0: int, ratio: np.ndarray) -> None:
        """Codes of float64 ratios ``ratio`` ``(n, W)``, rows ``r0 .. r0 + n``."""
        r1 = r0 + ratio.shape[0]
        g, low = cone_codes(ratio, self.max_ratio, self.bits[-1])
        self.base[r0:r1] = g
        if low:  # only ever set: bands may be added from several threads
            self.low[self.bits[-1]] = True
        for b in self.bits[:-1]:
            g, low = cone_codes(ratio, self.max_ratio, b)
            if low:
                self.low[b] = True
            wrong = np.flatnonzero(_derive(self.base[r0:r1], b) != g)
            self._parts[b].append((wrong + r0 * self.shape[1], g.reshape(-1)[wrong].astype(DTYPES[b])))

    def rows(self, rows, bits: int) -> np.ndarray:
        """Codes of rows ``rows`` (an int index array) at ``bits``: ``(len(rows), W)``, as
        :func:`cone_codes` gives them (in the output's dtype). Once every row is added, it may be
        called from several threads."""
        if bits not in self.bits:
            raise ValueError(f"these cone codes were kept for {self.bits} bits, not {bits}")
        rows = np.asarray(rows, np.int64)
        if bits == self.bits[-1]:
            return self.base[rows]
        out = _derive(self.base[rows], bits)
        idx, codes = self._fixes(bits)
        W = self.shape[1]
        lo, hi = np.searchsorted(idx, rows * W), np.searchsorted(idx, (rows + 1) * W)
        count = hi - lo
        if count.any():
            which = np.repeat(np.arange(len(rows)), count)
            sel = np.arange(int(count.sum())) + np.repeat(lo - (np.cumsum(count) - count), count)
            out[which, idx[sel] % W] = codes[sel]
        return out

    def _fixes(self, bits):
        with self._lock:
            if bits not in self._fix:
                parts = self._parts.pop(bits)
                idx = np.concatenate([p[0] for p in parts] or [np.zeros(0, np.int64)])
                codes = np.concatenate([p[1] for p in parts] or [np.zeros(0, DTYPES[bits])])
                order = np.argsort(idx, kind="stable")
                self._fix[bits] = idx[order], codes[order]
            return self._fix[bits]
