"""Curved test scenes the tests build: a UV sphere (material "stones") and a cylinder
whose uvs mirror halfway round (material "ridges", u runs 0..1..0), each with its own
tiling height texture, written as glTF (+ .bin, and a camera), GLB, OBJ + MTL and USD (with a camera)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
from conftest import random_field
from PIL import Image


def uv_sphere(rings=12, segments=16, radius=1.0):
    """(positions, normals, uvs (glTF: v down), triangles) of a UV sphere; seams duplicated."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi) * 2, T / np.pi], -1).reshape(-1, 2)  # u repeats twice around
    return radius * n, n, uv, _grid_faces(rings, segments, skip_poles=True)


def mirrored_cylinder(segments=16, rows=4, radius=0.6, height=1.5, x=2.5):
    """A cylinder beside the sphere whose u runs 0 -> 1 -> 0 around (mirrored uvs)."""
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    y = np.linspace(-height / 2, height / 2, rows + 1)
    Y, P = np.meshgrid(y, ph, indexing="ij")
    n = np.stack([np.cos(P), np.zeros_like(P), np.sin(P)], -1).reshape(-1, 3)
    pos = n * radius + np.stack([np.full_like(P, x), Y, np.zeros_like(P)], -1).reshape(-1, 3)
    u = 1.0 - np.abs(P / np.pi - 1.0)  # 0 .. 1 .. 0
    uv = np.stack([u, (Y - y[0]) / height], -1).reshape(-1, 2)
    return pos, n, uv, _grid_faces(rows, segments)


def _grid_faces(rows, segments, skip_poles=False):
    faces = []
    w = segments + 1
    for r in range(rows):
        for s in range(segments):
            a, b, c, d = r * w + s, r * w + s + 1, (r + 1) * w + s, (r + 1) * w + s + 1
            if not (skip_poles and r == 0):
                faces.append((a, c, b))
            if not (skip_poles and r == rows - 1):
                faces.append((b, c, d))
    return np.array(faces, np.int64)


def height_textures(folder: Path):
    folder.mkdir(parents=True, exist_ok=True)
    for name, seed in (("stones", 1), ("ridges", 2)):
        h = random_field(32, seed, smooth=1.5)
        Image.fromarray((h * 65535).astype(np.uint16)).save(folder / f"{name}_height.png")


def meshes():
    return [("sphere", "stones", *uv_sphere()), ("cylinder", "ridges", *mirrored_cylinder())]


def write_gltf(folder: Path, name="curved", binary=False, depth=0.05) -> Path:
    height_textures(folder)
    blob, views, accessors, prims = bytearray(), [], [], []
    mats = ["stones", "ridges"]

    def add(arr, kind, ctype, target):
        arr = np.ascontiguousarray(arr)
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": arr.nbytes, "target": target})
        blob.extend(arr.tobytes())
        acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": len(arr), "type": kind}
        if kind == "VEC3":
            acc["min"], acc["max"] = arr.min(0).tolist(), arr.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    for _, mat, pos, nrm, uv, faces in meshes():
        attrs = {"POSITION": add(pos.astype(np.float32), "VEC3", 5126, 34962),
                 "NORMAL": add(nrm.astype(np.float32), "VEC3", 5126, 34962),
                 "TEXCOORD_0": add(uv.astype(np.float32), "VEC2", 5126, 34962)}
        prims.append({"attributes": attrs, "indices": add(faces.astype(np.uint32).ravel(), "SCALAR", 5125, 34963),
                      "material": mats.index(mat)})
    doc = {
        "asset": {"version": "2.0", "generator": "csm-assets tests"},
        "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0, "name": "sphere"}, {"mesh": 1, "name": "cylinder"},
                  {"camera": 0, "name": "cam", "translation": [1.2, 0.8, 5.0]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.1, "zfar": 50}}],
        "meshes": [{"name": "sphere", "primitives": [prims[0]]}, {"name": "cylinder", "primitives": [prims[1]]}],
        "materials": [{"name": m, "extras": {"csm_height": {"index": i, "scale": depth}}} for i, m in enumerate(mats)],
        "textures": [{"source": i} for i in range(2)],
        "images": [{"uri": f"{m}_height.png"} for m in mats],
        "buffers": [{"byteLength": len(blob)}], "bufferViews": views, "accessors": accessors,
    }
    if not binary:
        doc["buffers"][0]["uri"] = f"{name}.bin"
        (folder / f"{name}.bin").write_bytes(bytes(blob))
        path = folder / f"{name}.gltf"
        path.write_text(json.dumps(doc))
        return path
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + bytes(blob)
    path = folder / f"{name}.glb"
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    return path


def write_obj(folder: Path, name="curved", depth=0.05) -> Path:
    height_textures(folder)
    lines, mtl, base = [f"mtllib {name}.mtl"], [], 0
    for obj, mat, pos, nrm, uv, faces in meshes():
        lines += [f"o {obj}"] + [f"v {x:.7g} {y:.7g} {z:.7g}" for x, y, z in pos]
        lines += [f"vt {u:.7g} {1 - v:.7g}" for u, v in uv]  # OBJ: v up
        lines += [f"vn {x:.7g} {y:.7g} {z:.7g}" for x, y, z in nrm]
        lines += [f"usemtl {mat}"] + ["f " + " ".join(f"{i + base}/{i + base}/{i + base}" for i in f + 1)
                                      for f in faces]
        base += len(pos)
        mtl += [f"newmtl {mat}", "Kd 0.8 0.8 0.8", f"disp -mm 0 {depth} {mat}_height.png", ""]
    path = folder / f"{name}.obj"
    path.write_text("\n".join(lines) + "\n")
    (folder / f"{name}.mtl").write_text("\n".join(mtl))
    return path


def write_usd(folder: Path, name="curved", depth=0.05) -> Path:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

    height_textures(folder)
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    for obj, mat_name, pos, nrm, uv, faces in meshes():
        mesh = UsdGeom.Mesh.Define(stage, f"/World/{obj}")
        mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pos])
        mesh.CreateFaceVertexCountsAttr([3] * len(faces))
        mesh.CreateFaceVertexIndicesAttr([int(i) for i in faces[:, ::-1].ravel()])  # USD: counter-clockwise
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateNormalsAttr([Gf.Vec3f(*n) for n in nrm])
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex).Set(
            [Gf.Vec2f(u, 1 - v) for u, v in uv])
        mat = UsdShade.Material.Define(stage, f"/World/Looks/{mat_name}")
        reader = UsdShade.Shader.Define(stage, f"/World/Looks/{mat_name}/st")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        tex = UsdShade.Shader.Define(stage, f"/World/Looks/{mat_name}/height")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(f"./{mat_name}_height.png")
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
            reader.CreateOutput("result", Sdf.ValueTypeNames.Float2))
        tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(depth, depth, depth, 1))
        surface = UsdShade.Shader.Define(stage, f"/World/Looks/{mat_name}/surface")
        surface.CreateIdAttr("UsdPreviewSurface")
        surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(
            tex.CreateOutput("r", Sdf.ValueTypeNames.Float))
        mat.CreateSurfaceOutput().ConnectToSource(surface.CreateOutput("surface", Sdf.ValueTypeNames.Token))
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    cam = UsdGeom.Camera.Define(stage, "/World/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(1.2, 0.8, 5.0))  # looks down -z, as the glTF's camera
    cam.CreateFocalLengthAttr(25.0)
    cam.CreateVerticalApertureAttr(24.0)
    path = folder / f"{name}.usda"
    stage.GetRootLayer().Export(str(path))
    return path


def write_usdz(folder: Path, name="curved", depth=0.05) -> Path:
    """The USD scene packaged as a .usdz (its textures inside the package)."""
    from pxr import UsdUtils

    src = write_usd(folder / "parts", name, depth)
    path = folder / f"{name}.usdz"
    assert UsdUtils.CreateNewUsdzPackage(str(src), str(path))
    return path
