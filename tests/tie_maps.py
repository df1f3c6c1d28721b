"""Hypothesis strategies for float maps full of exact and near ties.

A map draws its heights from a small pool: zeros, ones, a few bases (round values such as
0.5 or 1/3, perhaps one other float or a subnormal) and each base's neighbours: the next float up and down
(in the map's dtype) and the values 1e-7 away. Few values make plateaus and equal slopes
(exact ties: a zero directional derivative, a midpoint level with p); neighbours make the
near ties where float64 rounding decides, if anything but exact arithmetic decides.
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

ROUND = (0.0, 1.0, 0.5, 0.25, 0.75, 1.0 / 3.0, 0.1)
TINY = (5e-324, 2.2250738585072014e-308, 1e-300, 2.0 ** -60)


def neighbours(base: float, dtype) -> set[float]:
    """``base`` in ``dtype`` and the values next to it, all in [0, 1]."""
    t = np.dtype(dtype).type
    b = t(base)
    out = {b, np.nextafter(b, t(2)), np.nextafter(b, t(-1)), t(base + 1e-7), t(base - 1e-7)}
    return {float(v) for v in out if 0.0 <= float(v) <= 1.0}


@st.composite
def tie_pools(draw, dtype=np.float64) -> list[float]:
    """The sorted heights one map draws from."""
    tiny = [float(np.dtype(dtype).type(v)) for v in TINY]
    bases = draw(st.lists(st.sampled_from(ROUND), min_size=1, max_size=4))
    bases += draw(st.lists(st.one_of(st.floats(0, 1, width=np.dtype(dtype).itemsize * 8),
                                     st.sampled_from(tiny)), max_size=1))
    pool = {0.0, 1.0}
    for b in bases:
        pool |= neighbours(b, dtype)
    return sorted(pool)


def tie_fields(max_side: int = 5, dtype=np.float64):
    """``(H, W)`` arrays of ``dtype``, sides 1..max_side, heights from one :func:`tie_pools`."""
    return st.tuples(st.integers(1, max_side), st.integers(1, max_side), tie_pools(dtype)).flatmap(
        lambda s: arrays(dtype, s[:2], elements=st.sampled_from(s[2])))
