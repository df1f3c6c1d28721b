"""Today's march far away (``verify --distance``'s numbers) on the real maps, and which uv
derivatives the shading fetch should filter with.

``python benchmarks/distance.py [--px 64] [--texels 8 16] [--size 256] [MAP ...]`` (maps: ``bricks2``
and ``toy_box`` from ``../shared/data`` at their own size when present, ``terrain`` 256² tiled, the
samples ``bricks_height`` (128²) and ``cobbles`` (256x192), or the path of any depth map (white is
deep, as ``*_disp`` files), resized to ``--size`` squared: held-out maps stay outside the
repository; step maps as ``convert`` makes them: 8 bits, bilinear safe, depth 0.1)

Per map and view (texels per pixel x elevations 45 and 20, azimuth 30) it prints
:func:`csm_assets.verify.distance.verify_distance`'s records of today's march and of the
averaged level chain's (RMSE, p95, flicker, fetches, tiles, through), then (unless
``--no-shading``) the shading question: the same hits shaded with the baked
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
from csm_assets.stepmap import StepMapSettings, make_step_map  # noqa: E402
from csm_assets.verify.distance import (baked_lighting, distance_view, distance_views,  # noqa: E402
                                        reference_image, shifted, verify_distance)
from csm_assets.verify.distance_shading import diffs, lit_chain, trilinear  # noqa: E402
from csm_assets.verify.distance_report import format_distance  # noqa: E402
from csm_assets.verify.maps import sampled_heights  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
SAMPLES = Path(__file__).resolve().parents[1] / "samples"
DEPTH = 0.1


def heights(names, size=256):
    """{name: float32 (H, W) heights in 0..255, white high} of ``names`` (module doc); a path's
    name is its stem, resized to ``size``²; names of maps not here are left out."""
    real = bench_maps.real_maps(SHARED)
    out = {}
    for name in names:
        if Path(name).is_file():  # a depth map from anywhere (held-out maps)
            h = bench_maps.load_real(Path(name), size)
            name = Path(name).stem
        elif name == "terrain":
            h = bench_maps.terrain(256)
        elif (SAMPLES / f"{name}.png").exists():  # the project's own: bricks_height 128², cobbles 256x192 16-bit
            from PIL import Image

            with Image.open(SAMPLES / f"{name}.png") as im:
                a = np.asarray(im)
            h = a.astype(np.float32) * (255.0 / (65535.0 if a.dtype != np.uint8 else 255.0))
        elif name + "_disp" in real:
            from PIL import Image

            with Image.open(real[name + "_disp"]) as im:
                h = bench_maps.load_real(real[name + "_disp"], im.size[0])
        else:
            continue
        out[name] = h.astype(np.float32)
    return out


def maps(names, size=256):
    """{name: StepMap} of ``names`` (:func:`heights`), as ``convert`` makes them with levels."""
    return {name: make_step_map(h / 255.0, StepMapSettings(levels="average")) for name, h in heights(names, size).items()}


def shading(packed, texels, elevation, px):
    """{'grad uv': (rmse, flicker), 'grad hit': (...)} at one view."""
    height, lit = sampled_heights(packed), baked_lighting(packed, DEPTH)
    levels = lit_chain(lit)
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
    return {name: rmse_flicker(a, b, refs) for name, (a, b) in images.items()}


def drawn(sm, texels, px, lit):
    """Per view of ``texels`` (texels per pixel) x elevations 45 and 20 (azimuth 30) of step map
    ``sm``: ``(texels, elevation, refs, renders)``, ``refs`` the reference images of ``lit`` at the
    view and at the camera shifted half a pixel, ``renders`` {False: today's renders there (level
    0), True: the level chain's}."""
    p = sm.pixels
    height = sampled_heights(p)
    for t in texels:
        for elevation in (45.0, 20.0):
            view = distance_view(p.shape, t, elevation, 30.0, DEPTH, px)
            refs, renders = [], {False: [], True: []}
            with Renderer((px, px)) as r:
                for cam in (view.camera, shifted(view.camera, 0.5 * view.pixel)):
                    refs.append(reference_image(height, lit, view, cam, DEPTH))
                    for chained in (False, True):
                        mat = Material(p, depth=view.world_depth, tile=True, min_step=0.25,
                                       uv_per_world=(view.uv_per_world,) * 2,
                                       levels=tuple(sm.levels) if chained else ())
                        renders[chained].append(r.render(mat, cam, variant="exact", mesh=view.mesh))
            yield t, elevation, refs, renders


def rmse_flicker(image, moved, refs):
    """(RMSE of ``image`` against ``refs[0]``, the change from ``image`` to ``moved`` (the camera
    shifted half a pixel) over the references' change), as ``verify --distance`` counts them."""
    both = np.isfinite(image) & np.isfinite(refs[0])
    rmse = math.sqrt(np.mean((image - refs[0])[both] ** 2))
    return rmse, math.sqrt(np.nanmean((moved - image) ** 2) / np.nanmean((refs[1] - refs[0]) ** 2))


def arguments(doc):
    """The parser of this benchmark's maps, ``--px`` and ``--texels`` (described by ``doc``)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("maps", nargs="*", default=["bricks2", "toy_box", "terrain", "bricks_height", "cobbles"])
    ap.add_argument("--px", type=int, default=64)
    ap.add_argument("--texels", type=float, nargs="+", default=[8.0, 16.0])
    ap.add_argument("--size", type=int, default=256, help="the side a depth map given by path is resized to")
    return ap


def main():
    ap = arguments(__doc__)
    ap.add_argument("--no-shading", action="store_true", help="leave out the shading question's table")
    a = ap.parse_args()
    for name, sm in maps(a.maps, a.size).items():
        packed = sm.pixels
        views = distance_views(a.texels, (45.0, 20.0), 30.0)
        report = verify_distance(packed, min_step=0.25, depth=DEPTH, views=views, size=a.px, source=name,
                                 levels=sm.levels)
        print(format_distance(report), flush=True)
        if a.no_shading:
            continue
        for t, el, _ in views:
            s = shading(packed, t, el, a.px)
            print(f"  shading {name} {t:g} tex/px {el:g}: " + ", ".join(
                f"{k} rmse {v[0]:.4f} flicker {v[1]:.2f}" for k, v in s.items()), flush=True)


if __name__ == "__main__":
    main()
