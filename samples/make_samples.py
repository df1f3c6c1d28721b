"""Regenerate the project's own sample height maps (run from the repository root).

samples/cobbles.png: 256x192, 16-bit grey, tiling rounded cobbles with mortar grooves.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def cobbles(width=256, height=192, cells=(8, 6), seed=11) -> np.ndarray:
    """Tileable rounded stones: height 1 at a stone's centre, falling to the mortar."""
    rng = np.random.default_rng(seed)
    cx, cy = cells
    # one jittered site per cell, copied around so distances wrap
    sites = (np.stack(np.meshgrid(np.arange(cx), np.arange(cy)), -1).reshape(-1, 2)
             + 0.5 + rng.uniform(-0.3, 0.3, (cx * cy, 2))) / [cx, cy]
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    U, V = np.meshgrid(u, v)
    d = np.full((2, height, width), np.inf)
    for s in sites:
        du = np.abs(U - s[0]); du = np.minimum(du, 1 - du) * cx
        dv = np.abs(V - s[1]); dv = np.minimum(dv, 1 - dv) * cy
        dist = np.hypot(du, dv)
        d[1] = np.minimum(d[1], np.maximum(d[0], dist))
        d[0] = np.minimum(d[0], dist)
    edge = np.clip((d[1] - d[0]) * 2.5, 0, 1)   # 0 in the mortar, 1 inside a stone
    h = 0.15 + 0.8 * np.sqrt(edge) * (1 - 0.25 * d[0])
    return np.clip(h, 0, 1)


if __name__ == "__main__":
    out = Path(__file__).resolve().parent / "cobbles.png"
    Image.fromarray(np.rint(cobbles() * 65535).astype(np.uint16)).save(out)
    print(f"wrote {out}")
