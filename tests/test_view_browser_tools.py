"""The viewer on scenes made by real glTF tools and converted by csm-assets, in headless chromium.

gltfpack (quantized geometry; ``-cc`` meshopt into a GLB with its images inside) and
gltf-pipeline (``-d`` Draco) are installed from npm at test time (tests/gltf_tools.py).
gltfpack puts a KHR_texture_transform on every texture (the dequantization of its uvs), and
the gltf-pipeline scene carries one with a rotation and an unequal scale: convert copies it
onto the step map's textureInfo, and the plugin must place the relief through it, as
csm-assets' own renderer does. Each scene's hit uv is compared with the moderngl render of
the same camera (tests/view_page.py); the scene with the transform dropped must fail it. The
Draco and meshopt outputs stay compressed: the page decodes them (DRACOLoader, MeshoptDecoder; the
Babylon.js page with the same decoders through its DracoDecoder and MeshoptCompression), in both engines.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cdp import Chromium
from conftest import SAMPLES
from gltf_tools import draco, gltfpack
from view_page import SIZE, camera, compare_hits, convert, load, needs_browser, serving, uv_screenshot_agreement
from view_scenes import two_material_scene

pytestmark = pytest.mark.browser
TRANSFORM = {"offset": [0.25, -0.5], "scale": [3.0, 2.0], "rotation": 0.3}
MIRRORED = 33648
VIEWS = {"two": ((0.3, 0.6, 1.6), (0.0, 0.0, 0.0)), "wall": ((0.9, 0.9, 1.1), (0.0, 0.5, 0.0))}


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> dict:
    """name -> (converted scene, its view): the two-material scene through gltfpack (quantized;
    bricks' images files beside it, the cobbles image embedded in its buffer), the wall through
    gltfpack -cc (a meshopt GLB holding its images) and the two-material scene with TRANSFORM
    on the bricks and a mirrored sampler on the cobbles' heights through gltf-pipeline -d."""
    root = tmp_path_factory.mktemp("tools")
    plain = two_material_scene(root / "plain", cobbles_color=True)
    shutil.copy(SAMPLES / "cobbles.png", plain.parent / "cobbles.png")  # gltfpack drops the heights
    heights = ["--height", f"bricks={plain.parent / 'bricks_height.png'}",
               "--height", f"cobbles={plain.parent / 'cobbles.png'}"]
    quantized = convert(gltfpack(plain, plain.parent / "two_q.gltf"), root / "out_q", *heights)
    wall = root / "wall"
    wall.mkdir()
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, wall / name)
    meshopt = convert(gltfpack(wall / "brick_wall.gltf", wall / "wall_mo.glb", "-cc"), root / "out_mo",
                      "--height", f"bricks={wall / 'bricks_height.png'}")
    rotated = two_material_scene(root / "rotated", transform=TRANSFORM)
    doc = json.loads(rotated.read_text())
    doc["samplers"] = [{"wrapS": MIRRORED, "wrapT": 10497}]
    doc["textures"][2]["sampler"] = 0
    rotated.write_text(json.dumps(doc))
    compressed = convert(draco(rotated, rotated.parent / "two_draco.gltf"), root / "out_d")
    return {"gltfpack": (quantized, VIEWS["two"]), "gltfpack-meshopt-glb": (meshopt, VIEWS["wall"]),
            "gltf-pipeline-draco": (compressed, VIEWS["two"])}


def step_map_infos(scene: Path) -> list[dict]:
    from csm_assets.formats import gltf_container as gc

    doc = gc.load(scene)
    return [m["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"] for m in doc.json["materials"]]


@pytest.mark.parametrize("engine", ["three", "babylon"])
@pytest.mark.parametrize("name", ["gltfpack", "gltfpack-meshopt-glb", "gltf-pipeline-draco"])
def test_tool_made_scenes_match_moderngl(scenes, name, engine):
    scene, view = scenes[name]
    infos = step_map_infos(scene)
    transforms = [i["extensions"]["KHR_texture_transform"] for i in infos if "extensions" in i]
    assert any(t.get("scale", [1, 1]) != [1, 1] for t in transforms), infos  # the transform matters here
    if name == "gltfpack-meshopt-glb":
        assert sorted(p.name for p in scene.parent.iterdir()) == ["csm-manifest.json", scene.name]
    packed = {"gltf-pipeline-draco": "KHR_draco_mesh_compression", "gltfpack-meshopt-glb": "EXT_meshopt_compression"}
    if name in packed:  # the output stays compressed: both engines decode it with three.js' decoders
        from csm_assets.formats import gltf_container as gc

        assert packed[name] in gc.load(scene).json["extensionsRequired"]
    with serving(scene, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert all(m["fallback"] is None for m in info["materials"]), info
        assert len(info["materials"]) == (1 if name == "gltfpack-meshopt-glb" else 2)
        cam = camera(*view)
        s = compare_hits(b, scene, cam)
        print(f"{name}: {s['within_1_texel']:.4%} of {s['relief']} relief pixels within 1 texel, median "
              f"{s['p50']:.3f}; status agrees on {s['status_agree']:.4%}")  # docs/measurements/accuracy.md's figures (pytest -s)
        assert s["relief"] > 0.3 * SIZE[0] * SIZE[1], s["relief"]
        assert s["status_agree"] >= 0.99, s["status_agree"]
        assert s["within_1_texel"] >= 0.998, (s["within_1_texel"], s["p50"])
        if len(info["materials"]) == 2:  # both quads drawn with relief
            hit = s["relief_mask"]
            assert hit[:, : SIZE[0] // 3].mean() > 0.2 and hit[:, -SIZE[0] // 3:].mean() > 0.2
        shown, flat = uv_screenshot_agreement(b, scene, cam)
        print(f"{name}: screenshot shows the hit uv on {shown:.2%}, the polygon's uv on {flat:.2%}")
        assert shown >= 0.95 and flat < shown - 0.2, (shown, flat)
        assert not b.console_errors(), b.console_errors()


def test_dropping_the_step_maps_transform_fails_the_comparison(scenes, tmp_path):
    """What the plugin drew before it read KHR_texture_transform: the same scene with the
    step map's transform removed disagrees with moderngl's render of the real one."""
    scene, view = scenes["gltf-pipeline-draco"]
    for f in scene.parent.iterdir():
        shutil.copy(f, tmp_path / f.name)
    doc = json.loads(scene.read_text())
    for m in doc["materials"]:
        m["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"].pop("extensions", None)
    (tmp_path / scene.name).write_text(json.dumps(doc))
    with serving(tmp_path / scene.name) as url, Chromium(*SIZE) as b:
        load(b, url)
        s = compare_hits(b, scene, camera(*view))  # the browser draws the copy, moderngl the original
        bricks = s["relief_mask"][:, : SIZE[0] // 2]
        err_ok = s["within_mask"][:, : SIZE[0] // 2]
        assert bricks.sum() > 1000
        print(f"transform dropped: {err_ok[bricks].mean():.2%} of the bricks' relief pixels within 1 texel")
        assert err_ok[bricks].mean() < 0.05, err_ok[bricks].mean()


PLACEMENT_PROBE = """(async () => {
  const { uvPlacement } = await import('./web/csm_plugin.js');
  return %s.map((info) => uvPlacement(info));
})()"""


def test_uv_placement_is_the_python_transform(scenes):
    """The plugin's texture transform (and texCoord override) against csm_assets' apply_transform."""
    from csm_assets.formats.gltf import apply_transform

    infos = [{}, {"texCoord": 1}, {"index": 0, "extensions": {"KHR_texture_transform": TRANSFORM}},
             {"texCoord": 0, "extensions": {"KHR_texture_transform": {"rotation": -1.2, "texCoord": 1}}},
             {"extensions": {"KHR_texture_transform": {"scale": [16.003664, 0.5], "offset": [0, 1]}}}]
    scene, _ = scenes["gltfpack"]
    with serving(scene) as url, Chromium(*SIZE) as b:
        load(b, url)
        got = b.eval(PLACEMENT_PROBE % json.dumps(infos))
    uv = np.random.default_rng(1).uniform(-2, 3, (20, 2))
    for info, placed in zip(infos, got):
        t = info.get("extensions", {}).get("KHR_texture_transform")
        assert placed["texCoord"] == (t or {}).get("texCoord", info.get("texCoord", 0))
        a, b_, c, d, ox, oy = placed["matrix"]
        mine = uv @ np.array([[a, c], [b_, d]]) + [ox, oy]
        np.testing.assert_allclose(mine, apply_transform(uv, t), atol=1e-12)
