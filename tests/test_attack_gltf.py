"""Attack suite for glTF input: crafted documents through the real CLI (``convert``).

Each case asserts exit 3, one error line naming the file (and the JSON pointer or item
where there is one), no traceback, inputs untouched and no outputs left.
"""

from __future__ import annotations

import json
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from attack import Attack, assert_clean_error, run_cli

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
FILES = ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"]


def sparse(acc: dict, **over) -> None:
    acc["sparse"] = {"count": 1, "indices": {"bufferView": 3, "componentType": 5123},
                     "values": {"bufferView": 0}}
    acc["sparse"].update(over)


def drop(d: dict, key: str) -> dict:
    d.pop(key)
    return d


# name -> (edit of the JSON document, text the error line must hold)
CASES = {
    "sparse without count": (lambda j: (sparse(j["accessors"][0]), j["accessors"][0]["sparse"].pop("count")),
                             "/accessors/0/sparse/count"),
    "sparse index type unknown": (lambda j: sparse(j["accessors"][0], indices={"bufferView": 3,
                                                                             "componentType": 5126}),
                                  "/accessors/0/sparse/indices/componentType"),
    "component type unknown": (lambda j: j["accessors"][2].update(componentType=5130),
                               "/accessors/2/componentType"),
    "image uri a number": (lambda j: j["images"][1].update(uri=5), "/images/1/uri"),
    "buffer uri a list": (lambda j: j["buffers"][0].update(uri=["brick_wall.bin"]), "/buffers/0/uri"),
    "material name an object": (lambda j: j["materials"][0].update(name={"a": 1}), "/materials/0/name"),
    "mesh name a number": (lambda j: j["meshes"][0].update(name=3), "/meshes/0/name"),
    "material a string": (lambda j: j["materials"].__setitem__(0, "bricks"), "/materials/0"),
    "materials an object": (lambda j: j.update(materials={"0": {}}), "/materials"),
    "factor a list": (lambda j: j["materials"][0]["extensions"]["KHR_materials_displacement"].update(
        displacementGeometryFactor=[0.1]), "displacementGeometryFactor"),
    "metallic factor a list": (lambda j: j["materials"][0]["pbrMetallicRoughness"].update(metallicFactor=[1]),
                               "/materials/0/pbrMetallicRoughness/metallicFactor"),
    "texcoord of another count": (lambda j: j["accessors"][2].update(count=14), "/meshes/0/primitives/0"),
    "texcoord a VEC3": (lambda j: j["accessors"][2].update(type="VEC3", count=10),
                        "/meshes/0/primitives/0/attributes/TEXCOORD_0"),
    "millions of elements, no view": (lambda j: drop(j["accessors"][1], "bufferView").update(count=300_000_000),
                                      "/accessors/1"),
    "odd byteStride": (lambda j: j["bufferViews"][0].update(byteStride=13), "/bufferViews/0/byteStride"),
    "float indices": (lambda j: j["accessors"][3].update(componentType=5126, count=12),
                      "/meshes/0/primitives/0/indices"),
    "texture index -1": (lambda j: j["materials"][0]["extensions"]["KHR_materials_displacement"]
                         ["displacementGeometryTexture"].update(index=-1), "displacementGeometryTexture/index"),
    "texture index out of range": (lambda j: j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
                                   .update(index=7), "baseColorTexture/index"),
    "texcoord a string": (lambda j: j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
                          .update(texCoord="0"), "baseColorTexture/texCoord"),
    "view past its buffer": (lambda j: j["bufferViews"][2].update(byteOffset=10_000), "/bufferViews/2"),
    "attribute accessor missing": (lambda j: j["meshes"][0]["primitives"][0]["attributes"].update(NORMAL=40),
                                   "attributes/NORMAL"),
    "negative count": (lambda j: j["accessors"][0].update(count=-3), "/accessors/0/count"),
    "bool as index": (lambda j: j["meshes"][0]["primitives"][0].update(material=True),
                      "/meshes/0/primitives/0/material"),
    "asset not an object": (lambda j: j.update(asset="2.0"), "glTF 2.0"),
    "sampler wrap unknown": (lambda j: j["samplers"][0].update(wrapS=1), "/samplers/0/wrapS"),
    "transform scale one number": (lambda j: j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
                                   .setdefault("extensions", {}).update(KHR_texture_transform={"scale": 2}),
                                   "KHR_texture_transform/scale"),
    "draco data corrupt": (lambda j: j["meshes"][0]["primitives"][0].setdefault("extensions", {}).update(
        KHR_draco_mesh_compression={"bufferView": 0, "attributes": {"POSITION": 0}}),
        "KHR_draco_mesh_compression"),
    "meshopt mode unknown": (lambda j: j["bufferViews"][0].setdefault("extensions", {}).update(
        EXT_meshopt_compression={"buffer": 0, "byteLength": 10, "byteStride": 12, "count": 15,
                                 "mode": "SPIRAL"}), "EXT_meshopt_compression"),
}


def crafted(tmp_path: Path, edit) -> Path:
    src = tmp_path / "in"
    src.mkdir()
    for name in FILES:
        shutil.copy(SAMPLES / name, src / name)
    doc = json.loads((src / "brick_wall.gltf").read_text())
    edit(doc)
    (src / "bad.gltf").write_text(json.dumps(doc))
    (src / "brick_wall.gltf").unlink()
    return src / "bad.gltf"


def refused(path: Path, tmp_path: Path, names: str, *args, env=None) -> str:
    out = tmp_path / "out"
    with Attack(path.parent):
        r = run_cli("convert", path, "-o", out, *args, env=env)
    line = assert_clean_error(r, 3, path.name)
    assert names in line, line
    assert not out.exists() or [p.name for p in out.iterdir()] == [], "partial outputs"
    return line


@pytest.mark.parametrize("case", list(CASES))
def test_malformed_fields_are_refused_naming_file_and_pointer(tmp_path, case):
    edit, where = CASES[case]
    refused(crafted(tmp_path, edit), tmp_path, where)


@pytest.mark.parametrize("token, where", [("NaN", "displacementGeometryFactor is NaN"),
                                          ("Infinity", "displacementGeometryFactor is Infinity"),
                                          ("1e999", "displacementGeometryFactor is 1e999")])
def test_non_finite_json_numbers(tmp_path, token, where):
    path = crafted(tmp_path, lambda j: None)
    text = path.read_text().replace('"displacementGeometryFactor": 0.03', f'"displacementGeometryFactor": {token}')
    assert token in text
    path.write_text(text)
    refused(path, tmp_path, where)


@pytest.mark.parametrize("offset, what", [(24, "POSITION"), (360 + 8, "TEXCOORD_0"), (180, "NORMAL")])
def test_non_finite_vertex_data(tmp_path, offset, what):
    path = crafted(tmp_path, lambda j: j["buffers"][0].update(uri="bad.bin"))
    data = bytearray((path.parent / "brick_wall.bin").read_bytes())
    struct.pack_into("<f", data, offset, float("nan") if what != "NORMAL" else float("inf"))
    (path.parent / "bad.bin").write_bytes(data)
    refused(path, tmp_path, what)


def test_many_materials_sharing_a_texture_over_the_limit(tmp_path):
    """70 000 materials (over the default 65 536) sharing one height texture: refused
    before any geometry or image is read; a lower limit from the environment refuses 1001."""
    def many(n):
        return lambda j: j.update(materials=[dict(j["materials"][0], name=f"m{i}") for i in range(n)])

    line = refused(crafted(tmp_path, many(70_000)), tmp_path, "70,000 materials")
    assert "CSM_ASSETS_MAX_MATERIALS" in line
    (tmp_path / "low").mkdir()
    import os

    env = dict(os.environ, CSM_ASSETS_MAX_MATERIALS="1000")
    refused(crafted(tmp_path / "low", many(1001)), tmp_path / "low", "1,001 materials", env=env)


def test_json_object_limit_is_checked_before_parsing(tmp_path):
    """A document of more JSON objects than CSM_ASSETS_MAX_JSON_OBJECTS is refused before
    it is parsed (a million materials took 3 GB and 20 s to parse before this)."""
    import os

    env = dict(os.environ, CSM_ASSETS_MAX_JSON_OBJECTS="20")
    line = refused(crafted(tmp_path, lambda j: None), tmp_path, "objects", env=env)
    assert "CSM_ASSETS_MAX_JSON_OBJECTS" in line


def test_vertex_limit_from_the_environment(tmp_path):
    import os

    env = dict(os.environ, CSM_ASSETS_MAX_VERTICES="40")
    refused(crafted(tmp_path, lambda j: None), tmp_path, "/accessors/3 declares 48 elements", env=env)


@pytest.mark.parametrize("module, extension", [("DracoPy", "KHR_draco_mesh_compression"),
                                               ("meshopt", "EXT_meshopt_compression")])
def test_missing_decoder_is_refused_naming_the_extension(tmp_path, module, extension):
    """Without the decoder package a compressed primitive is refused with exit 3 naming
    the extension (never converted from garbage)."""
    import os

    shim = tmp_path / "shim"
    (shim / module).mkdir(parents=True)
    (shim / module / "__init__.py").write_text("raise ImportError('not here')\n")
    if module == "DracoPy":
        edit = CASES["draco data corrupt"][0]
    else:
        def edit(j):
            j["bufferViews"][2]["extensions"] = {extension: {"buffer": 0, "byteLength": 120, "byteStride": 8,
                                                             "count": 15, "mode": "ATTRIBUTES"}}
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shim), os.environ.get("PYTHONPATH", "")]))
    line = refused(crafted(tmp_path, edit), tmp_path, extension, env=env)
    assert f"pip install {module}" in line


def test_truncated_glb(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    data = (SAMPLES / "brick_wall.glb").read_bytes()
    (src / "cut.glb").write_bytes(data[: len(data) // 3])
    refused(src / "cut.glb", tmp_path, "truncated")


def test_outputs_never_hold_non_finite_numbers(tmp_path):
    """A sane file converts; its output JSON parses with NaN and Infinity refused."""
    path = crafted(tmp_path, lambda j: None)
    r = run_cli("convert", path, "-o", tmp_path / "out")
    assert r.returncode == 0, r.stderr

    def refuse(token):
        raise AssertionError(f"output holds {token}")

    doc = json.loads((tmp_path / "out" / "bad.gltf").read_text(), parse_constant=refuse)
    assert np.isfinite(doc["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["depthScale"])
