"""What weighting the shading fetches by what the pixel sees buys far away (csm.glsl's
``csm_visible_taps``), against the one filtered fetch before it.

``python benchmarks/distance_taps.py [--px 64] [--texels 8 16] [--size 512] [MAP ...]`` (the maps of
``benchmarks/distance.py``; a depth map given by path is resized to ``--size`` squared)

A filtered fetch weighs every texel of its footprint alike; the pixel sees a surface patch in
proportion to its area projected towards the eye, ``max(ds.z + grad h . ds.xy, 0)`` per unit of uv.
Per map and view (texels per pixel x elevations 45 and 20, azimuth 30) it draws the ``exact``
variant with the level chain and shades its hits with ``verify --distance``'s baked N·L filtered
(``baked``: a colour map's kind of quantity) and with N·L of the filtered slopes' normal (``lit``,
as the shader lights), both against the same reference (the baked N·L averaged over the exact hits
of about one ray per texel² of the pixel):

- ``one fetch``: the shader before, one fetch over the visible footprint (``csm_shading_grads``;
  the lit normal half a level finer), its pixel quad's share 0.15 (0.175 from 16 texels a pixel);
- ``taps alike``: the four taps of ``csm_visible_taps`` weighted alike, share 0.2;
- ``weighted 0.15``: the four taps weighted by their projected area, share 0.15 and 0.175;
- ``shipped``: the same with the share 0.2 (the shader, ``verify --distance``'s ``levels`` image);

and today's (level 0, one bilinear sample) for scale: RMSE / flicker (x the reference's).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/distance.py's maps
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from distance import DEPTH, arguments, drawn, maps, rmse_flicker  # noqa: E402

from csm_assets.render.renderer import STATUS_MISS  # noqa: E402
from csm_assets.verify import distance_shading as shading  # noqa: E402
from csm_assets.verify.distance import baked_lighting, slope_lighting  # noqa: E402

BEFORE = (0.15, 0.175)  # the quad share before the taps (up to 8 texels a pixel, from 16)
SHADINGS = (("one fetch", None, BEFORE), ("taps alike", False, None), ("weighted 0.15", True, BEFORE),
            ("shipped", True, None))  # (name, taps weighted (None: one fetch), quad share (None: the shader's))


def images(res, slopes, chain, shape):
    """{(shading name, "baked" | "lit"): float64 (h, w) image} of one render with the chain, each
    blended with its pixel quad far away (NaN off the relief)."""
    ok = (res.covered & (res.status != STATUS_MISS)).ravel()
    uv, ds = res.hit_uv.reshape(-1, 2)[ok], res.ray_dir.reshape(-1, 3)[ok]
    dx, dy = shading.diffs(res.ray_uv)
    size = np.array(shape[::-1], np.float64)
    g = shading.shading_grad(slopes, uv, ds, dx[ok], dy[ok])
    gn = g * 2.0 ** -shading.NORMAL_SHARPEN
    spread = shading.tap_spread(dx[ok], dy[ok], size)
    out = {}
    for name, weighted, share in SHADINGS:
        if weighted is None:  # one fetch, the normal half a level finer
            colour = shading.trilinear(chain, uv, g, g)
            slope = np.column_stack([shading.trilinear([s[..., c] for s in slopes], uv, gn, gn) for c in (0, 1)])
        else:
            taps, gt, slope = shading.visible_taps(slopes, uv, ds, g, spread, weighted=weighted)
            colour = shading.tapped(chain, taps, gt)
        weight = shading.quad_weight(dx, dy, size, share).reshape(res.covered.shape)
        for quantity, values in (("baked", colour), ("lit", slope_lighting(slope[:, 0], slope[:, 1], shape, DEPTH))):
            img = np.full(ok.shape, np.nan)
            img[ok] = values
            out[name, quantity] = shading.quad_share(img.reshape(res.covered.shape), weight)
    return out


def today(res, slopes, baked, shape):
    """{("today", "baked" | "lit"): image}: one bilinear sample at level 0's hits."""
    ok = res.covered & (res.status != STATUS_MISS)
    hit = res.hit_uv[ok]
    out = {}
    for quantity, values in (("baked", shading.bilinear(baked, hit)), ("lit", slope_lighting(
            *(shading.bilinear(slopes[0][..., c], hit) for c in (0, 1)), shape, DEPTH))):
        img = np.full(ok.shape, np.nan)
        img[ok] = values
        out["today", quantity] = img
    return out


def main():
    a = arguments(__doc__).parse_args()
    for name, sm in maps(a.maps, a.size).items():
        p = sm.pixels
        baked, slopes = baked_lighting(p, DEPTH), shading.slope_chain(p, sm.levels)
        chain, shape = shading.lit_chain(baked), p.shape[:2]
        for texels, elevation, refs, renders in drawn(sm, a.texels, a.px, baked):
            shots = {}
            for res in renders[False]:
                for k, img in today(res, slopes, baked, shape).items():
                    shots.setdefault(k, []).append(img)
            for res in renders[True]:
                for k, img in images(res, slopes, chain, shape).items():
                    shots.setdefault(k, []).append(img)
            for quantity in ("baked", "lit"):
                cells = [f"{kind} {rmse:.3f} / {flicker:.2f}" for (kind, q), (img, moved) in shots.items()
                         if q == quantity for rmse, flicker in [rmse_flicker(img, moved, refs)]]
                print(f"{name} {texels:g} tex/px {elevation:g} {quantity}: " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
