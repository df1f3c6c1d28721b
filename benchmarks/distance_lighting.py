"""How far the shader's lit normal is from the supersampled picture far away, by how much finer than
the shading footprint it is fetched (csm.glsl's ``CSM_NORMAL_SHARPEN``).

``python benchmarks/distance_lighting.py [--px 64] [--texels 8 16] [--size 512] [MAP ...]`` (the maps of
``benchmarks/distance.py``; a depth map given by path is resized to ``--size`` squared)

Per map and view (texels per pixel x elevations 45 and 20, azimuth 30) it draws the ``exact``
variant without the level chain (today) and with it, and prints RMSE / flicker (x the reference's)
of the diffuse term max(N·L, 0) against ``verify --distance``'s reference (the same N·L of the stored
slopes per texel, averaged over the exact hits of about one ray per texel² of the pixel): today's
normal from one bilinear fetch of the slopes at the hit, and the chain's from the slopes filtered
over the visible footprint (``csm_shading_grads``) made 0, 0.5 or 1 level finer, blended with its
pixel quad far away (``csm_quad_share``, 0.15), as the shader lit it before its taps
(``csm_visible_taps``; ``benchmarks/distance_taps.py`` compares the two).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/distance.py's maps
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from distance import DEPTH, arguments, drawn, maps, rmse_flicker  # noqa: E402

from csm_assets.render.renderer import STATUS_MISS  # noqa: E402
from csm_assets.verify.distance import baked_lighting, slope_lighting  # noqa: E402
from csm_assets.verify.distance_shading import (bilinear, diffs, quad_share, quad_weight,  # noqa: E402
                                                shading_grad, slope_chain, trilinear)

SHARPEN = (0.0, 0.5, 1.0)  # levels finer than the shading footprint
BEFORE = (0.15, 0.175)  # the pixel quad's share before the taps (up to 8 texels a pixel, from 16)


def images(res, slopes, chained):
    """{name: float64 (h, w) diffuse image} of one render (NaN off the relief)."""
    ok = (res.covered & (res.status != STATUS_MISS)).ravel()
    uv, shape = res.hit_uv.reshape(-1, 2)[ok], slopes[0].shape[:2]
    if not chained:
        img = np.full(ok.shape, np.nan)
        img[ok] = slope_lighting(bilinear(slopes[0][..., 0], uv), bilinear(slopes[0][..., 1], uv), shape, DEPTH)
        return {"today": img.reshape(res.covered.shape)}
    dx, dy = diffs(res.ray_uv)
    g = shading_grad(slopes, uv, res.ray_dir.reshape(-1, 3)[ok], dx[ok], dy[ok])
    weight = quad_weight(dx, dy, np.array(shape[::-1], np.float64), BEFORE).reshape(res.covered.shape)
    out = {}
    for k in SHARPEN:
        gk = g * 2.0 ** -k
        su, sv = (trilinear([s[..., c] for s in slopes], uv, gk, gk) for c in (0, 1))
        img = np.full(ok.shape, np.nan)
        img[ok] = slope_lighting(su, sv, shape, DEPTH)
        out[f"normal {k:g} finer"] = quad_share(img.reshape(res.covered.shape), weight)
    return out


def main():
    a = arguments(__doc__).parse_args()
    for name, sm in maps(a.maps, a.size).items():
        baked, slopes = baked_lighting(sm.pixels, DEPTH), slope_chain(sm.pixels, sm.levels)
        for texels, elevation, refs, renders in drawn(sm, a.texels, a.px, baked):
            shots = {}
            for chained, pair in renders.items():
                for res in pair:
                    for k, img in images(res, slopes, chained).items():
                        shots.setdefault(k, []).append(img)
            cells = []
            for k, (img, moved) in shots.items():
                rmse, flicker = rmse_flicker(img, moved, refs)
                cells.append(f"{k} {rmse:.3f} / {flicker:.2f}")
            print(f"{name} {texels:g} tex/px {elevation:g}: " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
