"""Self-shadowing in the three.js plugin (the material's ``selfShadow`` and ``lightSize``):
csm.glsl's csm_shadow run for the viewer's directional light, in headless chromium, against
csm-assets' moderngl render of the same camera and light direction."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from cdp import Chromium
from conftest import SAMPLES
from view_page import SIZE, browser_raw, camera, convert, load, needs_browser, png, serving
from view_scenes import moderngl_shadows

pytestmark = pytest.mark.browser
VIEW = ((0.9, 0.9, 1.1), (0.0, 0.5, 0.0))
LIGHTS = [(1.0, 0.8, 0.6), (0.2, -1.0, 0.4)]  # world directions towards the light


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    return convert(SAMPLES / "brick_wall.gltf", tmp_path_factory.mktemp("wall"))


def with_shadows(scene, light_size: float):
    doc = json.loads(scene.read_text())
    ext = doc["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]
    ext.update(selfShadow=True, lightSize=light_size)
    scene.write_text(json.dumps(doc))
    return scene


def browser_shadows(b: Chromium, cam, light) -> tuple[np.ndarray, np.ndarray]:
    """(light direction u, v, up and hard lit; soft, steps, status, 1) for the pixels drawn."""
    b.eval(f"window.csmViewer.setLight({light[0]}, {light[1]}, {light[2]})")
    return browser_raw(b, cam, "rawLight"), browser_raw(b, cam, "rawShadow")


def test_hard_self_shadows_match_moderngl(wall):
    scene = with_shadows(wall, 0.0)
    cam = camera(*VIEW)
    with serving(scene) as url, Chromium(*SIZE) as b:
        load(b, url)
        for light in LIGHTS:
            mine, _ = browser_shadows(b, cam, light)
            status, ref = moderngl_shadows(scene, cam, SIZE, light)
            drawn = (status == 0) & (np.linalg.norm(mine[..., :3], axis=-1) > 0.5)
            assert drawn.sum() > 0.3 * SIZE[0] * SIZE[1], drawn.sum()
            shadowed = 1 - mine[..., 3][drawn].mean()
            agree = np.mean(mine[..., 3][drawn] == ref[..., 0][drawn])
            bad = drawn & (mine[..., 3] != ref[..., 0])
            edge = binary_dilation(ref[..., 0] > 0.5) & binary_dilation(ref[..., 0] < 0.5)
            print(f"light {light}: {shadowed:.1%} shadowed; hard lit agrees on {agree:.3%}, "
                  f"{(bad & edge).sum()} of {bad.sum()} others on a shadow edge")
            assert shadowed > 0.05, shadowed
            assert agree >= 0.99, agree
            assert (bad & edge).sum() >= 0.9 * bad.sum()
        # the lit picture: shadows darken it where moderngl says shadowed, and only with selfShadow on
        b.eval("window.csmViewer.showPanel(false)")
        shaded = png(b.screenshot())
        b.eval("window.csmViewer.setSelfShadow(false)")
        plain = png(b.screenshot())
        darker = (plain - shaded).max(axis=-1) > 0.02
        shadowed, lit = drawn & (ref[..., 0] == 0) & ~edge, drawn & (ref[..., 0] == 1) & ~edge
        # shadowed pixels turned away from the light lose nothing; no pixel gains light
        print(f"lit view: {darker[shadowed].mean():.1%} of the shadowed pixels darker, {darker[lit].mean():.2%} of the lit")
        assert darker[shadowed].mean() > 0.3 and darker[lit].mean() < 0.01
        assert np.mean((shaded - plain).max(axis=-1)[drawn] < 0.02) > 0.999
        assert not b.console_errors(), b.console_errors()


def test_soft_self_shadows_match_moderngl(wall, tmp_path):
    scene = with_shadows(wall, 0.05)
    cam = camera(*VIEW)
    light = LIGHTS[0]
    with serving(scene) as url, Chromium(*SIZE) as b:
        load(b, url)
        _, mine = browser_shadows(b, cam, light)
    status, ref = moderngl_shadows(scene, cam, SIZE, light)
    drawn = (status == 0) & (mine[..., 3] > 0)
    diff = np.abs(mine[..., 0] - ref[..., 1])[drawn]
    penumbra = (ref[..., 1] > 0.05) & (ref[..., 1] < 0.95) & drawn
    print(f"soft share: {np.mean(diff <= 0.1):.3%} within 0.1, mean |difference| {diff.mean():.4f}; "
          f"{penumbra.sum()} penumbra pixels")
    assert penumbra.sum() > 500, penumbra.sum()
    assert np.mean(diff <= 0.1) >= 0.98 and diff.mean() < 0.01
