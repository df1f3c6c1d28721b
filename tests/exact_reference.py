"""Exact (rational) references: what "never wider than exact" means, checked without rounding.

A float height is a dyadic rational and an 8/16-bit code k stands for k / 255 or
k / 65535: :func:`exact_heights` turns either into :class:`fractions.Fraction`. Squared
ratios are rationals too (``|q - p|_uv^2 / dh^2``), so :func:`exact_cone_squares` gives the
conservative cone of DESIGN.md's definition with no rounding at all, and
:func:`assert_never_wider` checks a float32 result against such squares exactly.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np


def exact_heights(h, levels=0) -> np.ndarray:
    """Object ``(H, W)`` of Fractions: ``h`` as it is (floats), or ``rint(h * levels) / levels``
    (levels 255 or 65535: unit heights of 8/16-bit codes, or the codes themselves when ``h``
    is an integer array)."""
    a = np.asarray(h)
    out = np.empty(a.shape, object)
    for idx, v in np.ndenumerate(a):
        if levels:
            k = int(v) if np.issubdtype(a.dtype, np.integer) else round(float(v) * levels)
            out[idx] = Fraction(k, levels)
        else:
            out[idx] = Fraction(float(v))
    return out


def axis_gap(d: int, n: int, tile: bool) -> int:
    """Texels between two columns (or rows) d apart on an axis of n, the short way round if tiled."""
    d = abs(d)
    return min(d, n - d) if tile else d


def exact_cone_squares(h, tile_x=True, tile_y=True, max_ratio=1.0, levels=0) -> np.ndarray:
    """Object ``(H, W)`` of Fractions: the squared cone ratio of every texel, exactly:
    ``min |q - p|_uv^2 / (h(q) - h(p))^2`` over strictly higher q, at most ``max_ratio^2``.
    (Heights on a common denominator D as integers k, squares compared as integer
    fractions ``(dx^2 H^2 + dy^2 W^2) D^2 / (W^2 H^2 (k_q - k_p)^2)``, reduced once.)"""
    z = exact_heights(h, levels)
    H, W = z.shape
    den = levels or max(f.denominator for f in z.flat)
    k = [[f.numerator * (den // f.denominator) for f in row] for row in z]
    cap = Fraction(float(max_ratio)) ** 2
    out = np.empty(z.shape, object)
    for r in range(H):
        for c in range(W):
            best_n, best_d = cap.numerator, cap.denominator
            kp = k[r][c]
            for qr in range(H):
                gy = axis_gap(qr - r, H, tile_y) ** 2 * W * W
                for qc in range(W):
                    dk = k[qr][qc] - kp
                    if dk > 0:
                        n = (axis_gap(qc - c, W, tile_x) ** 2 * H * H + gy) * den * den
                        d = W * W * H * H * dk * dk
                        if n * best_d < best_n * d:
                            best_n, best_d = n, d
            out[r, c] = Fraction(best_n, best_d)
    return out


def assert_never_wider(got, squares, what="a cone"):
    """Every float ``got`` (H, W) is at most the exact ratio whose square is ``squares``."""
    wide = [(idx, float(g)) for idx, g in np.ndenumerate(np.asarray(got))
            if g < 0 or Fraction(float(g)) ** 2 > squares[idx]]
    assert not wide, f"{what} wider than exact at (texel, value) {wide[:5]}: exact " \
                     f"{[float(squares[i]) ** 0.5 for i, _ in wide[:5]]}"
