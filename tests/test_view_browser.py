"""The viewer in a real browser: headless chromium (WebGL2 on SwiftShader) against moderngl.

Each test serves a converted scene with ``csm-assets view --no-browser``, loads the page,
sets the camera to the exact view and projection matrices of a
:class:`csm_assets.render.renderer.Camera`, and compares the plugin's hit uv (read from a float
render target) with the project's moderngl render of the same camera and size. Skips
when chromium or EGL is missing. Set ``CSM_VIEWER_SCREENSHOT=PATH`` to keep the lit
screenshot of the two-material scene (the README's and the docs' picture).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from cdp import Chromium
from conftest import SAMPLES
from view_page import (SIZE, browser_raw, camera, compare_hits, convert, load, needs_browser, png, serving,
                       uv_screenshot_agreement)
from view_scenes import cylinder_scene, two_material_scene

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    out = tmp_path_factory.mktemp("wall")
    return convert(SAMPLES / "brick_wall.gltf", out)


WALL_VIEWS = [((0.9, 0.9, 1.1), (0.0, 0.5, 0.0)), ((-0.2, 0.3, 0.9), (0.1, 0.5, 0.0)),
              ((1.2, 0.55, 0.3), (0.0, 0.5, 0.0))]  # the last at 14 degrees: grazing


def test_wall_hit_uv_matches_moderngl_and_relief_shows(wall):
    w, h = SIZE
    with serving(wall) as url, Chromium(w, h) as b:
        info = load(b, url)
        assert [m["fallback"] for m in info["materials"]] == [None]
        for eye, target in WALL_VIEWS:
            s = compare_hits(b, wall, camera(eye, target))
            assert s["relief"] > 0.3 * w * h, s["relief"]
            assert s["status_agree"] >= 0.99, s["status_agree"]
            assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])
        # the screenshot: the hit uv view shows the relief's uv, not the polygon's (the fallback)
        shown, flat = uv_screenshot_agreement(b, wall, camera(*WALL_VIEWS[0]))
        assert shown >= 0.95 and flat < shown - 0.2, (shown, flat)
        b.eval("window.csmViewer.setDebug('lit')")
        lit = b.screenshot()
        b.eval("window.csmViewer.setDebug('off')")
        plain = png(b.screenshot())
        assert np.mean(np.abs(png(lit) - plain).max(axis=-1) > 0.05) > 0.2
        b.eval("window.csmViewer.setDebug('heat')")
        heat = png(b.screenshot())
        assert np.mean(np.abs(heat - plain).max(axis=-1) > 0.05) > 0.3
        assert not b.console_errors(), b.console_errors()


def test_glb_hit_uv_matches_moderngl(tmp_path):
    """The GLB's images live in its binary chunk; --no-tile: rays leaving the map miss (CLAMP)."""
    scene = convert(SAMPLES / "brick_wall.glb", tmp_path / "out", "--no-tile")
    for p in scene.parent.glob("*.png"):  # the GLB holds its images: the files beside it are not needed
        p.unlink()
    with serving(scene) as url, Chromium(*SIZE) as b:
        load(b, url)
        assert b.eval("window.csmViewer.ready")["materials"][0]["extension"]["tile"] == [False, False]
        s = compare_hits(b, scene, camera(*WALL_VIEWS[0]))
        assert s["relief"] > 0.3 * SIZE[0] * SIZE[1]
        assert s["status_agree"] >= 0.99, s["status_agree"]
        assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])
        misses = np.rint(s["raw"][..., 3]) == 3
        assert misses.sum() > 50, misses.sum()  # the wall's edges: rays that leave the map


def test_two_materials_external_and_embedded_images(tmp_path):
    scene = convert(two_material_scene(tmp_path / "src"), tmp_path / "out")
    with serving(scene) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert sorted(m["name"] for m in info["materials"]) == ["bricks", "cobbles"]
        assert all(m["fallback"] is None for m in info["materials"])
        cam = camera((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))
        s = compare_hits(b, scene, cam)
        assert s["status_agree"] >= 0.99, s["status_agree"]
        assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])
        hit = s["relief_mask"]
        assert hit[:, : SIZE[0] // 3].mean() > 0.2 and hit[:, -SIZE[0] // 3:].mean() > 0.2  # both quads
        b.eval("window.csmViewer.showPanel(false)")
        lit = b.screenshot()
        b.eval("window.csmViewer.setDebug('off')")
        plain = png(b.screenshot())
        changed = np.abs(png(lit) - plain).max(axis=-1) > 0.05
        assert changed[:, : SIZE[0] // 3].mean() > 0.2 and changed[:, -SIZE[0] // 3:].mean() > 0.2
        assert not b.console_errors(), b.console_errors()
    if os.environ.get("CSM_VIEWER_SCREENSHOT"):  # the README's and the docs' picture
        Path(os.environ["CSM_VIEWER_SCREENSHOT"]).write_bytes(lit)


def test_curved_mesh_with_a_uv_seam(tmp_path):
    """A cylinder: interpolated MikkTSpace tangents and normals, the texture wrapped twice round."""
    scene = convert(cylinder_scene(tmp_path / "src"), tmp_path / "out")
    with serving(scene) as url, Chromium(*SIZE) as b:
        load(b, url)
        s = compare_hits(b, scene, camera((0.4, 0.9, 1.9), (0.0, 0.5, 0.0)))
        assert s["relief"] > 0.15 * SIZE[0] * SIZE[1], s["relief"]
        assert s["status_agree"] >= 0.99, s["status_agree"]
        assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])


def test_switching_variant_and_steps_recompiles(wall):
    with serving(wall) as url, Chromium(*SIZE) as b:
        load(b, url)
        cam = camera(*WALL_VIEWS[0])
        exact = browser_raw(b, cam, "rawInfo")
        b.eval("window.csmViewer.setVariant('fixed', 3)")
        fixed = browser_raw(b, cam, "rawInfo")
        drawn = fixed[..., 1] > 0
        assert np.all(fixed[..., 0][drawn] == 3)  # the fixed variant runs its steps, no more
        assert np.mean(exact[..., 0][drawn]) > 3
        assert not b.console_errors(), b.console_errors()




FALLBACK_PROBE = """(async () => {
  const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
  const { CSMExtension } = await import('./web/csm_plugin.js');
  const loader = new GLTFLoader();
  loader.register((parser) => new CSMExtension(parser, { webgl2: false }));
  const gltf = await loader.loadAsync('scene/brick_wall.gltf');
  const out = [];
  gltf.scene.traverse((o) => { if (o.isMesh) out.push([o.material.userData.csm.fallback, !!o.geometry.attributes.csmDpdu]); });
  return out;
})()"""


def test_fallbacks_without_webgl2_or_tangents(wall, tmp_path):
    """The plain PBR material where the relief cannot run: no WebGL2, or a mesh without TANGENT."""
    with serving(wall) as url, Chromium(*SIZE) as b:
        load(b, url)
        assert b.eval(FALLBACK_PROBE) == [["no WebGL2", False]]
    doc = json.loads(wall.read_text())
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            del prim["attributes"]["TANGENT"]
    for f in wall.parent.iterdir():
        if f.is_file():
            shutil.copy(f, tmp_path / f.name)
    (tmp_path / wall.name).write_text(json.dumps(doc))
    with serving(tmp_path / wall.name) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert [m["fallback"] for m in info["materials"]] == ["no TANGENT"]
        assert not b.console_errors(), b.console_errors()
