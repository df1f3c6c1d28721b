"""Both web plugins with mipmapped step maps in a real browser (headless chromium, WebGL2).

An engine may generate mipmaps for the step map (a glTF sampler without minFilter: three's
default is LinearMipmapLinear with generateMipmaps). The plugin's march fetches read level 0
(csm.glsl's textureLod), so the step maps switched to mipmaps at run time draw the same hits,
iterations and statuses as the plugin's own unmipped copies, near and far (the bricks repeat six
times: 1 to 16 texels per pixel across these views), and still agree with moderngl. With the
implicit-LOD fetches of main's csm_glsl.js before the change most far pixels changed. The same for
the Babylon.js plugin (csm_babylon.js, which shares csm.glsl and csm_frag.js): its step maps get
mipmaps and trilinear sampling at run time, its hits stay, its slope normals filter."""

from __future__ import annotations

import numpy as np
import pytest

from cdp import Chromium
from view_page import SIZE, browser_raw, camera, compare_hits, convert, load, needs_browser, png, serving
from view_scenes import two_material_scene

pytestmark = pytest.mark.browser
VIEWS = [((0.0, 0.0, 2.6), (0.0, 0.0, 0.0)),      # straight on
         ((-0.6, -2.2, 2.2), (-0.6, 0.0, 0.0)),   # 45 degrees onto the bricks
         ((-0.6, -1.6, 0.6), (-0.6, 0.2, 0.0))]   # about 20 degrees

MIPMAPS = """(() => {
  for (const m of window.csmViewer.materials()) for (const k of ['stepmap', 'stepmap2']) {
    const u = m.userData.csm.uniforms[k];
    if (!u) continue;
    u.value.generateMipmaps = true; u.value.minFilter = 1008; u.value.needsUpdate = true;  // LinearMipmapLinear
  }
  window.csmViewer.draw();
  return window.csmViewer.materials().map((m) => [m.userData.csm.uniforms.stepmap.value.minFilter,
                                                   m.userData.csm.uniforms.stepmap.value.generateMipmaps]);
})()"""
# Babylon.js: gl.generateMipmap on each step map's texture and trilinear sampling (its loader made
# them without mipmaps: the converted sampler's minFilter is LINEAR)
BABYLON_MIPMAPS = """(() => {
  for (const m of window.csmViewer.materials()) {
    const p = m.metadata.csm.plugin;
    for (const t of [p.stepmap, p.stepmap2]) if (t) {
      m.getScene().getEngine().updateTextureSamplingMode(BABYLON.Texture.TRILINEAR_SAMPLINGMODE, t.getInternalTexture(), true);
    }
  }
  window.csmViewer.materials()[0].getScene().resetCachedMaterial();
  window.csmViewer.draw();
  return window.csmViewer.materials().map((m) => [m.metadata.csm.plugin.stepmap.samplingMode,
                                                   m.metadata.csm.plugin.stepmap.getInternalTexture().generateMipMaps]);
})()"""


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    src = two_material_scene(tmp_path_factory.mktemp("src"), transform={"scale": [6.0, 6.0]})
    # a map without its level chain, given the engines' own mipmaps (a chain uploaded as the mip
    # levels, and a mipmapped sampler at level 0: tests/test_view_browser_levels.py)
    return convert(src, tmp_path_factory.mktemp("out"), "--levels", "none")


def _raw(b, cams):
    return [(browser_raw(b, c, "rawUv"), browser_raw(b, c, "rawInfo")) for c in cams]


@pytest.mark.parametrize("engine, script, switched", [("three", MIPMAPS, [1008, True]),
                                                     ("babylon", BABYLON_MIPMAPS, [3, True])])
def test_mipmapped_step_maps_draw_the_same_hits(scene, engine, script, switched):
    cams = [camera(*v) for v in VIEWS]
    w, h = SIZE
    with serving(scene, engine) as url, Chromium(w, h) as b:
        load(b, url)
        b.eval("window.csmViewer.showPanel(false)")
        plain = _raw(b, cams)
        lit_plain = png(b.screenshot())
        assert b.eval(script) == [switched, switched]
        mipped = _raw(b, cams)
        lit_mipped = png(b.screenshot())
        for k, ((uv0, info0), (uv1, info1)) in enumerate(zip(plain, mipped)):
            relief = (uv0[..., 3] == 1) & (info0[..., 1] > 0)  # hit: status 0 (+1)
            assert relief.sum() > 0.1 * w * h, (k, relief.sum())
            assert np.array_equal(uv0, uv1) and np.array_equal(info0, info1), (
                k, float(np.mean((uv0 != uv1).any(-1)[relief])))
        # the mipmaps are in use: the lit picture's normals (textureGrad of the slopes) filter far away
        assert np.abs(lit_plain - lit_mipped).max() > 0.05
        for cam, least in zip(cams, (0.99, 0.99, 0.95)):  # and the march still agrees with moderngl's
            s = compare_hits(b, scene, cam)  # (measured 99.8%, 99.2%, 96.1% within a texel: the last far, grazing)
            assert s["status_agree"] >= 0.99 and s["within_1_texel"] >= least, s["within_1_texel"]
        assert not b.console_errors(), b.console_errors()
