"""Scene conversion end to end: step maps, tangents, the CSM material, and what is left alone."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from csm_assets import OutputError, load_heightfield, read_step_map, read_step_map_meta, step_map
from csm_assets.convert.pipeline import convert
from csm_assets.formats import gltf_container as gc
from conftest import GLTF_WALL, OBJ_WALL, SAMPLES, copy_samples
from khronos import errors, validate


@pytest.fixture
def src(tmp_path):
    return copy_samples(tmp_path / "in", GLTF_WALL)


def tangent_of(doc):
    prim = doc.json["meshes"][0]["primitives"][0]
    return gc.read_accessor(doc, prim["attributes"]["TANGENT"])


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.glb"])
def test_converts_the_sample_wall(src, tmp_path, name):
    out = tmp_path / "out"
    before = {p.name: p.read_bytes() for p in src.iterdir()}
    report = convert(src / name, out)
    assert {p.name: p.read_bytes() for p in src.iterdir()} == before  # inputs untouched
    step = out / "bricks_height_csm.png"
    expected = step_map(load_heightfield(SAMPLES / "bricks_height.png").exact_heights(), bilinear_safe=True)
    if name.endswith(".glb"):  # the GLB holds its step map: no copy beside it
        assert report.step_maps == {"bricks_height_csm": out / name} and not step.exists()
        assert sorted(p.name for p in out.iterdir()) == [name, "csm-manifest.json"]
        doc = gc.load(out / name)
        (image,) = [im for im in doc.json["images"] if im.get("name") == "bricks_height_csm"]
        step = tmp_path / "embedded.png"
        step.write_bytes(gc.view_bytes(doc, image["bufferView"]))
    else:
        assert report.step_maps == {"bricks_height_csm": step}
    np.testing.assert_array_equal(read_step_map(step), expected)
    assert errors(validate(out / name)) == []
    doc = gc.load(out / name)
    np.testing.assert_allclose(tangent_of(doc), np.tile([1, 0, 0, 1], (15, 1)), atol=1e-6)
    ext = doc.json["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]
    assert ext["depthScale"] == pytest.approx(0.03)  # 2 m x 1 m over 2 x 1 uv: 1 m per uv unit
    assert ext["tile"] == [True, True] and ext["maxRatio"] == 1.0
    assert report.tangent_meshes == ["wall[0]"]


def test_shared_texture_is_processed_once_and_plain_materials_untouched(src, tmp_path):
    doc = json.loads((src / "brick_wall.gltf").read_text())
    twin = json.loads(json.dumps(doc["materials"][0]))
    twin["name"] = "bricks2"
    plain = {"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}}
    doc["materials"] += [twin, plain]
    prim = doc["meshes"][0]["primitives"][0]
    doc["meshes"].append({"name": "twin", "primitives": [dict(prim, material=1)]})
    doc["meshes"].append({"name": "plain", "primitives": [dict(prim, material=2)]})
    doc["nodes"] += [{"mesh": 1}, {"mesh": 2}]
    doc["scenes"][0]["nodes"] += [1, 2]
    (src / "two.gltf").write_text(json.dumps(doc))
    report = convert(src / "two.gltf", tmp_path / "out")
    assert list(report.step_maps) == ["bricks_height_csm"]
    out = json.loads((tmp_path / "out" / "two.gltf").read_text())
    assert out["materials"][2] == plain
    assert "TANGENT" not in out["meshes"][2]["primitives"][0]["attributes"]
    assert errors(validate(tmp_path / "out" / "two.gltf")) == []


def test_clamped_texture_is_not_tiled(src, tmp_path):
    doc = json.loads((src / "brick_wall.gltf").read_text())
    doc["samplers"].append({"wrapS": 33071, "wrapT": 10497})
    doc["textures"][1]["sampler"] = 1
    (src / "c.gltf").write_text(json.dumps(doc))
    convert(src / "c.gltf", tmp_path / "out")
    got = read_step_map(tmp_path / "out" / "bricks_height_csm.png")
    h = load_heightfield(SAMPLES / "bricks_height.png").exact_heights()
    np.testing.assert_array_equal(got, step_map(h, tile=(False, True), bilinear_safe=True))


def test_clamped_sampler_stays_clamped_and_command_line_heights_follow_the_colour(src, tmp_path):
    """The step map's sampler has the height texture's wrap modes; a height from the command
    line takes the wrap modes (and uv set) of the material's base colour texture."""
    doc = json.loads((src / "brick_wall.gltf").read_text())
    doc["samplers"].append({"wrapS": 33071, "wrapT": 10497})
    doc["textures"][1]["sampler"] = 1
    (src / "c.gltf").write_text(json.dumps(doc))
    convert(src / "c.gltf", tmp_path / "a")
    del doc["materials"][0]["extensions"]
    doc["textures"][0]["sampler"] = 1  # the base colour clamps along S
    (src / "d.gltf").write_text(json.dumps(doc))
    convert(src / "d.gltf", tmp_path / "b", heights={"bricks": src / "bricks_height.png"})
    for out, name in ((tmp_path / "a", "c.gltf"), (tmp_path / "b", "d.gltf")):
        j = json.loads((out / name).read_text())
        ext = j["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]
        sampler = j["samplers"][j["textures"][ext["stepMapTexture"]["index"]]["sampler"]]
        assert (sampler["wrapS"], sampler["wrapT"]) == (33071, 10497) and ext["tile"] == [False, True]


@pytest.mark.parametrize("wrap, tile, want", [
    (10497, False, (33071, 33071)),  # --no-tile on a repeating texture: the step map clamps
    (33071, True, (10497, 10497)),  # --tile on a clamped texture: the step map repeats, as its cones
    (33648, None, (33648, 33648)),  # mirrored: not tiled, and mirrored copies stay safe
    (33648, True, (10497, 10497)),
])
def test_step_map_sampler_follows_its_tiling(src, tmp_path, wrap, tile, want):
    """The step map sampler's wrap modes always agree with the material's `tile` (REPEAT on a
    tiled axis, else the height's clamped or mirrored mode, else CLAMP_TO_EDGE): a generic
    engine that trusts the sampler samples what the cones were made for."""
    doc = json.loads((src / "brick_wall.gltf").read_text())
    doc["samplers"].append({"wrapS": wrap, "wrapT": wrap})
    doc["textures"][1]["sampler"] = len(doc["samplers"]) - 1
    (src / "w.gltf").write_text(json.dumps(doc))
    convert(src / "w.gltf", tmp_path / "out", tile=tile)
    j = json.loads((tmp_path / "out" / "w.gltf").read_text())
    ext = j["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]
    sampler = j["samplers"][j["textures"][ext["stepMapTexture"]["index"]]["sampler"]]
    assert (sampler["wrapS"], sampler["wrapT"]) == want
    assert ext["tile"] == [w == 10497 for w in want]


def test_output_folder_may_not_be_the_inputs(src):
    with pytest.raises(OutputError, match="input's folder"):
        convert(src / "brick_wall.gltf", src)


def test_cli_convert(src, tmp_path):
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(src / "brick_wall.gltf"),
                        "-o", str(tmp_path / "o"), "--json", "--depth", "0.2", "--bits", "16"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (rep,) = json.loads(r.stdout)["results"]
    assert rep["status"] == "converted" and rep["out_dir"] == str(tmp_path / "o")
    assert str(tmp_path / "o" / "bricks_height_csm.png") in rep["written"]
    assert read_step_map(tmp_path / "o" / "bricks_height_csm.png").dtype == np.uint16
    doc = gc.load(tmp_path / "o" / "brick_wall.gltf")
    assert doc.json["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["depthScale"] == 0.2
    bad = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(src / "nope.gltf"), "-o",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=300)
    assert bad.returncode == 3 and "nope.gltf" in bad.stderr


def test_converts_the_obj_wall(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    report = convert(src / "brick_wall.obj", tmp_path / "out")
    assert report.tangent_meshes == []  # OBJ cannot store tangents: none are computed
    expected = step_map(load_heightfield(SAMPLES / "bricks_height.png").exact_heights(), bilinear_safe=True)
    np.testing.assert_array_equal(read_step_map(tmp_path / "out" / "bricks_height_csm.png"), expected)
    mtl = (tmp_path / "out" / "brick_wall.mtl").read_text().splitlines()
    assert "csm_map bricks_height_csm.png" in mtl and "csm_depth 0.03" in mtl


@pytest.mark.parametrize("cones", ["conservative", "quadrant"])
def test_extension_matches_its_documented_schema(src, tmp_path, cones):
    schema = json.loads((Path(__file__).resolve().parents[1] / "docs" /
                         "EXT_materials_cone_step_mapping.schema.json").read_text())
    convert(src / "brick_wall.gltf", tmp_path / "out", cones=cones,
            variant="quadrant" if cones == "quadrant" else "exact")
    ext = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())["materials"][0]["extensions"][
        "EXT_materials_cone_step_mapping"]
    jsonschema.Draft202012Validator.check_schema(schema)
    assert [e.message for e in jsonschema.Draft202012Validator(schema).iter_errors(ext)] == []
    assert set(ext) <= set(schema["properties"]) and ("stepMap2Texture" in ext) == (cones == "quadrant")


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.glb"])
def test_verify_renders_the_converted_scene(src, tmp_path, name):
    """The converted wall drawn as the file has it (MikkTSpace tangents, uvs, depth) matches
    the exact tracer at every view."""
    from csm_assets.verify.scene import verify_scene

    convert(src / name, tmp_path / "out", depth=0.1)
    report = verify_scene(tmp_path / "out" / name, size=48)
    assert report.passed, report.to_dict()
    (prim,) = report.primitives
    assert prim.worst_p95 <= 1.0 and prim.variants[0].variant == "exact"
    r = subprocess.run([sys.executable, "-m", "csm_assets", "verify", str(tmp_path / "out" / name), "--size",
                        "48", "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["primitives"][0]["variants"][0]["variant"] == "exact"


def test_verify_scene_refuses_unconverted(src):
    from csm_assets.errors import FormatError
    from csm_assets.verify.scene import verify_scene

    with pytest.raises(FormatError, match="convert the scene first"):
        verify_scene(src / "brick_wall.gltf")


def test_degenerate_and_non_manifold_meshes_warn_and_still_convert():
    from csm_assets.convert.pipeline import mesh_problems
    from csm_assets.scene import Mesh

    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [0, -1, 0], [0, 0, 1]], float)
    uvs = pos[:, :2].copy()
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4], [0, 1, 5]])  # edge 0-1 four times; 0,1,3 flat
    problems = mesh_problems(Mesh("m", pos, faces, uvs=uvs))
    assert any(c == "CSM205" and "1 triangle(s) without area" in p for c, p in problems)
    assert any(c == "CSM206" and "1 non-manifold edge" in p for c, p in problems)
    assert mesh_problems(Mesh("ok", pos, faces[:1], uvs=uvs)) == []


def test_float_exr_step_maps_on_request(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL + GLTF_WALL)
    report = convert(src / "brick_wall.obj", tmp_path / "obj", bits=32)
    (path,) = report.step_maps.values()
    assert path.suffix == ".exr" and read_step_map(path).dtype == np.float32
    assert f"csm_map {path.name}" in (tmp_path / "obj" / "brick_wall.mtl").read_text()
    with pytest.raises(ValueError, match="glTF images are PNG"):
        convert(src / "brick_wall.gltf", tmp_path / "gltf", bits=32)


def test_exact_step_maps_without_the_safety_pass(src, tmp_path):
    report = convert(src / "brick_wall.gltf", tmp_path / "out", bilinear_safe=False)
    h = load_heightfield(SAMPLES / "bricks_height.png").exact_heights()
    np.testing.assert_array_equal(read_step_map(report.step_maps["bricks_height_csm"]), step_map(h))
    ext = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())["materials"][0]["extensions"][
        "EXT_materials_cone_step_mapping"]
    assert ext["minStep"] == 1.0
    safe = convert(src / "brick_wall.gltf", tmp_path / "safe")
    ext = json.loads((tmp_path / "safe" / "brick_wall.gltf").read_text())["materials"][0]["extensions"][
        "EXT_materials_cone_step_mapping"]
    assert ext["minStep"] == 0.25
    assert read_step_map_meta(safe.step_maps["bricks_height_csm"])["bilinear_safe"] is True
