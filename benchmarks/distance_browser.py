"""The shading far away as the browser draws it, against ``verify --distance``'s supersampled exact
reference: three.js and Babylon.js in headless chromium (SwiftShader), and moderngl's emulation.

``python benchmarks/distance_browser.py [--texels 8 16] [--size 512] [--engines three babylon] [MAP ...]``
(the maps of ``benchmarks/distance.py``: the repository's own, or the path of any depth map,
white deep, resized to ``--size`` squared: held-out maps stay outside the repository)

Each map is written as a unit quad displaced by its heights, 0.1 of the texture's width deep,
repeated so that 1536 texels span it (``tests/far_scenes.py``), converted with ``csm-assets convert
--levels average``, and its base colour made the baked N·L of its step map (the quantity
``verify --distance`` compares). The engines draw it unlit through the plugins' ``rawAlbedo`` view
(the base colour as the relief fetched it: far away at csm.glsl's four taps over the visible
footprint, blended with the pixel quad) from the distance that puts ``--texels`` texels a pixel across
the screen at its centre, at elevations 45 and 20 degrees, azimuth 30; per view it prints the RMSE
against the reference (``sub``² = 8² exact rays a pixel, the central 96x96 pixels) of each engine's
image, of moderngl's emulation of the same shading (``verify.distance_shading.footprint_image``)
and of one unfiltered fetch at moderngl's hit; and each engine's RMSE against the emulation.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout
sys.path.insert(0, str(ROOT / "benchmarks"))  # benchmarks/distance.py's maps
sys.path.insert(0, str(ROOT / "tests"))  # the browser driver and the far-away scene

import numpy as np  # noqa: E402

from cdp import Chromium  # noqa: E402
from distance import heights  # noqa: E402
from far_scenes import (bake_albedo, distance_for, far_camera, far_images, far_reference,  # noqa: E402
                        relief_quad_scene, rmse)
from view_page import SIZE, convert, load, serving  # noqa: E402

WINDOW = np.s_[48:144, 96:192]  # the central 96x96 pixels of the 288x192 view


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("maps", nargs="*", default=["bricks_height", "cobbles"])
    ap.add_argument("--texels", type=float, nargs="+", default=[8.0, 16.0])
    ap.add_argument("--size", type=int, default=512, help="the side a depth map given by path is resized to")
    ap.add_argument("--engines", nargs="+", default=["three", "babylon"], choices=["three", "babylon"])
    a = ap.parse_args()
    print("map            tex/px elev  engine   browser emulation one_fetch  vs_emulation")
    for name, h in heights(a.maps, a.size).items():
        with tempfile.TemporaryDirectory() as tmp:
            scene = convert(relief_quad_scene(Path(tmp) / "src", h / 255.0), Path(tmp) / "out", "--levels", "average")
            baked = bake_albedo(scene)
            views = [(t, el, far_reference(scene, baked, far_camera(distance_for(t, SIZE), el), SIZE, window=WINDOW))
                     for t in a.texels for el in (45.0, 20.0)]
            for engine in a.engines:
                with serving(scene, engine) as url, Chromium(*SIZE) as b:
                    load(b, url)
                    for t, el, view in views:
                        f = far_images(b, view)
                        m, ref = f["mask"], f["reference"]
                        print(f"{name[:14]:14s} {t:6g} {el:4g}  {engine:7s}  {rmse(f['browser'], ref, m):.4f}"
                              f"    {rmse(f['emulation'], ref, m):.4f}    {rmse(f['one_fetch'], ref, m):.4f}"
                              f"        {rmse(f['browser'], f['emulation'], m):.4f}", flush=True)
                    errors = b.console_errors()
                    if errors:
                        raise SystemExit(f"{engine}: console errors: {errors}")


if __name__ == "__main__":
    main()
