"""Exact sums of small integer multiples of float64 heights (numba), for the near ties that
a float64 filter cannot decide.

``sum c[k] z[k]`` with integers ``|c[k]| < 2^52`` and finite ``z[k]`` in ``[0, 1]``: each
product is split into four pieces that float64 holds exactly (Veltkamp's split of z, c cut
at 2^26), the pieces are added into a nonoverlapping expansion (Shewchuk's grow-expansion
with zero elimination, "Adaptive Precision Floating-Point Arithmetic", 1997), and the sign
of the sum is the sign of the expansion's largest component. Heights are scaled by 2^600
first (exact), so no piece underflows, subnormal heights included.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels import CACHE

_SCALE = 2.0 ** 600
_SPLITTER = 134217729.0  # 2^27 + 1
_CUT = 2.0 ** 26


@njit(cache=CACHE, inline="always")
def two_sum(a, b):
    """(s, e): s = fl(a + b) and e its rounding error, so that a + b = s + e exactly."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@njit(cache=CACHE)
def _grow(e, m, b):
    """Add b to the expansion e[:m] (nonoverlapping, increasing magnitude); its new length."""
    q = b
    k = 0
    for i in range(m):
        q, err = two_sum(q, e[i])
        if err != 0.0:
            e[k] = err
            k += 1
    if q != 0.0:
        e[k] = q
        k += 1
    return k


@njit(cache=CACHE)
def _expansion(c, z, n, e):
    """Fill e with the expansion of ``2^600 sum c[:n] z[:n]``; its length."""
    m = 0
    for k in range(n):
        t = z[k] * _SCALE
        s = _SPLITTER * t
        zh = s - (s - t)
        zl = t - zh
        ch = math.floor(c[k] / _CUT) * _CUT
        cl = c[k] - ch
        m = _grow(e, m, ch * zh)
        m = _grow(e, m, ch * zl)
        m = _grow(e, m, cl * zh)
        m = _grow(e, m, cl * zl)
    return m


@njit(cache=CACHE)
def exact_sum(c, z):
    """(sign, value) of ``sum c[k] z[k]`` (float64 arrays of equal length, at most 8): the
    sign exactly (-1, 0 or 1), the value to a few float64 roundings (it may underflow to 0
    where the sign does not)."""
    e = np.empty(4 * len(c) + 1)
    m = _expansion(c, z, len(c), e)
    if m == 0:
        return 0, 0.0
    v = 0.0
    for i in range(m):
        v += e[i]
    return (1 if e[m - 1] > 0.0 else -1), v / _SCALE
