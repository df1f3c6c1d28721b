"""Compressed, quantized and transformed glTF, made at test time by the real tools
(gltfpack, gltf-pipeline) from the sample wall and a UV sphere whose height texture is
on uv set 1 with KHR_texture_transform and a clamped sampler; every output is checked
by the Khronos validator and against the conversion of the uncompressed original. Compressed
outputs stay compressed (tests/test_gltf_recompress.py); their geometry is read here through our
own decoder (``decode_all``)."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from attack import assert_clean_run, run_cli
from csm_assets.formats import gltf_container as gc
from gltf_tools import draco, gltfpack
from khronos import errors, validate

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
TRANSFORM = {"offset": [0.25, -0.5], "scale": [3.0, 2.0], "rotation": 0.3}
CSM = "EXT_materials_cone_step_mapping"


def uv_sphere(path: Path, rings: int = 24, segments: int = 48, mirror: bool = False) -> Path:
    """A UV sphere (seam and pole vertices duplicated) with NORMAL, TEXCOORD_0 (a dummy)
    and TEXCOORD_1; its material's heights and base colour sample uv set 1 through
    KHR_texture_transform, the heights with a sampler clamped along S. ``mirror``: u runs
    back on the far half, so the vertices on the mirror line need two tangents."""
    v, u = np.meshgrid(np.linspace(0, 1, rings + 1), np.linspace(0, 1, segments + 1), indexing="ij")
    theta, phi = v.ravel() * math.pi, u.ravel() * 2 * math.pi
    normals = np.column_stack([np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)])
    uvs = np.column_stack([1 - np.abs(2 * u.ravel() - 1) if mirror else u.ravel(), v.ravel()])
    grid = np.arange((rings + 1) * (segments + 1)).reshape(rings + 1, segments + 1)
    a, b, c, d = grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    doc = gc.Document(path, {"asset": {"version": "2.0"}}, [], False)
    attrs = {"POSITION": gc.add_accessor(doc, normals.astype(np.float32), minmax=True),
             "NORMAL": gc.add_accessor(doc, normals.astype(np.float32)),
             "TEXCOORD_0": gc.add_accessor(doc, np.zeros_like(uvs, np.float32)),
             "TEXCOORD_1": gc.add_accessor(doc, uvs.astype(np.float32))}
    indices = gc.add_accessor(doc, faces.reshape(-1).astype(np.uint16), target=gc.ELEMENT_ARRAY_BUFFER)
    placed = {"texCoord": 1, "extensions": {"KHR_texture_transform": dict(TRANSFORM)}}
    doc.json.update({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": "sphere", "primitives": [{"attributes": attrs, "indices": indices, "material": 0}]}],
        "images": [{"uri": "bricks_color.png"}, {"uri": "bricks_height.png"}],
        "samplers": [{"wrapS": 33071, "wrapT": 10497}],
        "textures": [{"source": 0}, {"source": 1, "sampler": 0}],
        "materials": [{"name": "bricks", "pbrMetallicRoughness": {"baseColorTexture": dict(placed, index=0)},
                       "extensions": {"KHR_materials_displacement": {
                           "displacementGeometryTexture": dict(placed, index=1),
                           "displacementGeometryFactor": 0.02}}}],
        "extensionsUsed": ["KHR_texture_transform", "KHR_materials_displacement"],
    })
    doc.json["buffers"][0]["uri"] = f"{path.stem}.bin"
    path.with_suffix(".bin").write_bytes(bytes(doc.buffers[0]))
    path.write_bytes(gc.gltf_bytes(doc))
    return path


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The sphere and the wall, plain, Draco-compressed, quantized and meshopt-compressed."""
    src = tmp_path_factory.mktemp("src")
    for name in ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"]:
        shutil.copy(SAMPLES / name, src / name)
    uv_sphere(src / "sphere.gltf")
    gltfpack(uv_sphere(src / "mirrored.gltf", mirror=True), src / "mirrored_q.gltf")
    files = {"sphere": src / "sphere.gltf", "wall": src / "brick_wall.gltf", "mirrored": src / "mirrored_q.gltf"}
    for stem in ("sphere", "wall"):
        files[f"{stem}-draco"] = draco(files[stem], src / f"{stem}_draco.gltf")
        files[f"{stem}-quantized"] = gltfpack(files[stem], src / f"{stem}_q.gltf")
        files[f"{stem}-meshopt"] = gltfpack(files[stem], src / f"{stem}_mo.glb", "-cc")
    return files


def convert(src: Path, out: Path, *args) -> gc.Document:
    """Convert through the CLI; the output, validated (no errors), loaded and decoded."""
    from csm_assets.formats.gltf_decode import decode_all

    assert_clean_run(run_cli("convert", src, "-o", out, *args))
    written = out / src.name
    assert errors(validate(written)) == [], src.name
    return decode_all(gc.load(written))


def primitive_arrays(doc: gc.Document) -> dict:
    prim = doc.json["meshes"][0]["primitives"][0]
    out = {k: gc.read_accessor(doc, a) for k, a in prim["attributes"].items()}
    out["faces"] = gc.read_accessor(doc, prim["indices"])[:, 0].reshape(-1, 3)
    return out


def node_matrix(doc: gc.Document) -> np.ndarray:
    """The local-to-world matrix of the node holding mesh 0 (gltfpack moves its dequantization there)."""
    node = next(n for n in doc.json["nodes"] if n.get("mesh") == 0)
    m = np.eye(4)
    if "matrix" in node:
        return np.array(node["matrix"]).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m[:3, :3] = rot * np.array(node.get("scale", [1, 1, 1]))
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def tangents_by_position(doc: gc.Document) -> tuple[np.ndarray, np.ndarray]:
    """World positions and tangents (xyz in world axes, w) of mesh 0's vertices."""
    a = primitive_arrays(doc)
    m = node_matrix(doc)
    pos = a["POSITION"] @ m[:3, :3].T + m[:3, 3]
    t = a["TANGENT"]
    xyz = t[:, :3] @ m[:3, :3].T
    xyz /= np.linalg.norm(xyz, axis=1, keepdims=True)
    return pos, np.column_stack([xyz, t[:, 3]])


def assert_same_tangents(doc: gc.Document, reference: gc.Document, tol: float = 0.02) -> None:
    """Every vertex's tangent matches the reference's nearest vertex away from the poles,
    where a sphere's tangents are undefined."""
    from scipy.spatial import cKDTree

    pos, tan = tangents_by_position(doc)
    rpos, rtan = tangents_by_position(reference)
    scale = np.ptp(rpos, axis=0).max()
    _, near = cKDTree(rpos).query(pos)
    keep = np.abs(pos[:, 1]) < 0.95 * scale / 2
    cos = np.einsum("ij,ij->i", tan[keep, :3], rtan[near[keep], :3])
    assert np.quantile(cos, 0.05) > 1 - tol, np.sort(cos)[:10]
    assert np.mean(tan[keep, 3] == rtan[near[keep], 3]) > 0.95


def step_info(doc: gc.Document) -> tuple[dict, dict]:
    ext = doc.json["materials"][0]["extensions"][CSM]
    tex = doc.json["textures"][ext["stepMapTexture"]["index"]]
    return ext["stepMapTexture"], doc.json["samplers"][tex["sampler"]]


def test_transformed_height_places_the_step_map_alike(made, tmp_path):
    doc = convert(made["sphere"], tmp_path / "o")
    info, sampler = step_info(doc)
    assert info["texCoord"] == 1 and info["extensions"]["KHR_texture_transform"] == TRANSFORM
    assert (sampler["wrapS"], sampler["wrapT"]) == (33071, 10497)  # CLAMP stays CLAMP
    assert doc.json["materials"][0]["extensions"][CSM]["tile"] == [False, True]
    # depth is per unit of the transformed uvs: 0.02 m over sqrt(world area / uv area)
    ext = doc.json["materials"][0]["extensions"][CSM]
    a = primitive_arrays(doc)
    p, t = a["POSITION"][a["faces"]], a["TEXCOORD_1"][a["faces"]]
    world = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    uv = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() * 3.0 * 2.0  # the transform's scale
    assert ext["depthScale"] == pytest.approx(0.02 / math.sqrt(world / uv), rel=1e-3)


def test_tangents_follow_the_rotated_uvs(made, tmp_path):
    """With a rotation in KHR_texture_transform the tangent is d(position)/du of the
    transformed u: on the sphere it is the untransformed frame turned by the rotation."""
    doc = convert(made["sphere"], tmp_path / "o")
    a = primitive_arrays(doc)
    n = a["NORMAL"]
    sin = np.sqrt(1 - n[:, 1] ** 2).clip(1e-9)
    east = np.column_stack([n[:, 2], np.zeros(len(n)), -n[:, 0]]) / sin[:, None]  # dP/du over 2 pi sin
    south = np.column_stack([n[:, 1] * n[:, 0], -sin ** 2, n[:, 1] * n[:, 2]]) / sin[:, None]  # dP/dv over pi
    sx, sy, r = 3.0, 2.0, 0.3
    m = np.array([[sx * math.cos(r), sy * math.sin(r)], [-sx * math.sin(r), sy * math.cos(r)]])
    inv = np.linalg.inv(m)  # (u, v) = inv (u', v'): dP/du' = inv[0, 0] dP/du + inv[1, 0] dP/dv
    expected = inv[0, 0] * 2 * math.pi * sin[:, None] * east + inv[1, 0] * math.pi * south
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    keep = np.abs(n[:, 1]) < 0.9
    cos = np.einsum("ij,ij->i", a["TANGENT"][keep, :3], expected[keep])
    assert np.quantile(cos, 0.05) > 0.98, np.sort(cos)[:5]


@pytest.mark.parametrize("kind", ["draco", "quantized", "meshopt"])
def test_compressed_and_quantized_spheres(made, tmp_path, kind):
    reference = convert(made["sphere"], tmp_path / "ref")
    src = made[f"sphere-{kind}"]
    args = () if kind == "draco" else ("--height", f"bricks={src.parent / 'bricks_height.png'}")
    doc = convert(src, tmp_path / "o", *args)
    raw, before = gc.load(tmp_path / "o" / src.name).json, gc.load(src).json
    for key in ("extensionsUsed", "extensionsRequired"):  # compressed as the input was
        packed = {"KHR_draco_mesh_compression", "EXT_meshopt_compression"}
        assert packed & set(raw.get(key, [])) == packed & set(before.get(key, [])), key
    assert [b for b in raw["buffers"] if b.get("extensions")] == [b for b in before["buffers"] if b.get("extensions")] \
        or kind == "meshopt"  # meshopt's fallback buffer, as gltfpack wrote it (its length grows by the tangents)
    views = {int(v) for v in re.findall(r'"bufferView": (\d+)', json.dumps(raw))}
    views |= {i for i, v in enumerate(raw["bufferViews"]) if "EXT_meshopt_compression" in v.get("extensions", {})}
    assert views == set(range(len(raw["bufferViews"])))  # none unused: the old Draco bytes went
    info, sampler = step_info(doc)
    if kind == "draco":  # gltf-pipeline keeps the height texture, its uv set and transform
        assert info["texCoord"] == 1 and info["extensions"]["KHR_texture_transform"] == TRANSFORM
        assert (sampler["wrapS"], sampler["wrapT"]) == (33071, 10497)
    else:  # gltfpack drops the height texture; the step map is placed like the base colour
        base = doc.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
        assert info["texCoord"] == base.get("texCoord", 0)
        assert info["extensions"]["KHR_texture_transform"] == base["extensions"]["KHR_texture_transform"]
        base_tex = doc.json["textures"][base["index"]]
        base_sampler = doc.json["samplers"][base_tex["sampler"]] if "sampler" in base_tex else {}
        assert (sampler["wrapS"], sampler["wrapT"]) == (base_sampler.get("wrapS", 10497),
                                                        base_sampler.get("wrapT", 10497))
    assert_same_tangents(doc, reference)
    if kind == "meshopt":  # decoded data equals gltfpack's own uncompressed quantized output
        decoded, plain = _decoded(src), primitive_arrays(gc.load(made["sphere-quantized"]))
        for key in ("POSITION", "TEXCOORD_1"):
            np.testing.assert_array_equal(np.sort(decoded[key], axis=0), np.sort(plain[key], axis=0))
        # -cc stores normals through meshopt's octahedral filter: the same up to a step of int8
        np.testing.assert_allclose(np.sort(decoded["NORMAL"], axis=0), np.sort(plain["NORMAL"], axis=0),
                                   atol=2.5 / 127)


def _decoded(src: Path) -> dict:
    from csm_assets.formats import gltf_decode

    doc = gc.load(src)
    assert gltf_decode.decode_meshopt(doc) > 0
    return primitive_arrays(doc)


@pytest.mark.parametrize("kind", ["draco", "quantized", "meshopt"])
def test_compressed_walls(made, tmp_path, kind):
    src = made[f"wall-{kind}"]
    args = () if kind == "draco" else ("--height", f"bricks={SAMPLES / 'bricks_height.png'}")
    doc = convert(src, tmp_path / "o", *args)
    tan = primitive_arrays(doc)["TANGENT"]
    np.testing.assert_allclose(tan, np.tile([1, 0, 0, 1], (len(tan), 1)), atol=1e-3)
    if src.suffix == ".glb":
        assert sorted(p.name for p in (tmp_path / "o").iterdir()) == sorted([src.name, "csm-manifest.json"])
    # the decoded, dequantized wall renders as the exact tracer sees it
    r = run_cli("verify", tmp_path / "o" / src.name)
    if r.returncode == 5:
        pytest.skip("no OpenGL/EGL context for verify")
    assert r.returncode == 0 and "PASS" in r.stdout, r.stdout + r.stderr


def test_quantized_split_vertices_stay_aligned(made, tmp_path):
    """Vertices on a uv mirror split for their tangents: the rewritten int16 VEC3 positions and
    int8 normals get 4-byte strides (the validator reports MESH_PRIMITIVE_ACCESSOR_UNALIGNED else)."""
    src = made["mirrored"]
    doc = convert(src, tmp_path / "o", "--height", f"bricks={src.parent / 'bricks_height.png'}")
    prim = doc.json["meshes"][0]["primitives"][0]
    before = gc.load(src)
    old_count = before.json["accessors"][before.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["count"]
    assert doc.json["accessors"][prim["attributes"]["POSITION"]]["count"] > old_count  # rewritten (split)
    for name, index in prim["attributes"].items():
        acc = doc.json["accessors"][index]
        view = doc.json["bufferViews"][acc["bufferView"]]
        assert (view.get("byteOffset", 0) + acc.get("byteOffset", 0)) % 4 == 0, name
        assert view.get("byteStride", 4) % 4 == 0, name
    assert json.dumps(doc.json)  # plain JSON
