"""Outputs hold only what the scene needs (issue 23): accessors, buffer views and bytes a
conversion replaces (old TANGENTs; what a split primitive no longer reads) are not left
behind, and step maps sampled alike share one sampler. The Khronos validator's
UNUSED_OBJECT list of an output is the input's, no longer."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from attack import assert_clean_run, run_cli
from conftest import GLTF_WALL, SAMPLES, copy_samples
from csm_assets.formats import gltf, gltf_container as gc
from csm_assets.formats.csm_params import GLTF_TEXTURES
from csm_assets.formats.gltf_prune import prune
from csm_assets.scene import CsmSettings
from csm_assets.stepmap import StepMapSettings
from khronos import errors, validate

EXT = "EXT_materials_cone_step_mapping"


def unused(path) -> list[str]:
    """The validator's UNUSED_OBJECT pointers, less the step map textures (and their levels'): the
    validator does not know EXT_materials_cone_step_mapping, so a texture only it uses counts as unused."""
    report = validate(path)
    assert errors(report) == [], errors(report)
    doc = json.loads(Path(path).read_text())
    ours = {f"/textures/{ext[key]['index']}" for m in doc.get("materials", [])
            for ext in [m.get("extensions", {}).get(EXT, {})] for key in GLTF_TEXTURES if key in ext}
    return sorted(m.get("pointer", "") for m in report["issues"]["messages"] if m["code"] == "UNUSED_OBJECT"
                  and m.get("pointer") not in ours)


def with_tangents(src, name="tangent_wall.gltf"):
    """The sample wall with TANGENTs of its own (a second buffer file, as exporters write them)."""
    doc = gc.load(src / "brick_wall.gltf")
    prim = doc.json["meshes"][0]["primitives"][0]
    count = doc.json["accessors"][prim["attributes"]["POSITION"]]["count"]
    prim["attributes"]["TANGENT"] = gc.add_accessor(doc, np.tile(np.float32([1, 0, 0, 1]), (count * 40, 1))[:count])
    doc.json["buffers"][-1]["uri"] = "tangents.bin"
    (src / "tangents.bin").write_bytes(bytes(doc.buffers[-1]))
    (src / name).write_text(json.dumps(doc.json))
    return src / name


def test_replaced_tangents_leave_nothing_behind(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    scene_in = with_tangents(src)
    before = unused(scene_in)
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", scene_in, "-o", out, "--regenerate-tangents"))
    assert unused(out / scene_in.name) == before
    doc = json.loads((out / scene_in.name).read_text())
    tangent_views = [a["bufferView"] for a in doc["accessors"]]
    assert len(doc["accessors"]) == len(json.loads(scene_in.read_text())["accessors"])  # replaced, not added
    assert len(set(tangent_views)) == len(tangent_views) == len(doc["bufferViews"])
    total_in = sum(b["byteLength"] for b in json.loads(scene_in.read_text())["buffers"])
    total_out = sum(b["byteLength"] for b in doc["buffers"])
    assert total_out <= total_in + 16  # the old tangents' bytes went with them


def test_a_split_primitive_keeps_no_old_attributes(tmp_path):
    from test_gltf import face_tangents

    src = copy_samples(tmp_path / "in", GLTF_WALL)
    before = unused(src / "brick_wall.gltf")
    scene = gltf.read(src / "brick_wall.gltf")
    mesh = scene.meshes[0]
    tangents = face_tangents(mesh)
    tangents[:8, :, 3] = -1.0  # mirrored: shared vertices split, every attribute gathered anew
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(SAMPLES / "bricks_height.png", out / "bricks_height_csm.png")
    scene.materials[0].csm = CsmSettings(out / "bricks_height_csm.png", 0.05, StepMapSettings(levels="none"))  # a stand-in
    mesh.corner_tangents = tangents
    gltf.write(scene, out)
    assert unused(out / "brick_wall.gltf") == before
    doc = gc.load(out / "brick_wall.gltf")
    assert len(doc.json["accessors"]) == len(json.loads((src / "brick_wall.gltf").read_text())["accessors"]) + 1


def test_step_maps_sampled_alike_share_one_sampler(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    doc = json.loads((src / "brick_wall.gltf").read_text())
    twin = json.loads(json.dumps(doc["materials"][0]))
    twin["name"] = "other"
    doc["materials"].append(twin)
    shutil.copy(SAMPLES / "cobbles.png", src / "cobbles.png")
    doc["images"].append({"uri": "cobbles.png"})
    doc["textures"].append({"source": len(doc["images"]) - 1, "sampler": 0})
    prim = doc["meshes"][0]["primitives"][0]
    doc["meshes"].append({"name": "other", "primitives": [dict(prim, material=1)]})
    doc["nodes"].append({"mesh": 1})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    (src / "two.gltf").write_text(json.dumps(doc))
    out = tmp_path / "out"
    r = run_cli("convert", src / "two.gltf", "-o", out, "--height", f"other={src / 'cobbles.png'}")
    assert_clean_run(r)
    got = json.loads((out / "two.gltf").read_text())
    exts = [m["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"]["index"] for m in got["materials"]]
    assert len(set(exts)) == 2  # two step maps
    samplers = [got["textures"][i]["sampler"] for i in exts]
    assert samplers[0] == samplers[1] and len(got["samplers"]) == len(doc["samplers"]) + 1
    assert unused(out / "two.gltf") == unused(src / "two.gltf")


def test_prune_leaves_what_others_still_use():
    doc = gc.Document(path=SAMPLES / "x.gltf", json={"asset": {"version": "2.0"}, "meshes": [
        {"primitives": [{"attributes": {"POSITION": 0}}]}]}, binary=True)
    a = gc.add_accessor(doc, np.zeros((4, 3), np.float32))
    b = gc.add_accessor(doc, np.ones((40, 4), np.float32))
    c = gc.add_accessor(doc, np.full((4, 2), 2, np.float32))
    doc.json["meshes"][0]["primitives"][0]["attributes"].update(POSITION=a, TEXCOORD_0=c)
    prune(doc, {a, b})  # a is still read: only b goes
    assert len(doc.json["accessors"]) == 2 and doc.json["meshes"][0]["primitives"][0]["attributes"] == {
        "POSITION": 0, "TEXCOORD_0": 1}
    assert len(doc.buffers[0]) == 48 + 32 and doc.json["buffers"][0]["byteLength"] == 80
    np.testing.assert_array_equal(gc.read_accessor(doc, 1), np.full((4, 2), 2, np.float32))


def test_a_poly_haven_style_gltf_gains_no_unused_object_but_its_step_map_texture(tmp_path):
    """As Poly Haven ships a glTF: diffuse, OpenGL normal and ARM (occlusion, roughness, metal)
    textures in textures/, the displacement map beside them that no glTF slot holds (named with
    --height). The validator's UNUSED_OBJECT list of the output is the input's (none) plus the
    step map texture, which only EXT_materials_cone_step_mapping names and the validator does not
    read, and its levels image's texture (the default level chain): no image, texture or sampler is orphaned."""
    src = tmp_path / "rock_wall_1k"
    (src / "textures").mkdir(parents=True)
    for name, sample in (("diff", "bricks_color.png"), ("nor_gl", "bricks_normal.png"), ("arm", "bricks_height.png"),
                         ("disp", "bricks_height.png")):
        shutil.copy(SAMPLES / sample, src / "textures" / f"rock_wall_{name}_1k.png")
    shutil.copy(SAMPLES / "brick_wall.bin", src / "brick_wall.bin")
    doc = json.loads((SAMPLES / "brick_wall.gltf").read_text())
    doc.pop("extensionsUsed")
    doc["images"] = [{"uri": f"textures/rock_wall_{n}_1k.png", "name": f"rock_wall_{n}"} for n in ("diff", "nor_gl", "arm")]
    doc["textures"] = [{"sampler": 0, "source": i} for i in range(3)]
    doc["materials"] = [{"name": "rock_wall", "normalTexture": {"index": 1}, "occlusionTexture": {"index": 2},
                         "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                  "metallicRoughnessTexture": {"index": 2}}}]
    scene_in = src / "rock_wall_1k.gltf"
    scene_in.write_text(json.dumps(doc))
    out = tmp_path / "out"
    r = run_cli("convert", scene_in, "-o", out, "--height", f"rock_wall={src / 'textures' / 'rock_wall_disp_1k.png'}")
    assert_clean_run(r)
    assert unused(scene_in) == unused(out / scene_in.name) == []
    raw = {m.get("pointer") for m in validate(out / scene_in.name)["issues"]["messages"] if m["code"] == "UNUSED_OBJECT"}
    got = json.loads((out / scene_in.name).read_text())
    ext = got["materials"][0]["extensions"][EXT]
    assert raw == {f"/textures/{ext[key]['index']}" for key in ("stepMapTexture", "stepMapLevelsTexture")}
    assert len(got["images"]) == len(got["textures"]) == 5 and len(got["samplers"]) <= 2
