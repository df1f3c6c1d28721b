"""glTF/GLB scenes: finding heights, writing tangents and the CSM material, keeping the rest."""

from __future__ import annotations

import json
import shutil
import struct
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from csm_assets import FormatError
from csm_assets.formats import gltf, gltf_container as gc
from csm_assets.scene import CsmSettings
from csm_assets.stepmap import StepMapSettings
from khronos import errors, validate

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


@pytest.fixture
def wall(tmp_path):
    """A copy of the sample wall (.gltf, .bin, images) with extras and an animation added."""
    for name in ["brick_wall.gltf", "brick_wall.bin", "brick_wall.glb", "bricks_color.png",
                 "bricks_height.png"]:
        shutil.copy(SAMPLES / name, tmp_path / name)
    doc = json.loads((tmp_path / "brick_wall.gltf").read_text())
    doc["asset"]["extras"] = {"pipeline": "kept"}
    doc["nodes"][0]["extras"] = {"tag": 7}
    doc["materials"][0]["extras"] = {"artist": "kept"}
    (tmp_path / "brick_wall.gltf").write_text(json.dumps(doc))
    return tmp_path


def face_tangents(mesh) -> np.ndarray:
    """Per-corner tangents from each triangle's uv derivatives (w = +1): enough for flat walls."""
    p = mesh.positions[mesh.faces]
    t = mesh.uvs[mesh.faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    tan = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * np.sign(det)[:, None]  # dp/du
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    out = np.ones((len(p), 3, 4))
    out[..., :3] = tan[:, None, :]
    return np.round(out, 6) + 0.0  # equal frames must be bitwise equal to share a vertex


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.glb"])
def test_reads_height_from_displacement_extension(wall, name):
    scene = gltf.read(wall / name)
    assert scene.format == name.split(".")[1]
    (mat,) = scene.materials
    assert mat.height.origin == "KHR_materials_displacement"
    assert mat.height.scale == pytest.approx(0.03) and mat.height.channel == 0
    data = mat.height.texture.read_bytes()
    assert data == (wall / "bricks_height.png").read_bytes()
    (mesh,) = scene.meshes
    assert mesh.positions.shape == (15, 3) and mesh.faces.shape == (16, 3) and mesh.uvs.shape == (15, 2)


def test_materials_without_height_load_no_geometry(wall):
    doc = json.loads((wall / "brick_wall.gltf").read_text())
    del doc["materials"][0]["extensions"]
    (wall / "plain.gltf").write_text(json.dumps(doc))
    scene = gltf.read(wall / "plain.gltf")
    assert scene.materials[0].height is None and scene.meshes == []


def test_parallax_extension_extras_and_override(wall):
    doc = json.loads((wall / "brick_wall.gltf").read_text())
    doc["materials"][0]["extensions"] = {"KHR_materials_parallax_mapping": {"heightTexture": 1,
                                                                            "heightFactor": 0.5}}
    (wall / "p.gltf").write_text(json.dumps(doc))
    h = gltf.read(wall / "p.gltf").materials[0].height
    assert (h.origin, h.scale, h.texture.path.name) == ("KHR_materials_parallax_mapping", 0.5,
                                                        "bricks_height.png")
    doc["materials"][0]["extensions"] = {}
    doc["materials"][0]["extras"] = {"csm_height": {"index": 0, "invert": True, "channel": 1}}
    (wall / "e.gltf").write_text(json.dumps(doc))
    h = gltf.read(wall / "e.gltf").materials[0].height
    assert (h.origin, h.invert, h.channel, h.texture.path.name) == ("extras.csm_height", True, 1,
                                                                    "bricks_color.png")
    h = gltf.read(wall / "e.gltf", heights={"bricks": wall / "bricks_height.png"}).materials[0].height
    assert h.origin == "command line" and h.texture.path == wall / "bricks_height.png"


@pytest.mark.parametrize("uri", ["../../etc/passwd", "/etc/passwd", "%2E%2E/x.png", "file:///etc/passwd"])
def test_uris_escaping_the_scene_are_refused(wall, uri):
    for key in ("images", "buffers"):
        doc = json.loads((wall / "brick_wall.gltf").read_text())
        doc[key][0]["uri"] = uri
        (wall / "esc.gltf").write_text(json.dumps(doc))
        with pytest.raises(FormatError, match="refused"):
            gltf.read(wall / "esc.gltf")


def test_missing_texture_warns_and_names_material(wall):
    (wall / "bricks_height.png").unlink()
    scene = gltf.read(wall / "brick_wall.gltf")
    assert scene.materials[0].height is None
    assert any("'bricks'" in w and "bricks_height.png" in w for w in map(str, scene.warnings))


def convert_by_hand(scene, out, tile=(True, True)):
    """What convert() does, with test tangents: a step map file and the CSM settings."""
    step = out / "bricks_height_csm.png"
    shutil.copy(SAMPLES / "bricks_height.png", step)  # any PNG stands in for the step map here
    scene.materials[0].csm = CsmSettings(step, 0.05, StepMapSettings(tile=tile, levels="none"), steps=0)  # a stand-in
    for mesh in scene.meshes:
        mesh.corner_tangents = face_tangents(mesh)
    return gltf.write(scene, out)


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.glb"])
def test_written_scene_is_valid_and_keeps_the_rest(wall, tmp_path_factory, name):
    out = tmp_path_factory.mktemp("out")
    written = convert_by_hand(gltf.read(wall / name), out)
    assert written[0] == out / name
    report = validate(out / name)
    assert errors(report) == []
    g = pygltflib.GLTF2().load(str(out / name))  # an independent reader
    prim = g.meshes[0].primitives[0]
    assert prim.attributes.TANGENT is not None
    ext = g.materials[0].extensions[gltf.EXTENSION]
    assert ext["depthScale"] == 0.05 and ext["maxRatio"] == 1.0 and ext["tile"] == [True, True]
    assert "KHR_materials_displacement" in g.materials[0].extensions  # kept for other tools
    assert gltf.EXTENSION in g.extensionsUsed and gltf.EXTENSION not in (g.extensionsRequired or [])
    doc = gc.load(out / name)
    tan = gc.read_accessor(doc, doc.json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"])
    np.testing.assert_allclose(tan, np.tile([1, 0, 0, 1], (15, 1)), atol=1e-6)
    if name.endswith(".gltf"):
        assert doc.json["asset"]["extras"] == {"pipeline": "kept"}
        assert doc.json["nodes"][0]["extras"] == {"tag": 7}
        assert doc.json["materials"][0]["extras"] == {"artist": "kept"}
        assert sorted(p.name for p in out.iterdir()) == [
            "brick_wall.bin", "brick_wall.gltf", "brick_wall_csm.bin", "bricks_color.png",
            "bricks_height.png", "bricks_height_csm.png"]
    step_tex = doc.json["textures"][ext["stepMapTexture"]["index"]]
    assert doc.json["samplers"][step_tex["sampler"]]["minFilter"] == gltf.LINEAR


def test_conflicting_corner_tangents_split_vertices(wall, tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    scene = gltf.read(wall / "brick_wall.gltf")
    mesh = scene.meshes[0]
    tangents = face_tangents(mesh)
    tangents[:8, :, 3] = -1.0  # the left half mirrored: shared vertices need two tangents
    step = out / "bricks_height_csm.png"
    shutil.copy(SAMPLES / "bricks_height.png", step)
    scene.materials[0].csm = CsmSettings(step, 0.05, StepMapSettings(levels="none"))  # a stand-in: no levels
    mesh.corner_tangents = tangents
    gltf.write(scene, out)
    assert errors(validate(out / "brick_wall.gltf")) == []
    doc = gc.load(out / "brick_wall.gltf")
    prim = doc.json["meshes"][0]["primitives"][0]
    pos = gc.read_accessor(doc, prim["attributes"]["POSITION"])
    tan = gc.read_accessor(doc, prim["attributes"]["TANGENT"])
    idx = gc.read_accessor(doc, prim["indices"])[:, 0].reshape(-1, 3)
    assert len(pos) > 15  # split
    np.testing.assert_allclose(pos[idx], mesh.positions[mesh.faces], atol=1e-7)  # same triangles
    np.testing.assert_array_equal(tan[idx][..., 3], tangents[..., 3])


def glb_with(tmp_path, mutate) -> Path:
    data = bytearray((SAMPLES / "brick_wall.glb").read_bytes())
    mutate(data)
    (tmp_path / "bad.glb").write_bytes(bytes(data))
    return tmp_path / "bad.glb"


def _set_json(data: bytearray, edit):
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    edit(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + length:]
    data[:] = struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(rest)) + struct.pack(
        "<II", len(text), gc.JSON_CHUNK) + text + rest


@pytest.mark.parametrize("mutate, why", [
    (lambda d: d.__delitem__(slice(len(d) // 2, None)), "truncated GLB"),
    (lambda d: d.__setitem__(slice(20, 24), b"{{{{"), "not valid glTF JSON"),
    (lambda d: _set_json(d, lambda j: j["accessors"][0].update(count=10 ** 9)), "/accessors/0 declares"),
    (lambda d: _set_json(d, lambda j: j["buffers"][0].update(byteLength=10 ** 12)), "declares"),
    (lambda d: _set_json(d, lambda j: j["asset"].update(version="1.0")), "glTF 2.0"),
    (lambda d: _set_json(d, lambda j: j["bufferViews"][3].update(byteOffset=10 ** 8)), "/bufferViews/3: ends at"),
])
def test_malformed_files_raise_format_errors(tmp_path, mutate, why):
    with pytest.raises(FormatError, match=why) as e:
        gltf.read(glb_with(tmp_path, mutate))
    assert "bad.glb" in str(e.value)


def test_sparse_and_normalized_accessors(tmp_path):
    doc = gc.Document(tmp_path / "x.gltf", {"asset": {"version": "2.0"}}, [], False)
    base = gc.add_accessor(doc, np.array([[0, 0], [255, 128], [10, 20]], np.uint8), normalized=True)
    np.testing.assert_allclose(gc.read_accessor(doc, base), [[0, 0], [1, 128 / 255], [10 / 255, 20 / 255]])
    assert gc.read_accessor(doc, base, raw=True).dtype == np.uint8
    idx = gc.add_view(doc, np.array([2], np.uint16).tobytes())
    val = gc.add_view(doc, np.array([[5.0, 6.0]], np.float32).tobytes())
    doc.json["accessors"].append({"componentType": 5126, "count": 3, "type": "VEC2", "sparse": {
        "count": 1, "indices": {"bufferView": idx, "componentType": 5123},
        "values": {"bufferView": val}}})
    np.testing.assert_array_equal(gc.read_accessor(doc, 1), [[0, 0], [0, 0], [5, 6]])
