"""Malformed items a reader leaves out of a mesh are counted, per mesh, in a coded warning that
names the file and the mesh (issue 34): faces of fewer than three vertices (CSM207: an OBJ face
of one or two corners, a USD faceVertexCount of 0, 1 or 2) and triangles without area (CSM205),
in all three readers (glTF, OBJ, USD), whether tangents are made for the mesh or not."""

from __future__ import annotations

import json

import numpy as np
from pxr import UsdGeom

from attack import Attack, assert_clean_run, run_cli
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from csm_assets.formats import gltf_container as gc
from usd_stages import edit, wall_folder


def _notices(r) -> list[dict]:
    assert_clean_run(r)
    return json.loads(r.stdout)["results"][0]["warnings"]


def _one(notices, code) -> dict:
    (n,) = [n for n in notices if n["code"] == code]
    return n


def test_obj_short_faces_and_flat_triangles_are_counted_per_mesh(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    obj = src / "brick_wall.obj"
    n = len(obj.read_text().splitlines())
    # a face of one corner, one of two, and two triangles without area (a repeated corner, a line)
    obj.write_text(obj.read_text() + "f 1/1/1\nf 1/1/1 2/2/1\nf 1/1/1 1/1/1 2/2/1\nf 1/1/1 2/2/1 3/3/1\n")
    with Attack(src):
        notices = _notices(run_cli("convert", obj, "-o", tmp_path / "out", "--json"))
    short = _one(notices, "CSM207")
    assert short["about"] == ["mesh bricks"] and short["message"].startswith(f"{obj}: mesh bricks: "), short
    assert f"2 face(s) with fewer than three vertices skipped (first on line {n + 1})" in short["message"]
    flat = _one(notices, "CSM205")
    assert flat["about"] == ["mesh bricks (material 'bricks')"] and "2 triangle(s) without area" in flat["message"]


def test_usd_face_counts_of_zero_to_two_and_flat_triangles_are_counted(tmp_path):
    src = wall_folder(tmp_path)

    def change(stage):
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/wall"))
        counts = list(mesh.GetFaceVertexCountsAttr().Get()) + [0, 1, 2, 3]
        indices = list(mesh.GetFaceVertexIndicesAttr().Get()) + [0, 0, 1, 0, 1, 2]  # the last: a line
        mesh.GetFaceVertexCountsAttr().Set(counts)
        mesh.GetFaceVertexIndicesAttr().Set(indices)
        normals = list(mesh.GetNormalsAttr().Get()) + [(0, 0, 1)] * 6  # faceVarying: one per face-vertex
        mesh.GetNormalsAttr().Set(normals)

    scene = edit(src / "brick_wall.usda", change)
    with Attack(src):
        notices = _notices(run_cli("convert", scene, "-o", tmp_path / "out", "--json"))
    short = _one(notices, "CSM207")
    assert short["about"] == ["mesh /World/wall"], short
    assert "3 face(s) with fewer than three vertices skipped (1 with none)" in short["message"]
    assert "brick_wall.usda" in short["message"]
    flat = _one(notices, "CSM205")
    assert "mesh /World/wall" in flat["about"][0] and "1 triangle(s) without area" in flat["message"]


def test_gltf_flat_triangles_are_counted_even_where_the_file_brings_its_tangents(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    doc = gc.load(src / "brick_wall.gltf")
    prim = doc.json["meshes"][0]["primitives"][0]
    faces = gc.read_accessor(doc, prim["indices"])[:, 0].astype(np.uint16)
    prim["indices"] = gc.add_accessor(doc, np.concatenate([faces, [0, 0, 1, 0, 1, 2]]).astype(np.uint16),
                                      target=gc.ELEMENT_ARRAY_BUFFER)
    count = doc.json["accessors"][prim["attributes"]["POSITION"]]["count"]
    prim["attributes"]["TANGENT"] = gc.add_accessor(doc, np.tile(np.float32([1, 0, 0, 1]), (count, 1)))
    doc.json["buffers"][-1]["uri"] = "flat.bin"
    (src / "flat.bin").write_bytes(bytes(doc.buffers[-1]))
    (src / "flat.gltf").write_text(json.dumps(doc.json))
    with Attack(src):
        notices = _notices(run_cli("convert", src / "flat.gltf", "-o", tmp_path / "out", "--json"))
    flat = _one(notices, "CSM205")
    assert flat["about"] == ["mesh wall[0] (material 'bricks')"], flat
    assert "2 triangle(s) without area" in flat["message"] and "flat.gltf" in flat["message"]
