"""The same converted scenes drawn by both web engines, three.js (csm_plugin.js) and Babylon.js
(csm_babylon.js), in headless chromium through ``csm-assets view --engine``, each against the
moderngl reference render and against each other: conservative, relaxed and quadrant step maps,
self-shadows, a curved mesh, the relief on a second uv set, a texture transform.

Hit uv: within one texel of moderngl's on at least 98% of the relief pixels (both say hit), and
within one texel of the other engine's on 98%. Lit: the engines shade with their own PBR
models and lights, moderngl with Lambert (white, one directional light, its self-shadowed share);
the stated tolerance is a rank correlation (lit_agreement) of the relief pixels' luminance of at
least LIT_MIN with moderngl's and with the other engine's. A material whose extension breaks the
schema falls back alone, with one console warning, in both engines.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdp import Chromium
from conftest import SAMPLES
from engine_scenes import lit_agreement, luminance, moderngl_lit, two_uv_scene, without_base_colour
from view_page import SIZE, browser_raw, camera, compare_hits, convert, load, needs_browser, png, serving
from view_scenes import cylinder_scene, moderngl_shadows, two_material_scene

pytestmark = pytest.mark.browser
ENGINES = ("three", "babylon")
LIGHT = (0.6, 0.8, 0.9)  # world direction towards the viewers' sun and moderngl's light
LIT_MIN = 0.9  # measured: 0.97 to 0.99 (three.js 0.989 and Babylon.js 0.973 on the self-shadowed wall)
TRANSFORM = {"offset": [0.25, -0.5], "scale": [3.0, 2.0], "rotation": 0.3}
TWO = ((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))
WALL = ((0.9, 0.9, 1.1), (0.0, 0.5, 0.0))

# name -> (how the converted scene is made from a temporary folder, the camera)
CASES = {
    "transform": (lambda d: convert(two_material_scene(d / "src", transform=TRANSFORM), d / "out"), TWO),
    "relaxed": (lambda d: convert(two_material_scene(d / "src"), d / "out", "--cones", "relaxed"), TWO),
    "quadrant": (lambda d: convert(two_material_scene(d / "src"), d / "out", "--cones", "quadrant"), TWO),
    "curved": (lambda d: without_base_colour(convert(cylinder_scene(d / "src"), d / "out")),
               ((0.4, 0.9, 1.9), (0.0, 0.5, 0.0))),
    "two_uv": (lambda d: convert(two_uv_scene(d / "src"), d / "out"), ((0.2, 0.5, 1.4), (0.0, 0.0, 0.0))),
    "self_shadow": (lambda d: without_base_colour(convert(SAMPLES / "brick_wall.gltf", d / "out", "--self-shadow")),
                    WALL),
}
LIT_CASES = {"curved", "self_shadow"}  # white surfaces: their lit images compare with moderngl's
# Lit comparisons that do not hold, with why. On the cylinder, three.js' viewer shades the
# polygon itself (the relief off too) brightest on the side away from the sun (rank correlation
# 0.72 with moderngl, which agrees with Babylon.js at 0.97): the viewer's lighting of curved
# meshes, the same before the plugins shared their code; its hit uv agrees (asserted above).
LIT_KNOWN = {("curved", "three")}


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


def draw(scene, engine: str, cam) -> dict:
    """One engine's drawing of the scene: compare_hits' answer, the lit screenshot (panel hidden,
    the sun towards LIGHT) and the raw light view."""
    with serving(scene, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert all(m["fallback"] is None for m in info["materials"]), info
        s = compare_hits(b, scene, cam)
        b.eval(f"window.csmViewer.setLight({LIGHT[0]}, {LIGHT[1]}, {LIGHT[2]})")
        s["light"] = browser_raw(b, cam, "rawLight")
        b.eval("window.csmViewer.showPanel(false)")
        b.eval("window.csmViewer.setDebug('lit')")
        s["lit"] = luminance(png(b.screenshot()))
        assert not b.console_errors(), b.console_errors()
    return s


@pytest.mark.parametrize("name", list(CASES))
def test_both_engines_match_moderngl_and_each_other(tmp_path, name):
    make, view = CASES[name]
    scene, cam = make(tmp_path), camera(*view)
    got = {engine: draw(scene, engine, cam) for engine in ENGINES}
    for engine, s in got.items():
        assert s["relief"] > 0.1 * SIZE[0] * SIZE[1], (engine, s["relief"])
        assert s["status_agree"] >= 0.98, (engine, s["status_agree"])
        assert s["within_1_texel"] >= 0.98, (engine, s["within_1_texel"], s["p50"])
    three, babylon = got["three"], got["babylon"]
    both = three["relief_mask"] & babylon["relief_mask"]
    err = np.hypot(*((three["raw"][..., :2] - babylon["raw"][..., :2]) * three["texels"]).transpose(2, 0, 1))[both]
    assert np.mean(err <= 1.0) >= 0.98, np.mean(err <= 1.0)
    if name == "self_shadow":  # hard lit of the sun, per pixel: both engines and moderngl
        status, ref = moderngl_shadows(scene, cam, SIZE, LIGHT)
        on = both & (status == 0)
        for engine, s in got.items():
            assert np.mean(s["light"][..., 3][on] == ref[..., 0][on]) >= 0.95, engine
        assert np.mean(three["light"][..., 3][on] == babylon["light"][..., 3][on]) >= 0.97
    if name in LIT_CASES:
        status, ref = moderngl_lit(scene, cam, SIZE, LIGHT)
        on = both & (status == 0)
        for engine, s in got.items():
            if (name, engine) in LIT_KNOWN:
                continue
            assert lit_agreement(s["lit"], ref, on) >= LIT_MIN, (engine, lit_agreement(s["lit"], ref, on))
        if not any(case == name for case, _ in LIT_KNOWN):
            assert lit_agreement(three["lit"], babylon["lit"], on) >= LIT_MIN



@pytest.mark.parametrize("engine", ENGINES)
def test_a_bad_extension_falls_back_per_material(tmp_path, engine):
    """One material's extension breaks the schema: that material alone is drawn plain, with one
    console warning naming it; the other keeps its relief (its hits match moderngl's render of
    the unbroken scene)."""
    good = convert(two_material_scene(tmp_path / "src"), tmp_path / "out")
    bad = good.with_name("bad.gltf")
    doc = json.loads(good.read_text())
    (cobbles,) = [m for m in doc["materials"] if m["name"] == "cobbles"]
    cobbles["extensions"]["EXT_materials_cone_step_mapping"]["depthScale"] = "abc"
    bad.write_text(json.dumps(doc))
    cam = camera(*TWO)
    with serving(bad, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        why = {m["name"]: m["fallback"] for m in info["materials"]}
        assert why["bricks"] is None and "depthScale must be a number" in why["cobbles"], why
        warned = [e["params"]["args"][0].get("value", "") for e in b.events
                  if e.get("method") == "Runtime.consoleAPICalled" and e["params"].get("type") == "warning"]
        assert [w for w in warned if "EXT_materials_cone_step_mapping" in w and "cobbles" in w] == \
            [w for w in warned if "EXT_materials_cone_step_mapping" in w], warned
        assert len([w for w in warned if "cobbles" in w]) == 1, warned
        s = compare_hits(b, good, cam)
        bricks = s["relief_mask"][:, : SIZE[0] // 3]
        assert bricks.mean() > 0.2
        assert s["within_mask"][:, : SIZE[0] // 3][bricks].mean() >= 0.98
        assert not b.console_errors(), b.console_errors()


@pytest.mark.parametrize("engine", ENGINES)
def test_a_mesh_without_tangents_is_drawn_plain(tmp_path, engine):
    """The cobbles' primitive loses its TANGENT: that mesh is drawn plain with one warning naming
    why; the bricks keep their relief."""
    good = convert(two_material_scene(tmp_path / "src"), tmp_path / "out")
    doc = json.loads(good.read_text())
    (cobbles,) = [m for m in doc["meshes"] if m["primitives"][0]["material"] == 1]
    del cobbles["primitives"][0]["attributes"]["TANGENT"]
    bad = good.with_name("bad.gltf")
    bad.write_text(json.dumps(doc))
    with serving(bad, engine) as url, Chromium(*SIZE) as b:
        load(b, url)
        warned = [e["params"]["args"][0].get("value", "") for e in b.events
                  if e.get("method") == "Runtime.consoleAPICalled" and e["params"].get("type") == "warning"]
        assert len([w for w in warned if "no TANGENT; plain PBR there" in w]) == 1, warned
        s = compare_hits(b, good, camera(*TWO))
        cobbles = s["relief_mask"][:, -SIZE[0] // 3:]  # the plain material writes its lit colour there, no hit uv
        assert cobbles.mean() > 0.2 and s["within_mask"][:, -SIZE[0] // 3:][cobbles].mean() < 0.2
        bricks = s["relief_mask"][:, : SIZE[0] // 3]
        assert bricks.mean() > 0.2 and s["within_mask"][:, : SIZE[0] // 3][bricks].mean() >= 0.98
        assert not b.console_errors(), b.console_errors()


@pytest.mark.parametrize("engine", ENGINES)
def test_every_one_image_variant_compiles_and_fixed_runs_its_steps(tmp_path, engine):
    """Switching variants recompiles without a shader error in both engines (Babylon's fixed
    variant unrolls its steps through CSM_FIXED_BIT defines): fixed with 5 steps takes 5."""
    scene = convert(SAMPLES / "brick_wall.gltf", tmp_path / "out")
    cam = camera(*WALL)
    with serving(scene, engine) as url, Chromium(*SIZE) as b:
        load(b, url)
        for variant in ("loop", "parallax", "pom", "relief", "relaxed", "fixed"):
            assert b.eval(f"window.csmViewer.setVariant('{variant}', 5)")["switched"] == ["bricks"]
            info = browser_raw(b, cam, "rawInfo")
            drawn = info[..., 1] > 0
            assert drawn.mean() > 0.3, (variant, drawn.mean())
        assert np.all(info[..., 0][drawn] == 5)  # fixed: its steps, no more
        assert not b.console_errors(), b.console_errors()
