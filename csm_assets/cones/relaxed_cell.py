"""One cell of the relaxed search (:mod:`.relaxed_search`): its limiting sub-cells and
their bounds, every decision exact.

Texel units, p at the origin: the cell ``[x0, x0+1] x [y0, y0+1]`` (x0, y0 integers) has
corner heights z00 (x0, y0), z10 (x0+1, y0), z01 (x0, y0+1), z11 (x0+1, y0+1) and is split
into s x s sub-cells whose corners are the grid points ``(x0 + i/s, y0 + j/s)``.

- *Falls* at grid point (i, j): ``grad h . (e - p)``, s^2 times, is ``gx X + gy Y`` with
  ``gx = (s-j)(z10-z00) + j(z11-z01)`` and ``gy = (s-i)(z01-z00) + i(z11-z10)`` (s times
  the slopes of the two sub-cell edges through the point: the patch is linear along them)
  and ``X = s x0 + i``, ``Y = s y0 + j``.
- *Rise* of grid point (i, j) above p, s^2 times: ``(s-i)(s-j) z00 + i(s-j) z10 +
  (s-i)j z01 + ij z11 - s^2 h(p)``.

Both are integer combinations of the heights, evaluated in float64: a falling test beside
a bound on its rounding (``TOL``, 16 units in the last place, times a bound of its terms'
magnitude over the cell, :func:`filter_bound`; it errs by at most about 5), a rise beside
its terms' magnitude where the corners' rises differ in sign (taken when it is at least
1/64 of that, so accurate to 2^-44). A test within its bound, or a rise that cancels more,
is summed again exactly (:mod:`.exact_sign`). So whether a sub-cell falls and whether it
rises above p are decided exactly for float heights (a zero stays zero), and a rise is
accurate to 2^-44 of itself. With tol 0 (integer heights, the 8/16-bit codes) float64 is
exact as it is.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .exact_sign import exact_sum
from ..kernels import CACHE

TOL = 2.0 ** -49  # 16 units in the last place: the filters' bound, relative to the terms' sum


@njit(cache=CACHE)
def _falls_exact(z, s, i, j, x0, y0):
    """Exact ``gx X + gy Y < 0`` at grid point (i, j) (see the module), by the coefficient of
    each corner height."""
    X = s * x0 + i
    Y = s * y0 + j
    wx0, wx1, wy0, wy1 = s - j, float(j), s - i, float(i)
    c = np.array([-wx0 * X - wy0 * Y, wx0 * X - wy1 * Y, -wx1 * X + wy0 * Y, wx1 * X + wy1 * Y])
    sign, _ = exact_sum(c, np.array([z[0], z[1], z[2], z[3]]))
    return sign < 0


@njit(cache=CACHE)
def _quad_exact(z, s, i, j, x0, y0):
    """Exact: does ``gx X + gy Y`` fall below 0 at a corner of sub-cell (i, j)?"""
    return (_falls_exact(z, s, i, j, x0, y0) or _falls_exact(z, s, i + 1, j, x0, y0)
            or _falls_exact(z, s, i, j + 1, x0, y0) or _falls_exact(z, s, i + 1, j + 1, x0, y0))


@njit(cache=CACHE, inline="always")
def _state(gx, gy, X, Y, b):
    """1: ``gx X + gy Y`` is surely negative, 0: surely not, 2: within ``b`` of 0 (b > 0)."""
    v = gx * X + gy * Y
    if v < -b:
        return 1
    if v > b or b == 0.0:
        return 0
    return 2


@njit(cache=CACHE, inline="always")
def quad_falls(z, b, s, i, j, x0, y0, gxa, gxb, gya, gyb):
    """Does ``grad h . (e - p)`` fall below 0 at a corner of sub-cell (i, j) of split s (the
    whole cell: s = 1, i = j = 0)? gxa, gxb: s gx on its rows j, j + 1; gya, gyb: s gy on
    its columns i, i + 1 (see the module); b: the filter's bound (:func:`filter_bound`
    times s^2). In float64 unless a corner is within the bound: then exactly."""
    X = s * x0 + i
    Y = s * y0 + j
    f = _state(gxa, gya, X, Y, b)
    if f == 1:
        return True
    g = _state(gxa, gyb, X + 1.0, Y, b)
    if g == 1:
        return True
    f = max(f, g)
    g = _state(gxb, gya, X, Y + 1.0, b)
    if g == 1:
        return True
    f = max(f, g)
    g = _state(gxb, gyb, X + 1.0, Y + 1.0, b)
    if g == 1:
        return True
    return max(f, g) == 2 and _quad_exact(z, s, i, j, x0, y0)


@njit(cache=CACHE, inline="always")
def filter_bound(d, tol, x0, y0):
    """The filters' bound at s = 1 for the cell at (x0, y0): ``tol`` times a bound of the
    terms' magnitude at any of its points (``max |d| (max |x| + max |y|)``); s^2 times it at
    split s. 0 where float64 is exact (tol = 0, or every difference too small to round)."""
    dmax = max(max(abs(d[0]), abs(d[1])), max(abs(d[2]), abs(d[3])))
    return tol * (max(abs(x0), abs(x0 + 1.0)) + max(abs(y0), abs(y0 + 1.0))) * dmax


@njit(cache=CACHE)
def _rise_exact(z, hp, w00, w10, w01, w11, s2):
    sign, v = exact_sum(np.array([w00, w10, w01, w11, -s2]), np.array([z[0], z[1], z[2], z[3], hp]))
    v /= s2
    if sign > 0:
        return max(v, 5e-324)  # underflow keeps its sign: a rise, however small, is a rise
    return min(v, -5e-324) if sign < 0 else 0.0


@njit(cache=CACHE, inline="always")
def _checked(r, m, z, hp, w00, w10, w01, w11, s2):
    """The rise r (magnitude of its terms m, both over s2) if float64 got it to 2^-44 (its
    error is under 7 ulp of m), else the exact one."""
    if m <= 64.0 * abs(r):
        return r
    return _rise_exact(z, hp, w00, w10, w01, w11, s2)


@njit(cache=CACHE, inline="always")
def rise(z, a, hp, s, i, j, mixed):
    """Height of grid point (i, j) above p's: exact in sign, accurate to 2^-44 of itself.
    a: the corners' rises (z - hp) in float64; mixed: some are positive and some not (else
    the sum has no cancellation and float64 is accurate as it is)."""
    w00, w10, w01, w11 = (s - i) * (s - j), i * (s - j), (s - i) * j, float(i * j)
    s2 = s * s
    r = (w00 * a[0] + w10 * a[1] + w01 * a[2] + w11 * a[3]) / s2
    if not mixed:
        return r
    m = (w00 * abs(a[0]) + w10 * abs(a[1]) + w01 * abs(a[2]) + w11 * abs(a[3])) / s2
    return _checked(r, m, z, hp, w00, w10, w01, w11, s2)


@njit(cache=CACHE, inline="always")
def _mid(z, a, hp, k, l, mixed):
    """Rise of the midpoint of corners k and l (split 2)."""
    r = 0.5 * (a[k] + a[l])
    if not mixed:
        return r
    return _checked(r, 0.5 * (abs(a[k]) + abs(a[l])), z, hp, 2.0 if k == 0 else 0.0,
                    2.0 if k == 1 or l == 1 else 0.0, 2.0 if k == 2 or l == 2 else 0.0,
                    2.0 if l == 3 else 0.0, 4.0)


@njit(cache=CACHE, inline="always")
def _near(a, b):
    """The point of [a, b] nearest to 0."""
    return min(max(0.0, a), b)


@njit(cache=CACHE, inline="always")
def _bound(dist, dh, best, top):
    """ratio^2 (W H)^2 of a sub-cell at ``dist`` rising ``dh`` if it beats ``best``, else -1
    (before the falling test)."""
    if dh <= 0.0 or (dist > 0.0 and dist >= best * dh * dh):
        return -1.0
    return dist / (dh * dh) if dist > 0.0 else 0.0


@njit(cache=CACHE)
def cell_bound(z, d, b, x0, y0, split, H2, W2, hp, best, exact):
    """Lower ``best`` (``ratio^2 (W H)^2``) by the limiting sub-cells of the cell at (x0, y0)
    (z: its corner heights z00, z10, z01, z11; d: their differences z10-z00, z11-z01,
    z01-z00, z11-z10 in float64; b: :func:`filter_bound`), nearest to p first. exact:
    float64 computes the rises exactly (integer heights)."""
    a = (z[0] - hp, z[1] - hp, z[2] - hp, z[3] - hp)
    top = max(max(a[0], a[1]), max(a[2], a[3]))
    mixed = not exact and min(min(a[0], a[1]), min(a[2], a[3])) <= 0.0
    s = float(split)
    bs = b * s * s
    if split == 2:  # the common case: nine grid points, four sub-cells
        r10, r01, r21, r12 = _mid(z, a, hp, 0, 1, mixed), _mid(z, a, hp, 0, 2, mixed), \
            _mid(z, a, hp, 1, 3, mixed), _mid(z, a, hp, 2, 3, mixed)
        r11 = 0.25 * ((a[0] + a[1]) + (a[2] + a[3]))
        if mixed:
            r11 = _checked(r11, 0.25 * ((abs(a[0]) + abs(a[1])) + (abs(a[2]) + abs(a[3]))), z, hp,
                           1.0, 1.0, 1.0, 1.0, 4.0)
        gx = (2.0 * d[0], d[0] + d[1], 2.0 * d[1])  # s gx at j = 0, 1, 2; s gy at i = 0, 1, 2
        gy = (2.0 * d[2], d[2] + d[3], 2.0 * d[3])
        for k in range(4):
            i = k & 1 if x0 >= 0.0 else 1 - (k & 1)
            j = k >> 1 if y0 >= 0.0 else 1 - (k >> 1)
            nx = _near(x0 + 0.5 * i, x0 + 0.5 * (i + 1))
            ny = _near(y0 + 0.5 * j, y0 + 0.5 * (j + 1))
            dist = nx * nx * H2 + ny * ny * W2
            if dist > 0.0 and dist >= best * top * top:
                continue
            if j == 0:
                dh = max(max(a[0], r10), max(r01, r11)) if i == 0 else max(max(r10, a[1]), max(r11, r21))
            else:
                dh = max(max(r01, r11), max(a[2], r12)) if i == 0 else max(max(r11, r21), max(r12, a[3]))
            v = _bound(dist, dh, best, top)
            if v < 0.0:
                continue
            if quad_falls(z, bs, s, i, j, x0, y0, gx[j], gx[j + 1], gy[i], gy[i + 1]):
                best = v
        return best
    for jj in range(split):
        j = jj if y0 >= 0.0 else split - 1 - jj
        for ii in range(split):
            i = ii if x0 >= 0.0 else split - 1 - ii
            nx = _near(x0 + i / s, x0 + (i + 1) / s)
            ny = _near(y0 + j / s, y0 + (j + 1) / s)
            dist = nx * nx * H2 + ny * ny * W2
            if dist > 0.0 and dist >= best * top * top:
                continue
            dh = max(max(rise(z, a, hp, s, i, j, mixed), rise(z, a, hp, s, i + 1, j, mixed)),
                     max(rise(z, a, hp, s, i, j + 1, mixed), rise(z, a, hp, s, i + 1, j + 1, mixed)))
            v = _bound(dist, dh, best, top)
            if v >= 0.0 and quad_falls(z, bs, s, i, j, x0, y0, (s - j) * d[0] + j * d[1],
                                       (s - j - 1) * d[0] + (j + 1) * d[1], (s - i) * d[2] + i * d[3],
                                       (s - i - 1) * d[2] + (i + 1) * d[3]):
                best = v
    return best
