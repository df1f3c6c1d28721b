"""Which shading fetch suits the level chain's march far away (an exploration for the shader).

``python benchmarks/distance_shading.py [--px 64] [--texels 8 16] [MAP ...]`` (the maps of
``benchmarks/distance.py``: bricks2, toy box, terrain; averaged chains, depth 0.1)

Per map and view (texels per pixel x elevations 45 and 20, azimuth 30) it renders the ``exact``
variant with and without the chain and prints RMSE / flicker against ``verify --distance``'s
reference for the baked N·L shaded four ways at the same hits: ``one sample`` (bilinear on level
0, today's verify image), ``longer axis`` (trilinear at the level GL's ``textureGrad`` takes from
the polygon's uv derivatives: the shader before ``csm_shading_grads``),
``shorter axis`` (trilinear at log2 of the footprint's shorter axis), ``march level``
(bilinear on the level the pixel marched), ``visible axis`` (trilinear at the shorter axis of
the visible footprint, csm.glsl's ``csm_shading_grads``) and ``shipped`` (the shader: far away
four taps in that footprint weighted by what the pixel sees, ``csm_visible_taps``, blended with its
2x2 pixel quad's neighbours, ``csm_quad_share``: ``verify --distance``'s ``levels`` image).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/distance.py's maps
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from distance import DEPTH, arguments, drawn, maps, rmse_flicker  # noqa: E402

from csm_assets.render.renderer import STATUS_MISS  # noqa: E402
from csm_assets.verify.distance import baked_lighting  # noqa: E402
from csm_assets.verify.distance_shading import (bilinear, diffs, footprint_image, lit_chain,  # noqa: E402
                                                shading_grad, slope_chain, trilinear)


def images(res, lit, chain, slopes):
    """{way: float64 (h, w) image} of one render's hits (NaN off the relief); slopes: the step map's
    (:func:`~csm_assets.verify.distance_shading.slope_chain`)."""
    ok = (res.covered & (res.status != STATUS_MISS)).ravel()
    uv = res.hit_uv.reshape(-1, 2)[ok]
    dx, dy = diffs(res.ray_uv)
    dx, dy = dx[ok], dy[ok]
    size = np.array(lit.shape[::-1], np.float64)
    short = np.where((np.hypot(*(dx * size).T) < np.hypot(*(dy * size).T))[:, None], dx, dy)
    lod = np.rint(res.lod.ravel()[ok]).astype(int)
    level = np.zeros(len(uv))
    for k in np.unique(lod):
        level[lod == k] = bilinear(chain[k], uv[lod == k])
    g = shading_grad(slopes, uv, res.ray_dir.reshape(-1, 3)[ok], dx, dy)
    out = {}
    for way, values in (("one sample", bilinear(lit, uv)), ("longer axis", trilinear(chain, uv, dx, dy)),
                        ("shorter axis", trilinear(chain, uv, short, short)), ("march level", level),
                        ("visible axis", trilinear(chain, uv, g, g))):
        img = np.full(ok.shape, np.nan)
        img[ok] = values
        out[way] = img.reshape(res.lod.shape)
    out["shipped"] = footprint_image(chain, res, ok.reshape(res.lod.shape), slopes)
    return out


def main():
    a = arguments(__doc__).parse_args()
    for name, sm in maps(a.maps, a.size).items():
        p = sm.pixels
        lit = baked_lighting(p, DEPTH)
        chain, slopes = lit_chain(lit), slope_chain(p, sm.levels)
        for t, el, refs, renders in drawn(sm, a.texels, a.px, lit):
            for march, chained in (("level 0", False), ("chain", True)):
                pair = [images(res, lit, chain, slopes) for res in renders[chained]]
                cells = ["{} {:.3f} / {:.2f}".format(way, *rmse_flicker(pair[0][way], pair[1][way], refs))
                         for way in pair[0]]
                print(f"{name} {t:g} tex/px {el:g} {march}: " + ", ".join(cells), flush=True)

if __name__ == "__main__":
    main()
