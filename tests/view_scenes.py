"""Scenes and reference renders for the viewer's browser tests.

``cylinder_scene`` writes a curved one. ``two_material_scene`` writes a .gltf with two quads side by side: one whose height and
colour images are files beside it (optionally placed through a KHR_texture_transform), one
whose height image is embedded (a data: URI) and whose node is moved and scaled.
``quadrant_material`` turns one material of a converted scene into a quadrant one (two images).
``moderngl_hits`` draws every primitive of a converted scene carrying the CSM extension with
the project's Renderer, at one camera, its uvs placed by the step map's texCoord and
KHR_texture_transform, and merges them (the quads of these scenes never overlap on screen);
``moderngl_draws`` gives each primitive's render. ``quad_geometry`` is the unit quad's buffers and
accessors.
"""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path

import numpy as np

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def quad_geometry() -> dict:
    """The glTF ``buffers``, ``bufferViews`` and ``accessors`` of a unit quad at the origin facing +z
    (accessors 0 POSITION, 1 NORMAL, 2 TEXCOORD_0 from 0 to 1, 3 indices), its buffer a data: URI."""
    pos = np.array([[-0.5, 0.5, 0], [0.5, 0.5, 0], [0.5, -0.5, 0], [-0.5, -0.5, 0]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    idx = np.array([0, 3, 2, 0, 2, 1], np.uint16)  # counter-clockwise seen from +z
    buf = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    views = [(0, 48, 34962), (48, 48, 34962), (96, 32, 34962), (128, 12, 34963)]
    return {
        "buffers": [{"byteLength": len(buf),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n, "target": t} for o, n, t in views],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-0.5, -0.5, 0], "max": [0.5, 0.5, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}]}


def two_material_scene(folder: Path, transform: dict | None = None, cobbles_color: bool = False) -> Path:
    """Write ``two.gltf`` (and its external images) into ``folder``; returns its path.
    transform: a KHR_texture_transform on the bricks' height and colour textures.
    cobbles_color: the cobbles image is also the cobbles' base colour (so that tools which
    drop textures they do not know, as gltfpack does, keep its uvs)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("bricks_height.png", "bricks_color.png"):
        shutil.copy(SAMPLES / name, folder / name)
    cobbles = base64.b64encode((SAMPLES / "cobbles.png").read_bytes()).decode()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0, "name": "bricks", "translation": [-0.6, 0, 0]},
                  {"mesh": 1, "name": "cobbles", "translation": [0.65, 0.1, 0.1], "scale": [0.8, 0.8, 0.8]}],
        "meshes": [{"name": f"quad{i}", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                                         "indices": 3, "material": i}]} for i in (0, 1)],
        **quad_geometry(),
        "images": [{"uri": "bricks_height.png"}, {"uri": "bricks_color.png"},
                   {"uri": "data:image/png;base64," + cobbles, "name": "cobbles"}],
        "textures": [{"source": 0}, {"source": 1}, {"source": 2}],
        "materials": [
            {"name": "bricks", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}, "metallicFactor": 0},
             "extensions": {"KHR_materials_displacement": {"displacementGeometryTexture": {"index": 0},
                                                           "displacementGeometryFactor": 0.05}}},
            {"name": "cobbles", "pbrMetallicRoughness": {"metallicFactor": 0},
             "extensions": {"KHR_materials_displacement": {"displacementGeometryTexture": {"index": 2},
                                                           "displacementGeometryFactor": 0.04}}}],
        "extensionsUsed": ["KHR_materials_displacement"],
    }
    bricks = doc["materials"][0]
    if transform is not None:
        for info in (bricks["pbrMetallicRoughness"]["baseColorTexture"],
                     bricks["extensions"]["KHR_materials_displacement"]["displacementGeometryTexture"]):
            info["extensions"] = {"KHR_texture_transform": dict(transform)}
        doc["extensionsUsed"].append("KHR_texture_transform")
    if cobbles_color:
        doc["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 2}
    path = folder / "two.gltf"
    path.write_text(json.dumps(doc))
    return path


def cylinder_scene(folder: Path, segments: int = 32) -> Path:
    """Write ``cylinder.gltf``: an open cylinder (radius 0.5, height 1, axis +y, radial normals)
    with the brick height texture wrapped twice around it (a seam where u goes 2 -> 0)."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(SAMPLES / "bricks_height.png", folder / "bricks_height.png")
    a = np.linspace(0, 2 * np.pi, segments + 1)
    ring = np.stack([0.5 * np.sin(a), np.zeros_like(a), 0.5 * np.cos(a)], axis=1)
    pos = np.concatenate([ring + [0, 1, 0], ring]).astype(np.float32)
    nrm = np.concatenate([ring, ring]).astype(np.float32) * 2
    u = np.linspace(0, 2, segments + 1)
    uv = np.concatenate([np.stack([u, np.zeros_like(u)], 1), np.stack([u, np.ones_like(u)], 1)]).astype(np.float32)
    n = segments + 1
    idx = np.array([[j, n + j, n + j + 1, j, n + j + 1, j + 1] for j in range(segments)], np.uint16).ravel()
    buf = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    sizes = [pos.nbytes, nrm.nbytes, uv.nbytes, idx.nbytes]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).tolist()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                    "indices": 3, "material": 0}]}],
        "buffers": [{"byteLength": len(buf),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": k} for o, k in zip(offsets, sizes)],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
             "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": len(pos), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": len(pos), "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": len(idx), "type": "SCALAR"}],
        "images": [{"uri": "bricks_height.png"}], "textures": [{"source": 0}],
        "materials": [{"name": "bricks", "extensions": {"KHR_materials_displacement": {
            "displacementGeometryTexture": {"index": 0}, "displacementGeometryFactor": 0.03}}}],
        "extensionsUsed": ["KHR_materials_displacement"],
    }
    path = folder / "cylinder.gltf"
    path.write_text(json.dumps(doc))
    return path


def quadrant_material(scene: Path, material: str) -> dict:
    """Rewrite the converted ``scene`` (.gltf) so that ``material`` carries a quadrant step map:
    the quadrant maps of its step map's heights (R, the settings it was made with), written by
    the library beside it (``<stem>_quadrant.png`` and its ``_q`` second image), as two new
    textures with the first's sampler; ``stepMap2Texture`` with the first's texCoord, variant
    quadrant, the quadrant map's minimum step. Returns the material's new extension object."""
    from csm_assets.stepmap import load_step_map, make_step_map, save_step_map, second_path

    doc = json.loads(scene.read_text())
    (mat,) = [m for m in doc["materials"] if m.get("name") == material]
    ext = mat["extensions"]["EXT_materials_cone_step_mapping"]
    tex = doc["textures"][ext["stepMapTexture"]["index"]]
    path = scene.parent / doc["images"][tex["source"]]["uri"]
    sm = load_step_map(path)
    assert sm.settings.cones == "conservative" and sm.pixels.dtype == np.uint8
    quad = make_step_map(sm.pixels[..., 0], sm.settings.replace(cones="quadrant"))
    first = path.with_name(path.stem + "_quadrant.png")
    save_step_map(quad, first)
    for p in (first, second_path(first)):
        doc["images"].append({"uri": p.name})
        doc["textures"].append({k: v for k, v in tex.items() if k != "source"} | {"source": len(doc["images"]) - 1})
    info = {k: v for k, v in ext["stepMapTexture"].items() if k != "index"}
    ext["stepMapTexture"] = {"index": len(doc["textures"]) - 2, **info}
    ext["stepMap2Texture"] = {"index": len(doc["textures"]) - 1, **({"texCoord": info["texCoord"]} if "texCoord" in info else {})}
    ext.update(variant="quadrant", steps=0, minStep=quad.min_step)
    scene.write_text(json.dumps(doc))
    return ext


def _uv_scale(pos: np.ndarray, uv: np.ndarray, faces: np.ndarray, tol: float = 3e-3) -> tuple:
    """(the Renderer's 2x2 uv_per_world (render.mesh.uv_frame: sheared where a texture transform
    shears the uvs), |dP/du x dP/dv|) of a mesh whose every triangle has the same ones (planes
    with affine uvs, regular cylinders), to ``tol`` (gltfpack's quantized uvs and positions vary
    them by up to 0.2 %); ValueError otherwise."""
    from csm_assets.render.mesh import uv_frame

    e1, e2 = pos[faces[:, 1]] - pos[faces[:, 0]], pos[faces[:, 2]] - pos[faces[:, 0]]
    d1, d2 = uv[faces[:, 1]] - uv[faces[:, 0]], uv[faces[:, 2]] - uv[faces[:, 0]]
    det = (d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1])[:, None]
    du = (e1 * d2[:, 1:] - e2 * d1[:, 1:]) / det
    dv = (e2 * d1[:, :1] - e1 * d2[:, :1]) / det
    frames = uv_frame(du, dv).reshape(-1, 4)
    vals = np.column_stack([frames, np.linalg.norm(np.cross(du, dv), axis=1)])
    if np.ptp(vals, axis=0).max() > tol * np.abs(vals).max():
        raise ValueError("the uv scale varies over the mesh: one Renderer uniform cannot match it")
    return frames.mean(axis=0).reshape(2, 2), float(vals[:, 4].mean())


def _node_matrices(doc) -> dict:
    """mesh index -> list of world matrices (4x4) of the nodes showing it."""
    out: dict = {}

    def local(node):
        if "matrix" in node:
            return np.array(node["matrix"], float).reshape(4, 4).T
        t = np.eye(4)
        t[:3, 3] = node.get("translation", [0, 0, 0])
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        s = np.diag([*node.get("scale", [1, 1, 1]), 1.0])
        return t @ r @ s

    def walk(i, parent):
        node = doc.json["nodes"][i]
        m = parent @ local(node)
        if "mesh" in node:
            out.setdefault(node["mesh"], []).append(m)
        for c in node.get("children", []):
            walk(c, m)

    for i in doc.json["scenes"][doc.json.get("scene", 0)]["nodes"]:
        walk(i, np.eye(4))
    return out


def moderngl_hits(path: Path, camera, size: tuple, transform: bool = True):
    """(status int8 (h, w): -1 none, 0 hit, 1 cap, 2 miss; hit uv float64 (h, w, 2); texels
    (h, w, 2): the step map's (cols, rows) there) of every CSM primitive of a converted scene.
    transform False: the step map's KHR_texture_transform ignored (what a viewer dropping it draws)."""
    w, h = size
    status = np.full((h, w), -1, np.int8)
    uv = np.zeros((h, w, 2))
    texels = np.ones((h, w, 2))
    for res, packed in moderngl_draws(path, camera, size, transform):
        sel = res.covered
        status[sel], uv[sel] = res.status[sel], res.hit_uv[sel]
        texels[sel] = (packed.shape[1], packed.shape[0])
    return status, uv, texels


def moderngl_iterations(path: Path, camera, size: tuple) -> np.ndarray:
    """int32 (h, w): the view ray's iterations (fetches) of every CSM primitive of a converted
    scene at one camera, as the rawInfo view counts them; -1 where no CSM primitive is drawn."""
    w, h = size
    out = np.full((h, w), -1, np.int32)
    for res, _ in moderngl_draws(path, camera, size, True):
        out[res.covered] = res.iterations[res.covered]
    return out


def moderngl_lods(path: Path, camera, size: tuple) -> np.ndarray:
    """int32 (h, w): the level each pixel's march read (RenderResult.lod: 0 without a level chain)
    for every CSM primitive of a converted scene; -1 where none is drawn."""
    w, h = size
    out = np.full((h, w), -1, np.int32)
    for res, _ in moderngl_draws(path, camera, size, True):
        out[res.covered] = res.lod[res.covered]
    return out


def moderngl_shadows(path: Path, camera, size: tuple, light_direction) -> tuple:
    """(status int8 (h, w) as moderngl_hits; shadow float64 (h, w, 4): hard lit, soft share,
    shadow steps, shadow status) of a converted scene whose materials say ``selfShadow`` (and
    ``lightSize``), lit by a directional light towards world ``light_direction``."""
    w, h = size
    status = np.full((h, w), -1, np.int8)
    shadow = np.zeros((h, w, 4))
    for res, _ in moderngl_draws(path, camera, size, True, tuple(map(float, light_direction))):
        sel = res.covered
        status[sel] = res.status[sel]
        if res.shadow is not None:
            shadow[sel] = res.shadow[sel]
    return status, shadow


def moderngl_draws(path: Path, camera, size: tuple, transform: bool, light_direction=None):
    """(RenderResult, packed step map) of each CSM primitive of a converted glTF at ``camera`` (a
    quadrant material with its second image, ``stepMap2Texture``; a step map with a level chain,
    ``stepMapLevelsTexture``, with its levels: the level march)."""
    from csm_assets.formats import gltf_container as gc
    from csm_assets.formats import read_step_map
    from csm_assets.formats.gltf import apply_transform
    from csm_assets.formats.gltf_decode import decode_all
    from csm_assets.render.renderer import Material, Mesh, Renderer
    from csm_assets.scene import Texture
    from csm_assets.step_levels import split_atlas

    doc = decode_all(gc.load(path))  # a compressed output's geometry, by our own reader
    with Renderer(size) as r:
        for mi, matrices in _node_matrices(doc).items():
            for prim in doc.json["meshes"][mi]["primitives"]:
                ext = doc.json["materials"][prim["material"]].get("extensions", {}).get(
                    "EXT_materials_cone_step_mapping")
                if ext is None:
                    continue
                def read(index):
                    image = doc.json["images"][doc.json["textures"][index]["source"]]
                    tex = (Texture("s", path=path.parent / image["uri"]) if "uri" in image else
                           Texture("s", data=gc.view_bytes(doc, image["bufferView"]), mime=image.get("mimeType")))
                    with tex.as_file() as f:
                        return read_step_map(f)

                packed = read(ext["stepMapTexture"]["index"])
                second = read(ext["stepMap2Texture"]["index"]) if "stepMap2Texture" in ext else None
                chains = [tuple(np.ascontiguousarray(lv) for lv in split_atlas(read(ext[key]["index"]), packed.shape[:2]))
                          if key in ext else () for key in ("stepMapLevelsTexture", "stepMap2LevelsTexture")]
                a = {k: gc.read_accessor(doc, v).astype(np.float64) for k, v in prim["attributes"].items()}
                idx = gc.read_accessor(doc, prim["indices"])[:, 0].astype(np.uint32).reshape(-1, 3)
                info = ext["stepMapTexture"]
                place = info.get("extensions", {}).get("KHR_texture_transform") if transform else None
                uvs = apply_transform(a[f"TEXCOORD_{(place or {}).get('texCoord', info.get('texCoord', 0))}"], place)
                for model in matrices:
                    pos = a["POSITION"] @ model[:3, :3].T + model[:3, 3]
                    frame, area = _uv_scale(pos, uvs, idx.astype(np.int64))
                    mesh = Mesh(a["POSITION"], a["NORMAL"], a["TANGENT"], uvs, idx)
                    mat = Material(packed, max_ratio=ext.get("maxRatio", 1.0), tile=tuple(ext["tile"]),
                                   depth=ext["depthScale"] * float(np.sqrt(area)), uv_per_world=frame,
                                   min_step=ext.get("minStep", 1.0), step_map2=second, levels=chains[0],
                                   levels2=chains[1] if second is not None else ())
                    if light_direction is not None:
                        mat.light_direction = light_direction
                        mat.self_shadow = ext.get("selfShadow", False) is True
                        mat.light_size = float(ext.get("lightSize", 0.0))
                    yield r.render(mat, camera, variant=ext.get("variant", "exact"), steps=ext.get("steps") or 16,
                                   mesh=mesh, model=model), packed
