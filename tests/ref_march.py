"""A slow, obviously correct ray/heightfield reference: a fine ray march.

The surface comes from scipy's ``map_coordinates`` (order 1), an implementation
of bilinear sampling independent of the tracer: ``grid-wrap`` repeats the texels,
``nearest`` clamps, exactly as GL's REPEAT and CLAMP_TO_EDGE do.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import map_coordinates


def surface(h, u, v, tile):
    """Bilinear height at texture coords ``u, v`` (arrays); texel centres at (k + 0.5) / n."""
    rows, cols = h.shape
    x = np.asarray(u, dtype=np.float64) * cols - 0.5
    y = np.asarray(v, dtype=np.float64) * rows - 0.5
    mode = "grid-wrap" if tile else "nearest"
    return map_coordinates(np.asarray(h, dtype=np.float64), [y.ravel(), x.ravel()], order=1,
                           mode=mode).reshape(x.shape)


def march(h, origin, direction, tile, t_max, samples=20000):
    """First t in [0, t_max] where the ray is at or under the surface, or inf.

    Samples ``samples`` points evenly, then bisects the first bracket 60 times.
    Without tiling, a ray that leaves uv in [0, 1] before the crossing misses.
    """
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    ts = np.linspace(0.0, t_max, samples)
    p = o[None, :] + ts[:, None] * d[None, :]
    under = p[:, 2] <= surface(h, p[:, 0], p[:, 1], tile)
    inside = np.ones(samples, dtype=bool)
    if not tile:
        inside = (p[:, 0] >= 0) & (p[:, 0] <= 1) & (p[:, 1] >= 0) & (p[:, 1] <= 1)
        out = np.flatnonzero(~inside)
        if out.size and (not under[: out[0]].any()):
            return np.inf
    first = np.flatnonzero(under & inside)
    if first.size == 0:
        return np.inf
    k = first[0]
    if k == 0:
        return 0.0
    lo, hi = ts[k - 1], ts[k]

    def below(t):
        q = o + t * d
        return q[2] <= surface(h, np.array([q[0]]), np.array([q[1]]), tile)[0]

    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if below(mid):
            hi = mid
        else:
            lo = mid
    return hi
