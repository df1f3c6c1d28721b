"""Far away, the browser's shading against ``verify --distance``'s supersampled exact reference, in
headless chromium (SwiftShader), both web plugins.

The bricks sample (128²) is written as a unit quad with 1536 texels across (tests/far_scenes.py),
converted with ``--levels average``, its base colour made the baked N·L of its step map (the
quantity ``verify --distance`` compares) and drawn unlit through the ``rawAlbedo`` view at 8
texels a pixel (45 and 20 degrees) and 16 (45 degrees), azimuth 30. Per view, over the central
96x96 pixels, against the mean of the albedo at the exact hits of 8x8 rays a pixel:

- each engine's RMSE is at most ``MOST`` (the issue's target at 8 texels a pixel) and at most
  ``OVER_EMULATION`` times that of moderngl's emulation of the same shading (``footprint_image``,
  which ``verify --distance`` reports);
- it is at most ``UNDER_ONE_FETCH`` times that of one unfiltered fetch at the hit (the shading
  before the taps and the level chain);
- three.js and Babylon.js draw the same image (``ENGINES_APART``).

Near the camera the view is what it says: one bilinear fetch of the base colour at the browser's
own hit.

Measured (SwiftShader): RMSE 0.066, 0.073 and 0.064 in both engines; the emulation's 0.069, 0.068
and 0.061 (the browser's 0.97x, 1.07x, 1.05x); one fetch's 0.118, 0.126 and 0.187 (0.56x, 0.58x,
0.34x); the engines apart by under 1e-4. Pixel by
pixel the browser's image is 0.045 to 0.06 RMS from the emulation's even at the browser's own hits:
SwiftShader's filtering and derivatives, not the march (the RMSE against the reference is alike).
"""

from __future__ import annotations

import numpy as np
import pytest

from cdp import Chromium
from far_scenes import bake_albedo, distance_for, far_camera, far_images, far_reference, relief_quad_scene, rmse
from view_page import SIZE, browser_raw, convert, load, needs_browser, serving
from view_scenes import SAMPLES

pytestmark = pytest.mark.browser
ENGINES = ("three", "babylon")
VIEWS = ((8.0, 45.0), (8.0, 20.0), (16.0, 45.0))  # texels a pixel across the screen's centre, elevation
WINDOW = np.s_[48:144, 96:192]  # the central 96x96 pixels
MOST, OVER_EMULATION, UNDER_ONE_FETCH, ENGINES_APART = 0.10, 1.25, 0.7, 0.005


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """{engine: [far_images of each view], engine + " near": (rawAlbedo, rawUv, Baked) at half a
    texel a pixel} of the baked bricks."""
    from PIL import Image

    with Image.open(SAMPLES / "bricks_height.png") as im:
        heights = np.asarray(im.convert("L"), np.float64) / 255.0
    tmp = tmp_path_factory.mktemp("far")
    scene = convert(relief_quad_scene(tmp / "src", heights), tmp / "out", "--levels", "average")
    baked = bake_albedo(scene)
    assert len(baked.levels) == 7
    views = [far_reference(scene, baked, far_camera(distance_for(t, SIZE), el), SIZE, window=WINDOW)
             for t, el in VIEWS]
    out = {}
    for engine in ENGINES:
        with serving(scene, engine) as url, Chromium(*SIZE) as b:
            info = load(b, url)
            assert all(m["fallback"] is None for m in info["materials"]), info
            out[engine] = [far_images(b, view) for view in views]
            near = far_camera(distance_for(0.5, SIZE), 45.0)
            out[engine + " near"] = (browser_raw(b, near, "rawAlbedo"), browser_raw(b, near, "rawUv"), baked)
            assert not b.console_errors(), b.console_errors()
    return out


@pytest.mark.parametrize("engine", ENGINES)
def test_the_browsers_far_shading_is_near_the_supersampled_reference(drawn, engine):
    for (t, el), f in zip(VIEWS, drawn[engine]):
        m, ref = f["mask"], f["reference"]
        assert m.sum() > 0.5 * 96 * 96 and abs(f["texels"] - t) < 0.25 * t, (m.sum(), f["texels"])
        got, emulated, one = (rmse(f[k], ref, m) for k in ("browser", "emulation", "one_fetch"))
        print(engine, t, el, got, emulated, one)
        assert got <= MOST and got <= OVER_EMULATION * emulated, (t, el, got, emulated)
        assert got <= UNDER_ONE_FETCH * one, (t, el, got, one)


def test_both_engines_draw_the_same_far_image(drawn):
    for a, b in zip(drawn["three"], drawn["babylon"]):
        m = a["mask"] & b["mask"]
        assert m.mean() > 0.1 and rmse(a["browser"], b["browser"], m) <= ENGINES_APART


@pytest.mark.parametrize("engine", ENGINES)
def test_near_the_albedo_view_is_one_fetch_at_the_browsers_hit(drawn, engine):
    """Half a texel a pixel (level 0, no taps): the rawAlbedo view is the base colour fetched
    bilinearly at the hit the rawUv view reports (measured: on 99.1% of the pixels to 1e-3, most
    to 1e-5; the rest where the visible footprint, wider on slopes turned from the eye, reaches
    level 1)."""
    from csm_assets.verify.distance_shading import bilinear

    albedo, raw, baked = drawn[engine + " near"]
    hit = np.rint(raw[..., 3]) == 1
    fetched = bilinear(baked.albedo, raw[..., :2][hit].astype(np.float64))
    assert hit.mean() > 0.5 and np.mean(np.abs(albedo[..., 0][hit] - fetched) <= 1e-3) >= 0.98
