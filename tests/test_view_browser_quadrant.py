"""Quadrant step maps in a real browser (headless chromium, WebGL2 on SwiftShader) against moderngl.

The scene: the two-material scene converted, then its bricks made a quadrant material by the
library (``view_scenes.quadrant_material``: the quadrant maps of the same heights, two images,
``stepMap2Texture``, variant quadrant); the cobbles stay a one-image (conservative) material.
The plugin draws the bricks with the quadrant variant: hit uv and iterations agree with the
project's Renderer drawing the same material (views whose rays run into different quadrants,
one into the second image's cone), and the lit picture equals the one-image material's (the
same slopes, now read from the second image). setVariant and the viewer's menu refuse what
cannot draw a map; a broken quadrant extension falls back to the plain material."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from cdp import Chromium
from view_page import SIZE, browser_raw, camera, compare_hits, convert, load, needs_browser, png, serving
from view_scenes import moderngl_iterations, quadrant_material, two_material_scene

pytestmark = pytest.mark.browser
EXT = "EXT_materials_cone_step_mapping"
VIEW = ((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))  # both quads; rays into -u+v
# rays on the bricks into +u-v (the second image's cone) and into -u-v
QUADRANT_VIEWS = [((-1.4, -0.7, 1.0), (-0.6, 0.0, 0.0)), ((0.4, -0.6, 1.0), (-0.6, 0.0, 0.0))]


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """(the scene with quadrant bricks, the same scene as converted: one-image bricks)."""
    # without level chains: quadrant_material makes the second image by hand, with no chain of its
    # own (a quadrant map's chains: tests/test_view_browser_levels.py)
    plain = convert(two_material_scene(tmp_path_factory.mktemp("src")), tmp_path_factory.mktemp("out"),
                    "--levels", "none")
    quad = tmp_path_factory.mktemp("quad") / "s"
    shutil.copytree(plain.parent, quad)
    quadrant_material(quad / plain.name, "bricks")
    return quad / plain.name, plain


@pytest.fixture
def scene(scenes, tmp_path):
    shutil.copytree(scenes[0].parent, tmp_path / "s")
    return tmp_path / "s" / scenes[0].name


TEXTURES = """(() => window.csmViewer.materials().map((m) => {
  const t = (x) => x && { size: [x.image.width, x.image.height], wrap: [x.wrapS, x.wrapT], filter: [x.minFilter, x.magFilter],
    mipmaps: x.generateMipmaps, colorSpace: x.colorSpace, flipY: x.flipY, source: x.source.uuid };
  const u = m.userData.csm.uniforms;
  return { name: m.name, quadrant: m.userData.csm.quadrant, defines: m.defines,
           stepmap: t(u.stepmap.value), stepmap2: u.stepmap2 ? t(u.stepmap2.value) : null };
}))()"""


def test_quadrant_material_matches_moderngl(scenes):
    scene, _ = scenes
    w, h = SIZE
    with serving(scene) as url, Chromium(w, h) as b:
        info = load(b, url)
        assert {m["name"]: (m["variant"], m["fallback"]) for m in info["materials"]} == {
            "bricks": ("quadrant", None), "cobbles": ("exact", None)}
        bricks, cobbles = b.eval(TEXTURES)
        # both images loaded, sampled alike: LINEAR (1006) without mipmaps, REPEAT (1000) (tiled), no colour space
        assert bricks["quadrant"] and "CSM_QUADRANT_MAPS" in bricks["defines"]
        assert bricks["defines"]["CSM_INTERSECT"] == "intersect_cone_quadrant"
        assert bricks["stepmap"]["source"] != bricks["stepmap2"]["source"]
        for t in (bricks["stepmap"], bricks["stepmap2"], cobbles["stepmap"]):
            assert t["filter"] == [1006, 1006] and t["wrap"] == [1000, 1000] and t["mipmaps"] is False
        assert {k: v for k, v in bricks["stepmap2"].items() if k != "source"} == {
            k: v for k, v in bricks["stepmap"].items() if k != "source"}
        assert bricks["stepmap"]["size"] == [128, 128] and bricks["stepmap"]["colorSpace"] == ""
        assert cobbles["stepmap2"] is None and not cobbles["quadrant"] and "CSM_QUADRANT_MAPS" not in cobbles["defines"]
        for k, (eye, target) in enumerate([VIEW, *QUADRANT_VIEWS]):
            cam = camera(eye, target)
            s = compare_hits(b, scene, cam)
            assert s["relief"] > 0.2 * w * h, (k, s["relief"])
            assert s["status_agree"] >= 0.99, (k, s["status_agree"])
            assert s["within_1_texel"] >= 0.99, (k, s["within_1_texel"], s["p50"])
            # the fetches too: a cone read from the wrong image or channel changes them
            raw = browser_raw(b, cam, "rawInfo")
            ref = moderngl_iterations(scene, cam, SIZE)
            on = (raw[..., 1] > 0) & (ref >= 0)
            assert on.sum() > 0.1 * w * h, (k, on.sum())
            it = raw[..., 0][on]
            assert np.mean(np.abs(it - ref[on]) <= 1) >= 0.98, k  # measured 99.2-99.8%
            assert abs(it.mean() - ref[on].mean()) <= 0.02 * ref[on].mean(), (k, it.mean(), ref[on].mean())
        assert not b.console_errors(), b.console_errors()


def _lit(url: str, cam) -> np.ndarray:
    with Chromium(*SIZE) as b:
        load(b, url)
        b.eval("window.csmViewer.showPanel(false)")
        view, proj = cam.view(), cam.projection(SIZE[0] / SIZE[1])
        b.eval(f"window.csmViewer.setCamera({view.ravel().tolist()}, {proj.ravel().tolist()})")
        return png(b.screenshot())


def test_lit_quadrant_material_is_the_one_image_material(scenes):
    """The same heights drawn from the quadrant map and from the one-image map: the same hits and
    the same slopes (the quadrant map's from its second image), so the same lit picture."""
    cam = camera(*VIEW)
    with serving(scenes[0]) as url:
        quad = _lit(url, cam)
    with serving(scenes[1]) as url:
        plain = _lit(url, cam)
    differ = np.abs(quad - plain).max(axis=-1) > 2 / 255
    left = np.zeros_like(differ)
    left[:, : SIZE[0] // 3] = True
    assert np.mean(np.abs(quad - 0x30 / 255).max(axis=-1)[left] > 0.05) > 0.3  # the bricks, not the background
    assert np.mean(differ[left]) <= 0.01, np.mean(differ[left])


MENU = "[...document.getElementById('variant').options].filter((o) => !o.disabled).map((o) => o.value)"


def _select(b: Chromium, element: str, value: str) -> None:
    b.eval(f"(() => {{ const e = document.getElementById('{element}'); e.value = '{value}'; "
           "e.dispatchEvent(new Event('change')); return 1; })()")


REFUSALS = """(async () => {
  const { setVariant } = await import('./web/csm_plugin.js');
  const out = [];
  for (const [i, v] of [[0, 'exact'], [0, 'relaxed'], [1, 'quadrant']]) {
    const m = window.csmViewer.materials()[i];
    try { setVariant(m, v); out.push(null); } catch (e) { out.push(`${e.constructor.name}: ${e.message}`); }
  }
  return out.concat(window.csmViewer.materials().map((m) => m.userData.csm.variant));
})()"""


def test_variant_menu_and_refusals(scenes):
    with serving(scenes[0]) as url, Chromium(*SIZE) as b:
        load(b, url)
        bricks_exact, bricks_relaxed, cobbles_quadrant, *kept = b.eval(REFUSALS)
        assert bricks_exact == ('Error: material "bricks" holds a quadrant step map (two images); only the '
                                'quadrant variant draws it, not exact')
        assert bricks_relaxed.endswith("not relaxed")
        assert cobbles_quadrant == ('Error: material "cobbles" holds a one-image step map; the quadrant variant '
                                    'draws quadrant step maps (stepMap2Texture) only')
        assert kept == ["quadrant", "exact"]  # a refusal changes nothing
        others = ["exact", "loop", "fixed", "parallax", "pom", "relief", "relaxed"]
        _select(b, "material", "0")
        assert b.eval(MENU) == ["quadrant"]
        _select(b, "material", "1")
        assert b.eval(MENU) == others
        _select(b, "material", "all")
        assert b.eval(MENU) == [*others, "quadrant"]
        _select(b, "variant", "loop")  # for all: the cobbles switch, the bricks keep quadrant and the page says so
        assert [m["variant"] for m in b.eval("window.csmViewer.materials().map((m) => m.userData.csm)")] == [
            "quadrant", "loop"]
        said = b.eval("document.getElementById('status').textContent")
        assert "kept their variant" in said and '"bricks" holds a quadrant step map' in said, said
        assert b.eval("window.csmViewer.setVariant('quadrant')") == {
            "switched": ["bricks"], "refused": [cobbles_quadrant.removeprefix("Error: ")]}
        raw = browser_raw(b, camera(*VIEW), "rawUv")
        hit = np.rint(raw[..., 3]) == 1
        assert hit[:, : SIZE[0] // 3].mean() > 0.2 and hit[:, -SIZE[0] // 3:].mean() > 0.2  # both still drawn
        assert not b.console_errors(), b.console_errors()


def _texture_of(doc: dict, uri: str) -> int:
    (i,) = [i for i, t in enumerate(doc["textures"]) if doc["images"][t["source"]].get("uri") == uri]
    return i


BAD = {  # change to the bricks' extension -> what the fallback says
    "no second image": ({"stepMap2Texture": None}, "stepMap2Texture is missing"),
    "second image with exact": ({"variant": "exact"}, "drawn only by variant quadrant, not exact"),
    "texCoord differs": ({"stepMap2Texture": {"index": 6, "texCoord": 1}}, "texCoord 1 is not stepMapTexture's 0"),
    "second index -1": ({"stepMap2Texture": {"index": -1}}, "stepMap2Texture.index -1 is below 0"),
    "second index 99": ({"stepMap2Texture": {"index": 99}}, "second step map texture (stepMap2Texture) 99 did not load"),
    "second of another size": ({"stepMap2Texture": "cobbles"}, "differ in size (128x128, stepMap2Texture 256x192)"),
}


def test_broken_quadrant_extensions_fall_back(scene):
    good = json.loads(scene.read_text())
    assert good["materials"][0]["extensions"][EXT]["stepMap2Texture"] == {"index": 6, "texCoord": 0}
    with serving(scene) as url, Chromium(*SIZE) as b:
        for case, (change, said) in BAD.items():
            doc = json.loads(json.dumps(good))
            ext = doc["materials"][0]["extensions"][EXT]
            for k, v in change.items():
                if v is None:
                    ext.pop(k)
                else:
                    ext[k] = {"index": _texture_of(doc, "cobbles_csm.png")} if v == "cobbles" else v
            scene.write_text(json.dumps(doc))
            info = load(b, url)
            fallbacks = {m["name"]: m["fallback"] for m in info["materials"]}
            assert fallbacks["cobbles"] is None, case
            assert fallbacks["bricks"] and said in fallbacks["bricks"], (case, fallbacks["bricks"])
            raw = browser_raw(b, camera(*VIEW), "rawUv")
            hit = np.rint(raw[..., 3]) == 1
            assert hit[:, : SIZE[0] // 3].mean() > 0.2 and hit[:, -SIZE[0] // 3:].mean() > 0.2, case  # all drawn
            assert not b.console_errors(), (case, b.console_errors())
