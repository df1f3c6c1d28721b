"""A slow, obviously correct measure of triangle areas (the reference of csm_assets.depth)."""

from __future__ import annotations

import math

import numpy as np


def slow_areas(parts):
    """(world, uv) area sums: Heron's formula for world areas, the shoelace sum for uv areas, one
    triangle at a time."""
    world = uv = 0.0
    for positions, uvs, faces in parts:
        for f in faces:
            a, b, c = (np.asarray(positions[i], float) for i in f)
            la, lb, lc = np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)
            s = (la + lb + lc) / 2
            world += math.sqrt(max(s * (s - la) * (s - lb) * (s - lc), 0.0))
            (x0, y0), (x1, y1), (x2, y2) = (uvs[i] for i in f)
            uv += abs(x0 * (y1 - y2) + x1 * (y2 - y0) + x2 * (y0 - y1)) / 2
    return world, uv
