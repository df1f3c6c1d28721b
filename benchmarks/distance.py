"""Today's march far away (``verify --distance``'s numbers) on the real maps, and which uv
derivatives the shading fetch should filter with.

``python benchmarks/distance.py [--px 64] [--texels 8 16] [MAP ...]`` (maps: ``bricks2`` and
``toy_box`` from ``../shared/data`` at their own size when present, ``terrain`` 256² tiled; step
maps as ``convert`` makes them: 8 bits, bilinear safe, depth 0.1)

Per map and view (texels per pixel x elevations 45 and 20, azimuth 30) it prints
:func:`csm_assets.verify.distance.verify_distance`'s record of today's march (RMSE, p95,
flicker, fetches, tiles, through), then the shading question: the same hits shaded with the baked
N·L fetched trilinearly from its 2x2-averaged mip chain at the level ``textureGrad`` takes from the
polygon's uv derivatives (``grad uv``) or from the hit's (``grad hit``), each pixel's derivatives
the forward differences to its right and lower neighbours, RMSE and flicker against the same
reference.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from csm_assets.bench import maps as bench_maps  # noqa: E402
from csm_assets.render.renderer import STATUS_MISS, Material, Renderer  # noqa: E402
from csm_assets.stepmap import make_step_map  # noqa: E402
from csm_assets.verify.distance import (baked_lighting, bilinear, distance_view,  # noqa: E402
                                        reference_image, shifted, verify_distance)
from csm_assets.verify.distance_report import format_distance  # noqa: E402
from csm_assets.verify.maps import sampled_heights  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
DEPTH = 0.1


def maps(names):
    real = bench_maps.real_maps(SHARED)
    out = {}
    for name in names:
        if name == "terrain":
            h = bench_maps.terrain(256)
        elif name + "_disp" in real:
            from PIL import Image

            with Image.open(real[name + "_disp"]) as im:
                h = bench_maps.load_real(real[name + "_disp"], im.size[0])
        else:
            continue
        out[name] = make_step_map(h.astype(np.float32) / 255.0).pixels
    return out


def pyramid(lit):
    levels = [lit]
    while min(levels[-1].shape) > 1 and all(n % 2 == 0 for n in levels[-1].shape):
        a = levels[-1]
        levels.append(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))
    return levels


def trilinear(levels, uv, duv_dx, duv_dy):
    """GL's trilinear textureGrad of the chain ``levels`` at uv with the given derivatives."""
    n = max(levels[0].shape)
    rho = np.maximum(np.hypot(*duv_dx.T), np.hypot(*duv_dy.T)) * n
    lod = np.clip(np.log2(np.maximum(rho, 1e-12)), 0.0, len(levels) - 1)
    lo = np.floor(lod).astype(int)
    hi = np.minimum(lo + 1, len(levels) - 1)
    out = np.zeros(len(uv))
    for k in range(len(levels)):
        for sel, w in ((lo == k, 1.0 - (lod - lo)), (hi == k, lod - lo)):
            if sel.any():
                out[sel] += w[sel] * bilinear(levels[k], uv[sel])
    return out


def diffs(a):
    """Forward differences of ``a`` ``(h, w, 2)`` to the right and down (backward at the last)."""
    dx = np.concatenate([a[:, 1:] - a[:, :-1], a[:, -1:] - a[:, -2:-1]], axis=1)
    dy = np.concatenate([a[1:] - a[:-1], a[-1:] - a[-2:-1]], axis=0)
    return dx.reshape(-1, 2), dy.reshape(-1, 2)


def shading(packed, texels, elevation, px):
    """{'grad uv': (rmse, flicker), 'grad hit': (...)} at one view."""
    height, lit = sampled_heights(packed), baked_lighting(packed, DEPTH)
    levels = pyramid(lit)
    view = distance_view(packed.shape, texels, elevation, 30.0, DEPTH, px)
    mat = Material(packed, depth=view.world_depth, tile=True, uv_per_world=(view.uv_per_world,) * 2, min_step=0.25)
    images = {"grad uv": [], "grad hit": []}
    refs = []
    with Renderer((px, px)) as r:
        for cam in (view.camera, shifted(view.camera, 0.5 * view.pixel)):
            res = r.render(mat, cam, variant="exact", mesh=view.mesh)
            ok = (res.covered & (res.status != STATUS_MISS)).ravel()
            refs.append(reference_image(height, lit, view, cam, DEPTH).ravel())
            for name, src in (("grad uv", res.ray_uv), ("grad hit", res.hit_uv)):
                dx, dy = diffs(src)
                img = np.full(ok.shape, np.nan)
                img[ok] = trilinear(levels, res.hit_uv.reshape(-1, 2)[ok], dx[ok], dy[ok])
                images[name].append(img)
    out = {}
    for name, (a, b) in images.items():
        both = np.isfinite(a) & np.isfinite(refs[0])
        rmse = math.sqrt(np.mean((a - refs[0])[both] ** 2))
        flicker = math.sqrt(np.nanmean((b - a) ** 2) / np.nanmean((refs[1] - refs[0]) ** 2))
        out[name] = (rmse, flicker)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("maps", nargs="*", default=["bricks2", "toy_box", "terrain"])
    ap.add_argument("--px", type=int, default=64)
    ap.add_argument("--texels", type=float, nargs="+", default=[8.0, 16.0])
    a = ap.parse_args()
    for name, packed in maps(a.maps).items():
        views = [(t, el, 30.0) for el in (45.0, 20.0) for t in a.texels]
        report = verify_distance(packed, min_step=0.25, depth=DEPTH, views=views, size=a.px, source=name)
        print(format_distance(report), flush=True)
        for t, el, _ in views:
            s = shading(packed, t, el, a.px)
            print(f"  shading {name} {t:g} tex/px {el:g}: " + ", ".join(
                f"{k} rmse {v[0]:.4f} flicker {v[1]:.2f}" for k, v in s.items()), flush=True)


if __name__ == "__main__":
    main()
