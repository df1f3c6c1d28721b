"""Both web plugins upload a step map's level chain (stepMapLevelsTexture, csm_levels.js) as its
mip levels, in a real browser (headless chromium, WebGL2).

The bricks (a 128² map repeated twelve times) converted with ``--levels average`` and drawn far
away (about 8 level-0 texels a pixel: csm.glsl marches level 2) by three.js and by Babylon.js
agree with moderngl's level march of the same scene (its levels uploaded as mip levels, as
csm_assets.render does): hit uv within one texel of the level marched on at least 99% of the
relief pixels. The
levels are in use: with the plugin's ``levels`` uniform set to 0 the hits change, and are then
those of the same scene converted without levels (a mipmapped sampler marched at level 0 draws an
unmipped one's hits), as they are near the camera (level 0) with the levels on. A quadrant map
uploads the levels of both its images (stepMap2LevelsTexture too). A levels image of the wrong size:
one console warning, and that material draws level 0 alone.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from cdp import Chromium
from view_page import SIZE, browser_raw, camera, compare_hits, convert, load, needs_browser, serving
from view_scenes import moderngl_lods, two_material_scene

pytestmark = pytest.mark.browser
ENGINES = ("three", "babylon")
TRANSFORM = {"scale": [12.0, 12.0]}  # the bricks' 128² map: 1536 texels across their quad
FAR = [((-0.6, 0.0, 1.4), (-0.6, 0.0, 0.0)),     # straight on: about 8 texels a pixel
       ((-0.6, -1.0, 1.0), (-0.6, 0.0, 0.0))]    # 45 degrees
NEAR = ((-0.6, -0.15, 0.3), (-0.6, 0.0, 0.0))     # up to 4 texels a pixel: level 0
LEVELS = {  # the plugin's `levels` uniform of each material (null: drawn plain), and a setter
    "three": ("window.csmViewer.materials().map((m) => m.userData.csm.uniforms && m.userData.csm.uniforms.levels.value)",
              "for (const m of window.csmViewer.materials()) m.userData.csm.uniforms.levels.value = {n};"),
    "babylon": ("window.csmViewer.materials().map((m) => m.metadata.csm.uniforms && m.metadata.csm.uniforms.levels)",
                "for (const m of window.csmViewer.materials()) m.metadata.csm.uniforms.levels = {n};"
                "window.csmViewer.materials()[0].getScene().resetCachedMaterial();"),
}


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """(the scene converted with --levels average, the same without levels)."""
    src = two_material_scene(tmp_path_factory.mktemp("src"), transform=TRANSFORM)
    return (convert(src, tmp_path_factory.mktemp("levels"), "--levels", "average"),
            convert(src, tmp_path_factory.mktemp("plain"), "--levels", "none"))


def _within_a_level_texel(scene, cam, s) -> float:
    """The share of :func:`compare_hits`' relief pixels whose browser hit is within one texel of the
    level moderngl marched there (a level-k march steps 1.5 of its texels at least: GPUs that take
    one step more or fewer differ by that much)."""
    lod = moderngl_lods(scene, cam, SIZE)[s["relief_mask"]]
    err = np.hypot(*((s["raw"][..., :2] - s["ref_uv"]) * s["texels"]).transpose(2, 0, 1))[s["relief_mask"]]
    return float(np.mean(err <= 2.0 ** lod))


def _hits(b, cams):
    return [(browser_raw(b, c, "rawUv"), browser_raw(b, c, "rawInfo")) for c in cams]


def _same(a, b):
    """The share of pixels whose raw hit (uv, status) and iterations are the same in both drawings."""
    return float(np.mean([np.mean(np.all(x[0] == y[0], -1) & np.all(x[1] == y[1], -1)) for x, y in zip(a, b)]))


def _warnings(b) -> list[str]:
    return [e["params"]["args"][0].get("value", "") for e in b.events
            if e.get("method") == "Runtime.consoleAPICalled" and e["params"].get("type") == "warning"]


def test_the_moderngl_reference_marches_level_2_far_and_level_0_near(scenes):
    levels, _ = scenes
    far = moderngl_lods(levels, camera(*FAR[0]), SIZE)
    assert np.median(far[far >= 0]) == 2, np.unique(far, return_counts=True)
    near = moderngl_lods(levels, camera(*NEAR), SIZE)
    assert near.max() == 0 and (near == 0).mean() > 0.5


@pytest.mark.parametrize("engine", ENGINES)
def test_levels_are_uploaded_and_match_the_moderngl_level_march(scenes, engine):
    levels, plain = scenes
    far, near = [camera(*v) for v in FAR], camera(*NEAR)
    with serving(plain, engine) as url, Chromium(*SIZE) as b:
        load(b, url)
        assert b.eval(LEVELS[engine][0]) == [0, 0]
        unmipped, unmipped_near = _hits(b, far), _hits(b, [near])
    with serving(levels, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert all(m["fallback"] is None for m in info["materials"]), info
        n = b.eval(LEVELS[engine][0])
        assert n == [7, 8], n  # the bricks. 128²: levels 64² .. 1²; the cobbles. 256x192: 128x96 .. 1x1
        for cam in far:
            s = compare_hits(b, levels, cam)
            assert s["relief"] > 0.2 * SIZE[0] * SIZE[1], s["relief"]
            assert s["status_agree"] >= 0.99 and _within_a_level_texel(levels, cam, s) >= 0.99, s["status_agree"]
        chained = _hits(b, far)
        assert _same(_hits(b, [near]), unmipped_near) == 1.0  # level 0 near the camera: today's hits
        b.eval(LEVELS[engine][1].format(n=0))  # the mipmapped step map marched at level 0
        at_level_0 = _hits(b, far)
        assert _same(at_level_0, unmipped) == 1.0
        assert _same(chained, unmipped) < 0.8, _same(chained, unmipped)  # the levels were marched
        assert not b.console_errors(), b.console_errors()
        assert not [w for w in _warnings(b) if "EXT_materials_cone_step_mapping" in w], _warnings(b)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_quadrant_map_uploads_the_levels_of_both_images(tmp_path, engine):
    src = two_material_scene(tmp_path / "src", transform=TRANSFORM)
    scene = convert(src, tmp_path / "out", "--cones", "quadrant", "--levels", "average")
    with serving(scene, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert all(m["fallback"] is None for m in info["materials"]), info
        assert b.eval(LEVELS[engine][0]) == [7, 8]
        for cam in (camera(*v) for v in FAR):
            s = compare_hits(b, scene, cam)
            assert s["status_agree"] >= 0.99 and _within_a_level_texel(scene, cam, s) >= 0.99, s["status_agree"]
        assert not b.console_errors(), b.console_errors()


@pytest.mark.parametrize("engine", ENGINES)
def test_a_levels_image_of_the_wrong_size_warns_once_and_draws_level_0(scenes, engine, tmp_path):
    levels, plain = scenes
    doc = json.loads(levels.read_text())
    (bricks,) = [m for m in doc["materials"] if m["name"] == "bricks"]
    info = bricks["extensions"]["EXT_materials_cone_step_mapping"]["stepMapLevelsTexture"]
    uri = doc["images"][doc["textures"][info["index"]]["source"]]["uri"]
    for f in levels.parent.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    img = Image.open(levels.parent / uri)
    img.crop((0, 0, img.width - 1, img.height)).save(tmp_path / uri)  # one column short
    far = [camera(*v) for v in FAR]
    with serving(plain, engine) as url, Chromium(*SIZE) as b:
        load(b, url)
        unmipped = _hits(b, far)
    with serving(tmp_path / levels.name, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert all(m["fallback"] is None for m in info["materials"]), info
        n = b.eval(LEVELS[engine][0])
        assert n[0] == 0 and n[1] > 0, n  # the bricks on level 0, the cobbles keep their levels
        warned = [w for w in _warnings(b) if "EXT_materials_cone_step_mapping" in w]
        assert len(warned) == 1 and "bricks" in warned[0] and "126x64, not 127x64" in warned[0], warned
        got = _hits(b, far)
        bricks_side = np.s_[:, : SIZE[0] * 2 // 3]
        assert np.mean([np.all(g[0][bricks_side] == u[0][bricks_side], -1).mean() for g, u in zip(got, unmipped)]) == 1.0
        assert not b.console_errors(), b.console_errors()
