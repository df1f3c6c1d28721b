"""Compressed input written back compressed (issue 35), on inputs the real tools make at test time
(tests/gltf_tools.py): gltf-pipeline ``-d`` Draco GLBs (extension required, and with
``--draco.uncompressedFallback``: used only, plain views beside the Draco data), gltfpack ``-cc``
(meshopt) and gltfpack's quantized output at 8- and 16-bit normals. Each output keeps the
input's compression, passes the Khronos validator and verify, reads back through our own decoder
with the input's geometry, and stays within a stated size of the input (the figures are printed,
``pytest -s``; docs/measurements/compressed-inputs.md)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from attack import assert_clean_run, run_cli
from csm_assets.formats import gltf_container as gc
from csm_assets.formats.csm_params import GLTF_TEXTURES
from csm_assets.formats.gltf_compress import grid_bits, octahedral_bits
from csm_assets.formats.gltf_decode import DRACO, decode_all
from gltf_tools import draco, gltfpack, run
from khronos import errors, validate
from test_gltf_compressed import SAMPLES, uv_sphere

MESHOPT = "EXT_meshopt_compression"
CSM = "EXT_materials_cone_step_mapping"
STEP_MAP_SLACK = 40_000  # bytes: the step map PNG a GLB embeds (32 KB for the sample's 256 x 256 heights)


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> dict:
    src = tmp_path_factory.mktemp("src")
    for name in ["bricks_color.png", "bricks_height.png"]:
        shutil.copy(SAMPLES / name, src / name)
    sphere = uv_sphere(src / "sphere.gltf")
    run("gltf-pipeline", "-d", "--draco.uncompressedFallback", "--keepUnusedElements", "-i", sphere,
        "-o", src / "sphere_fallback.glb")
    return {"draco": draco(sphere, src / "sphere_draco.glb"), "fallback": src / "sphere_fallback.glb",
            "meshopt": gltfpack(sphere, src / "sphere_mo.glb", "-cc"),
            "quantized": gltfpack(sphere, src / "sphere_q.gltf"),
            "quantized16": gltfpack(sphere, src / "sphere_q16.gltf", "-vn", "16"),
            "mirrored": gltfpack(uv_sphere(src / "mirrored.gltf", mirror=True), src / "mirrored_mo.glb", "-cc")}


def convert(src: Path, out: Path, *args) -> list[str]:
    """Convert through the CLI (heights named: gltfpack drops the displacement texture); the
    warning lines. The output passes the validator and verify."""
    heights = ("--height", f"bricks={src.parent / 'bricks_height.png'}")
    warnings = assert_clean_run(run_cli("convert", src, "-o", out, *heights, *args))
    assert errors(validate(out / src.name)) == [], src.name
    r = run_cli("verify", out / src.name)
    assert r.returncode in (0, 5) and ("PASS" in r.stdout or r.returncode == 5), r.stdout + r.stderr
    return warnings


def unused(path: Path) -> list[str]:
    """The validator's UNUSED_OBJECT pointers less the step map textures and their levels' (only our
    extension uses them), a Draco primitive's view named as such (the validator reads no Draco): an output's
    list must be its input's (tests/test_outputs_lean.py)."""
    doc = gc.load(path).json
    prims = [p for m in doc.get("meshes", []) for p in m["primitives"]]
    draco_views = {f"/bufferViews/{p['extensions'][DRACO]['bufferView']}" for p in prims
                   if DRACO in p.get("extensions", {})}
    ours = {f"/textures/{ext[key]['index']}" for m in doc.get("materials", [])
            for ext in [m.get("extensions", {}).get(CSM, {})] for key in GLTF_TEXTURES if key in ext}
    pointers = [m.get("pointer", "") for m in validate(path)["issues"]["messages"] if m["code"] == "UNUSED_OBJECT"]
    return sorted("a Draco view" if p in draco_views else p for p in pointers if p not in ours)


def scene_bytes(path: Path) -> int:
    """A scene's size: its file and the buffer files it names."""
    doc = gc.load(path)
    return path.stat().st_size + sum(f.stat().st_size for f in doc.files)


def arrays(doc: gc.Document) -> dict:
    prim = doc.json["meshes"][0]["primitives"][0]
    out = {k: gc.read_accessor(doc, a) for k, a in prim["attributes"].items()}
    out["faces"] = gc.read_accessor(doc, prim["indices"])[:, 0].reshape(-1, 3)
    return out


def matched(doc: gc.Document, reference: gc.Document, key: str) -> float:
    """The largest difference of attribute ``key`` between each vertex of ``doc`` and the
    reference's vertex at the same position and uvs (Draco may order vertices anew)."""
    from scipy.spatial import cKDTree

    a, b = arrays(doc), arrays(reference)
    where = lambda x: np.column_stack([x["POSITION"], x["TEXCOORD_1"]])  # noqa: E731
    _, near = cKDTree(where(b)).query(where(a))
    return float(np.abs(a[key] - b[key][near]).max())


def test_quantization_bits_are_read_off_the_decoded_grid():
    """DracoPy's own encodings at known bits give those bits back; floats off any grid give None.
    (Every point is in a face: Draco drops the others, and with them maybe the grid's extent.)"""
    import DracoPy

    rng = np.random.default_rng(3)
    normals = rng.normal(size=(501, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    faces = rng.permutation(501).reshape(-1, 3).astype(np.uint32)
    for pos_bits, normal_bits, uv_bits in [(11, 8, 10), (14, 10, 12), (16, 12, 14)]:
        mesh = DracoPy.decode(DracoPy.encode(normals * 3.7 + 1, faces, quantization_bits=pos_bits, normals=normals,
                                             normal_quantization_bits=normal_bits, tex_coord=rng.random((501, 2)),
                                             tex_coord_quantization_bits=uv_bits))
        assert (grid_bits(mesh.points), octahedral_bits(mesh.normals), grid_bits(mesh.tex_coord)) == \
            (pos_bits, normal_bits, uv_bits)
    assert grid_bits(rng.random((501, 3)).astype(np.float32)) is None
    assert octahedral_bits(normals.astype(np.float32)) is None


def test_draco_stays_draco(made, tmp_path):
    src = made["draco"]
    convert(src, tmp_path / "o")
    out = tmp_path / "o" / src.name
    raw, before = gc.load(out).json, gc.load(src).json
    prim = raw["meshes"][0]["primitives"][0]
    assert set(prim["extensions"][DRACO]["attributes"]) == {"POSITION", "NORMAL", "TEXCOORD_0", "TEXCOORD_1", "TANGENT"}
    for key in ("extensionsUsed", "extensionsRequired"):
        assert (DRACO in raw.get(key, [])) == (DRACO in before.get(key, [])), key
    assert all("bufferView" not in raw["accessors"][a] for a in prim["attributes"].values())  # no fallback: required
    assert unused(out) == unused(src)
    # the input's quantization (gltf-pipeline's 11-bit positions, 8-bit normals) is kept: the same values
    decoded, reference = decode_all(gc.load(out)), decode_all(gc.load(src))
    assert matched(decoded, reference, "POSITION") < 1e-6 and matched(decoded, reference, "NORMAL") < 1e-6
    size_in, size_out = scene_bytes(src), scene_bytes(out)
    print(f"Draco GLB: {size_in} -> {size_out} bytes ({size_out / size_in:.2f}x, step map included)")
    # the sphere's mesh is 5 KB of Draco in; out, DracoPy stores TANGENT and the second uv set as
    # lossless floats (24 bytes a vertex): 35 KB, where the plain mesh with tangents takes 82 KB
    assert size_out - STEP_MAP_SLACK < 2.5 * size_in


def test_draco_with_an_uncompressed_fallback_keeps_one(made, tmp_path):
    src = made["fallback"]
    convert(src, tmp_path / "o")
    out = tmp_path / "o" / src.name
    raw = gc.load(out).json
    assert DRACO in raw["extensionsUsed"] and DRACO not in raw.get("extensionsRequired", [])
    prim = raw["meshes"][0]["primitives"][0]
    assert DRACO in prim["extensions"]
    assert all("bufferView" in raw["accessors"][a] for a in [*prim["attributes"].values(), prim["indices"]])
    assert unused(out) == unused(src)
    plain, decoded = arrays(gc.load(out)), arrays(decode_all(gc.load(out)))  # the fallback is the Draco data
    for key in plain:
        np.testing.assert_array_equal(plain[key], decoded[key])


def test_meshopt_stays_meshopt(made, tmp_path):
    src = made["meshopt"]
    convert(src, tmp_path / "o")
    out = tmp_path / "o" / src.name
    raw_doc, in_doc = gc.load(out), gc.load(src)

    def payloads(doc):
        return {bytes(doc.buffers[e["buffer"]][e["byteOffset"]:e["byteOffset"] + e["byteLength"]])
                for v in doc.json["bufferViews"] if (e := v.get("extensions", {}).get(MESHOPT))}

    assert payloads(in_doc) < payloads(raw_doc)  # the input's compressed bytes, as they were, and the tangents'
    assert unused(out) == unused(src)
    prim = raw_doc.json["meshes"][0]["primitives"][0]
    tangent_view = raw_doc.json["bufferViews"][raw_doc.json["accessors"][prim["attributes"]["TANGENT"]]["bufferView"]]
    assert MESHOPT in tangent_view["extensions"]
    assert gc.is_fallback(raw_doc.json["buffers"][tangent_view["buffer"]])  # no uncompressed copy, as in the input
    decoded, reference = arrays(decode_all(gc.load(out))), arrays(decode_all(gc.load(src)))
    for key in ("POSITION", "NORMAL", "TEXCOORD_0", "faces"):
        np.testing.assert_array_equal(decoded[key], reference[key])
    assert decoded["TANGENT"].shape == (len(reference["POSITION"]), 4)
    size_in, size_out = scene_bytes(src), scene_bytes(out)
    print(f"meshopt GLB: {size_in} -> {size_out} bytes ({size_out / size_in:.2f}x, step map included)")
    assert size_out - STEP_MAP_SLACK < 1.2 * size_in


@pytest.mark.parametrize("kind, dtype", [("quantized", np.int8), ("quantized16", np.int16)])
def test_quantized_input_gets_quantized_tangents(made, tmp_path, kind, dtype):
    src = made[kind]
    convert(src, tmp_path / "o")
    out = tmp_path / "o" / src.name
    doc = gc.load(out)
    prim = doc.json["meshes"][0]["primitives"][0]
    tangent, normal = (doc.json["accessors"][prim["attributes"][k]] for k in ("TANGENT", "NORMAL"))
    assert tangent["componentType"] == normal["componentType"] == gc.COMPONENT_CODES[np.dtype(dtype)]
    assert tangent["normalized"] and "KHR_mesh_quantization" in doc.json["extensionsRequired"]
    t = gc.read_accessor(doc, prim["attributes"]["TANGENT"])
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1, atol=2 / np.iinfo(dtype).max)
    assert set(np.unique(t[:, 3])) <= {-1.0, 1.0}
    added = scene_bytes(out) - scene_bytes(src)
    size = 4 * np.dtype(dtype).itemsize
    print(f"{kind}: {scene_bytes(src)} -> {scene_bytes(out)} bytes (tangents {tangent['count']} x {size} B)")
    assert added < tangent["count"] * 4 * np.dtype(dtype).itemsize + 4096  # the tangents, and a few KB of JSON


def test_what_cannot_be_encoded_again_is_a_warned_choice(made, tmp_path):
    """Draco with int8 normals (KHR_mesh_quantization beside it): DracoPy takes no int8 attribute,
    so the primitive is written plain, with CSM211 naming the sizes; --ignore CSM211 accepts it."""
    doc = gc.load(made["draco"])
    prim = doc.json["meshes"][0]["primitives"][0]
    doc.json["accessors"][prim["attributes"]["NORMAL"]].update(componentType=5120, normalized=True)
    doc.json.pop("extensionsRequired", None)
    doc.json["extensionsRequired"] = [DRACO, "KHR_mesh_quantization"]
    doc.json["extensionsUsed"].append("KHR_mesh_quantization")
    src = made["draco"].parent / "sphere_int8.glb"
    src.write_bytes(gc.glb_bytes(doc))
    warnings = convert(src, tmp_path / "o")
    [line] = [w for w in warnings if "CSM211" in w]
    assert "NORMAL is int8" in line and "MB in" in line and "MB out" in line, line
    raw = gc.load(tmp_path / "o" / src.name).json
    assert DRACO not in raw["meshes"][0]["primitives"][0].get("extensions", {})
    assert DRACO not in raw.get("extensionsUsed", []) + raw.get("extensionsRequired", [])
    assert not [w for w in convert(src, tmp_path / "o2", "--ignore", "CSM211") if "CSM211" in w]
    r = run_cli("convert", src, "-o", tmp_path / "o3", "--height", f"bricks={src.parent / 'bricks_height.png'}",
                "--strict")
    assert r.returncode != 0 and "CSM211" in r.stderr
    assert json.loads((tmp_path / "o" / "csm-manifest.json").read_text())  # the manifest records it


def test_a_real_gltf_transform_draco_glb_stays_draco(tmp_path):
    """@pmndrs/assets' pmndrs.glb (CC0, made by glTF-Transform: Draco, extension required): written
    back Draco with the input's positions, normals and uvs, at most 1.5 times its size step map aside."""
    from pmndrs import model

    src = model("pmndrs", tmp_path / "in")
    shutil.copy(SAMPLES / "bricks_height.png", src.parent / "bricks_height.png")
    out = tmp_path / "o"
    assert_clean_run(run_cli("convert", src, "-o", out, "--height", f"base={src.parent / 'bricks_height.png'}"))
    assert errors(validate(out / src.name)) == [] and unused(out / src.name) == unused(src)
    raw = gc.load(out / src.name).json
    assert raw["extensionsRequired"] == gc.load(src).json["extensionsRequired"] == [DRACO]
    assert all(DRACO in p["extensions"] for m in raw["meshes"] for p in m["primitives"])
    decoded, reference = decode_all(gc.load(out / src.name)), decode_all(gc.load(src))
    prim, before = decoded.json["meshes"][0]["primitives"][0], reference.json["meshes"][0]["primitives"][0]
    from scipy.spatial import cKDTree

    for key in ("POSITION", "NORMAL", "TEXCOORD_0"):  # the same values, in another order (and split for tangents)
        a = gc.read_accessor(decoded, prim["attributes"][key])
        b = gc.read_accessor(reference, before["attributes"][key])
        assert cKDTree(b).query(a)[0].max() < 1e-6 and cKDTree(a).query(b)[0].max() < 1e-6, key
    info = raw["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"]
    step_map = raw["bufferViews"][raw["images"][raw["textures"][info["index"]]["source"]]["bufferView"]]["byteLength"]
    size_in, size_out = src.stat().st_size, (out / src.name).stat().st_size
    print(f"pmndrs.glb: {size_in} -> {size_out} bytes ({(size_out - step_map) / size_in:.2f}x step map aside)")
    assert size_out - step_map < 1.5 * size_in
    r = run_cli("verify", out / src.name)
    assert r.returncode == 5 or "PASS" in r.stdout, r.stdout + r.stderr


def test_draco_beside_mesh_quantization_keeps_float_tangents(made, tmp_path):
    """KHR_mesh_quantization declared beside Draco: the tangents of the Draco primitive stay float
    (int8 ones would keep it from being encoded again), and it stays Draco without a warning."""
    doc = gc.load(made["draco"])
    doc.json["extensionsUsed"].append("KHR_mesh_quantization")
    doc.json["extensionsRequired"].append("KHR_mesh_quantization")
    src = made["draco"].parent / "sphere_draco_q.glb"
    src.write_bytes(gc.glb_bytes(doc))
    assert not [w for w in convert(src, tmp_path / "o") if "CSM211" in w]
    raw = gc.load(tmp_path / "o" / src.name).json
    prim = raw["meshes"][0]["primitives"][0]
    assert "TANGENT" in prim["extensions"][DRACO]["attributes"]
    assert raw["accessors"][prim["attributes"]["TANGENT"]]["componentType"] == 5126


def test_a_split_meshopt_primitive_is_encoded_anew(made, tmp_path):
    """A uv mirror splits vertices for their tangents: every attribute and the indices are new views,
    each meshopt-encoded (ATTRIBUTES, TRIANGLES), and decode to the split mesh."""
    src = made["mirrored"]
    convert(src, tmp_path / "o")
    out = tmp_path / "o" / src.name
    raw = gc.load(out).json
    prim = raw["meshes"][0]["primitives"][0]
    modes = {k: raw["bufferViews"][raw["accessors"][a]["bufferView"]]["extensions"][MESHOPT]["mode"]
             for k, a in [*prim["attributes"].items(), ("indices", prim["indices"])]}
    assert modes == {**{k: "ATTRIBUTES" for k in prim["attributes"]}, "indices": "TRIANGLES"}
    before = arrays(decode_all(gc.load(src)))
    after = arrays(decode_all(gc.load(out)))
    assert len(after["POSITION"]) > len(before["POSITION"])  # split
    assert (after["faces"] < len(after["POSITION"])).all()
    assert unused(out) == unused(src)
