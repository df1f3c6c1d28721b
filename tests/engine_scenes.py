"""Scenes and references for the tests that draw one converted scene with both web engines
(three.js and Babylon.js): ``two_uv_scene`` writes a quad whose relief lies on its second uv
set (the colour on the first); ``white_diffuse`` makes a converted scene's materials white
Lambert-like dielectrics; ``moderngl_lit`` is the project's lit render of a scene (Lambert,
one directional light, self-shadowed where the material says so); ``luminance`` and
``lit_agreement`` compare lit images drawn by different shading models."""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path

import numpy as np

from view_scenes import SAMPLES, moderngl_draws


def two_uv_scene(folder: Path) -> Path:
    """Write ``two_uv.gltf``: one quad (1 x 1, facing +z) with TEXCOORD_0 in [0, 1] (its base
    colour) and TEXCOORD_1 = 2 uv + (0.25, 0.5) (its height texture, texCoord 1)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("bricks_height.png", "bricks_color.png"):
        shutil.copy(SAMPLES / name, folder / name)
    pos = np.array([[-0.5, 0.5, 0], [0.5, 0.5, 0], [0.5, -0.5, 0], [-0.5, -0.5, 0]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    uv0 = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    uv1 = (2 * uv0 + [0.25, 0.5]).astype(np.float32)
    idx = np.array([0, 3, 2, 0, 2, 1], np.uint16)
    parts = [pos, nrm, uv0, uv1, idx]
    buf = b"".join(p.tobytes() for p in parts)
    offsets = np.concatenate([[0], np.cumsum([p.nbytes for p in parts])[:-1]]).tolist()
    kinds = [("VEC3", 5126), ("VEC3", 5126), ("VEC2", 5126), ("VEC2", 5126), ("SCALAR", 5123)]
    accessors = [{"bufferView": i, "componentType": c, "count": len(p), "type": t}
                 for i, ((t, c), p) in enumerate(zip(kinds, parts))]
    accessors[0].update(min=[-0.5, -0.5, 0], max=[0.5, 0.5, 0])
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": "quad"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3},
                                    "indices": 4, "material": 0}]}],
        "buffers": [{"byteLength": len(buf),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": p.nbytes} for o, p in zip(offsets, parts)],
        "accessors": accessors,
        "images": [{"uri": "bricks_height.png"}, {"uri": "bricks_color.png"}],
        "textures": [{"source": 0}, {"source": 1}],
        "materials": [{"name": "bricks", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}, "metallicFactor": 0},
                       "extensions": {"KHR_materials_displacement": {
                           "displacementGeometryTexture": {"index": 0, "texCoord": 1},
                           "displacementGeometryFactor": 0.03}}}],
        "extensionsUsed": ["KHR_materials_displacement"],
    }
    path = folder / "two_uv.gltf"
    path.write_text(json.dumps(doc))
    return path


def white_diffuse(scene: Path) -> Path:
    """Make every material of a converted .gltf a white, fully rough dielectric (no base colour
    texture, base colour factor 1, metallic 0, roughness 1), in place: the glTF material nearest
    to the lit comparison's reference, white Lambert. (A material without pbrMetallicRoughness is
    a rough metal by glTF's defaults; three.js draws it with no diffuse term at all.)"""
    doc = json.loads(scene.read_text())
    for m in doc["materials"]:
        pbr = m.setdefault("pbrMetallicRoughness", {})
        pbr.pop("baseColorTexture", None)
        pbr.update(baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=1.0)
    scene.write_text(json.dumps(doc))
    return scene


def moderngl_lit(path: Path, camera, size: tuple, light_direction) -> tuple:
    """(status int8 (h, w) as moderngl_hits; lit float64 (h, w): ambient + diffuse * max(0, n.l)
    times the self-shadowed share, white surfaces) of a converted scene's CSM primitives lit by a
    directional light towards world ``light_direction``."""
    w, h = size
    status = np.full((h, w), -1, np.int8)
    lit = np.zeros((h, w))
    for res, _ in moderngl_draws(path, camera, size, True, tuple(map(float, light_direction))):
        sel = res.covered
        status[sel] = res.status[sel]
        lit[sel] = res.color[..., 0][sel]
    return status, lit


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luma of an (h, w, 3) image in [0, 1]."""
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def lit_agreement(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """Spearman's rank correlation of two lit images' values over ``mask``: 1 when one is any
    increasing function of the other (engines differ in their lights' units, their BRDF and
    their output transfer, not in where the relief is bright or dark)."""
    from scipy.stats import spearmanr

    return float(spearmanr(a[mask].ravel(), b[mask].ravel()).statistic)
