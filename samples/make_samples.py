"""Regenerate the project's own samples: ``python samples/make_samples.py``.

- cobbles.png: 256x192, 16-bit grey, tiling rounded cobbles with mortar grooves.
- bricks_height.png, bricks_color.png: 128x128 tiling bricks (height: white = high).
- brick_wall.gltf (+ .bin) and brick_wall.glb: a 2 m x 1 m wall, uvs repeating the
  bricks twice, its material's height in KHR_materials_displacement; written by pygltflib.
- brick_wall.obj + brick_wall.mtl: the same wall; the MTL names the height as ``disp``
  and a tangent-space normal map (bricks_normal.png) as ``map_Bump``, as Blender does.
- brick_wall.usda: the same wall (quads, faceVarying normals, vertex ``st``) bound to a
  UsdPreviewSurface whose displacement is a UsdUVTexture (bricks_height.png, ``outputs:r``,
  scale 0.03) reading ``st`` through a UsdPrimvarReader_float2; written with usd-core.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def cobbles(width=256, height=192, cells=(8, 6), seed=11) -> np.ndarray:
    """Tileable rounded stones: height 1 at a stone's centre, falling to the mortar."""
    rng = np.random.default_rng(seed)
    cx, cy = cells
    # one jittered site per cell, copied around so distances wrap
    sites = (np.stack(np.meshgrid(np.arange(cx), np.arange(cy)), -1).reshape(-1, 2)
             + 0.5 + rng.uniform(-0.3, 0.3, (cx * cy, 2))) / [cx, cy]
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    U, V = np.meshgrid(u, v)
    d = np.full((2, height, width), np.inf)
    for s in sites:
        du = np.abs(U - s[0]); du = np.minimum(du, 1 - du) * cx
        dv = np.abs(V - s[1]); dv = np.minimum(dv, 1 - dv) * cy
        dist = np.hypot(du, dv)
        d[1] = np.minimum(d[1], np.maximum(d[0], dist))
        d[0] = np.minimum(d[0], dist)
    edge = np.clip((d[1] - d[0]) * 2.5, 0, 1)   # 0 in the mortar, 1 inside a stone
    h = 0.15 + 0.8 * np.sqrt(edge) * (1 - 0.25 * d[0])
    return np.clip(h, 0, 1)


def bricks(size=128, rows=4, cols=2, mortar=0.06) -> np.ndarray:
    """Tileable running-bond bricks with bevelled edges, mortar at 0.1, faces near 0.9."""
    v = (np.arange(size) + 0.5) / size
    V, U = np.meshgrid(v, v, indexing="ij")
    row = np.floor(V * rows)
    fu = (U * cols + 0.5 * (row % 2)) % 1.0
    fv = (V * rows) % 1.0
    edge = np.minimum(np.minimum(fu, 1 - fu) * 2 / cols, np.minimum(fv, 1 - fv) / rows)
    bevel = np.clip((edge - mortar / rows) / 0.03, 0, 1)
    rng = np.random.default_rng(3)
    return np.clip(0.1 + 0.8 * bevel + 0.04 * rng.random((size, size)) * bevel, 0, 1)


def wall_gltf(folder: Path) -> None:
    """brick_wall.gltf/.bin and brick_wall.glb, written with pygltflib."""
    import pygltflib as g

    nx, ny = 4, 2
    xs, ys = np.meshgrid(np.linspace(-1, 1, nx + 1), np.linspace(0, 1, ny + 1))
    pos = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1).astype(np.float32)
    nrm = np.tile([0, 0, 1], (len(pos), 1)).astype(np.float32)
    uv = np.stack([(xs.ravel() + 1), 1 - ys.ravel()], 1).astype(np.float32)  # v down (glTF)
    quads = [(j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i)
             for j in range(ny) for i in range(nx)]
    idx = np.array([[a, b, c, a, c, d] for a, b, c, d in quads], np.uint16).ravel()
    blobs = [pos.tobytes(), nrm.tobytes(), uv.tobytes(), idx.tobytes()]
    offsets = np.cumsum([0] + [len(b) for b in blobs])
    blob = b"".join(blobs)
    doc = g.GLTF2(
        scene=0, scenes=[g.Scene(nodes=[0])], nodes=[g.Node(mesh=0, name="wall")],
        meshes=[g.Mesh(name="wall", primitives=[g.Primitive(
            attributes=g.Attributes(POSITION=0, NORMAL=1, TEXCOORD_0=2), indices=3, material=0)])],
        materials=[g.Material(name="bricks", pbrMetallicRoughness=g.PbrMetallicRoughness(
            baseColorTexture=g.TextureInfo(index=0), metallicFactor=0.0, roughnessFactor=0.8),
            extensions={"KHR_materials_displacement": {
                "displacementGeometryTexture": {"index": 1}, "displacementGeometryFactor": 0.03}})],
        textures=[g.Texture(source=0, sampler=0), g.Texture(source=1, sampler=0)],
        samplers=[g.Sampler(magFilter=9729, minFilter=9987, wrapS=10497, wrapT=10497)],
        images=[g.Image(uri="bricks_color.png"), g.Image(uri="bricks_height.png")],
        accessors=[
            g.Accessor(bufferView=0, componentType=5126, count=len(pos), type="VEC3",
                       min=pos.min(0).tolist(), max=pos.max(0).tolist()),
            g.Accessor(bufferView=1, componentType=5126, count=len(pos), type="VEC3"),
            g.Accessor(bufferView=2, componentType=5126, count=len(pos), type="VEC2"),
            g.Accessor(bufferView=3, componentType=5123, count=len(idx), type="SCALAR")],
        bufferViews=[g.BufferView(buffer=0, byteOffset=int(offsets[i]), byteLength=len(b),
                                  target=34963 if i == 3 else 34962) for i, b in enumerate(blobs)],
        buffers=[g.Buffer(byteLength=len(blob), uri="brick_wall.bin")],
        extensionsUsed=["KHR_materials_displacement"])
    (folder / "brick_wall.bin").write_bytes(blob)
    doc.save_json(str(folder / "brick_wall.gltf"))
    doc.buffers[0].uri = None
    doc.set_binary_blob(blob)
    for i, name in enumerate(["bricks_color.png", "bricks_height.png"]):
        data = (folder / name).read_bytes()
        doc.images[i] = g.Image(bufferView=len(doc.bufferViews), mimeType="image/png", name=Path(name).stem)
        doc.bufferViews.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data)))
        blob += data + b"\0" * (-len(data) % 4)
    doc.buffers[0].byteLength = len(blob)
    doc.set_binary_blob(blob)
    doc.save_binary(str(folder / "brick_wall.glb"))


def wall_grid(nx=4, ny=2):
    """The wall's vertices (x, y, 0), uvs (v up, OBJ style) and quads, row-major."""
    xs, ys = np.meshgrid(np.linspace(-1, 1, nx + 1), np.linspace(0, 1, ny + 1))
    pos = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    uv = np.stack([xs.ravel() + 1, ys.ravel()], 1)
    quads = [(j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i)
             for j in range(ny) for i in range(nx)]
    return pos, uv, quads


def normal_map(h: np.ndarray, strength=4.0) -> np.ndarray:
    """A tangent-space normal map (RGB, OpenGL convention) of tiling heights ``h``."""
    dx = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / 2 * strength
    dy = (np.roll(h, -1, 0) - np.roll(h, 1, 0)) / 2 * strength
    n = np.stack([-dx, dy, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.rint((n * 0.5 + 0.5) * 255).astype(np.uint8)


def wall_obj(folder: Path) -> None:
    pos, uv, quads = wall_grid()
    lines = ["# brick wall sample (csm-assets)", "mtllib brick_wall.mtl", "o wall"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in pos]
    lines += [f"vt {u:g} {v:g}" for u, v in uv]
    lines += ["vn 0 0 1", "usemtl bricks", "s off"]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}/1" for i in q) for q in quads]
    (folder / "brick_wall.obj").write_text("\n".join(lines) + "\n")
    (folder / "brick_wall.mtl").write_text("\n".join([
        "# brick wall sample (csm-assets)", "newmtl bricks", "Ka 0 0 0", "Kd 0.8 0.8 0.8",
        "Ks 0.1 0.1 0.1", "Ns 20", "map_Kd bricks_color.png", "map_Bump -bm 1 bricks_normal.png",
        "disp -mm 0 0.03 bricks_height.png", ""]))


def wall_usd(folder: Path) -> None:
    """brick_wall.usda, written with usd-core (pxr)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

    pos, uv, quads = wall_grid()
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    wall = UsdGeom.Mesh.Define(stage, "/World/wall")
    wall.CreatePointsAttr([Gf.Vec3f(*p) for p in pos])
    wall.CreateFaceVertexCountsAttr([4] * len(quads))
    wall.CreateFaceVertexIndicesAttr([i for q in quads for i in q])
    wall.CreateExtentAttr([Gf.Vec3f(*pos.min(0)), Gf.Vec3f(*pos.max(0))])
    wall.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    wall.CreateNormalsAttr([Gf.Vec3f(0, 0, 1)] * (4 * len(quads)))
    wall.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    UsdGeom.PrimvarsAPI(wall).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                            UsdGeom.Tokens.vertex).Set([Gf.Vec2f(*t) for t in uv])
    UsdGeom.Scope.Define(stage, "/World/Looks")
    mat = UsdShade.Material.Define(stage, "/World/Looks/bricks")
    frame = mat.CreateInput("frame:stPrimvarName", Sdf.ValueTypeNames.String)
    frame.Set("st")
    reader = UsdShade.Shader.Define(stage, "/World/Looks/bricks/stReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).ConnectToSource(frame)
    st_out = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    surface = UsdShade.Shader.Define(stage, "/World/Looks/bricks/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.8)
    textures = {}
    for name, file, out, typ in [("colorTex", "bricks_color.png", "rgb", Sdf.ValueTypeNames.Float3),
                                 ("heightTex", "bricks_height.png", "r", Sdf.ValueTypeNames.Float)]:
        tex = UsdShade.Shader.Define(stage, f"/World/Looks/bricks/{name}")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(f"./{file}")
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(st_out)
        for w in ("wrapS", "wrapT"):
            tex.CreateInput(w, Sdf.ValueTypeNames.Token).Set("repeat")
        textures[name] = tex.CreateOutput(out, typ)
    heights = UsdShade.Shader(stage.GetPrimAtPath("/World/Looks/bricks/heightTex"))
    heights.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
    heights.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(0.03, 0.03, 0.03, 1))
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(textures["colorTex"])
    surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(textures["heightTex"])
    mat.CreateSurfaceOutput().ConnectToSource(surface.CreateOutput("surface", Sdf.ValueTypeNames.Token))
    mat.CreateDisplacementOutput().ConnectToSource(surface.CreateOutput("displacement",
                                                                        Sdf.ValueTypeNames.Token))
    UsdShade.MaterialBindingAPI.Apply(wall.GetPrim()).Bind(mat)
    stage.GetRootLayer().Export(str(folder / "brick_wall.usda"))


def main() -> None:
    here = Path(__file__).resolve().parent
    Image.fromarray(np.rint(cobbles() * 65535).astype(np.uint16)).save(here / "cobbles.png")
    h = bricks()
    Image.fromarray(np.rint(h * 255).astype(np.uint8)).save(here / "bricks_height.png")
    tint = np.array([170, 74, 52]) / 255
    colour = np.clip(h[..., None] * tint + (1 - h[..., None]) * 0.55, 0, 1)
    Image.fromarray(np.rint(colour * 255).astype(np.uint8)).save(here / "bricks_color.png")
    Image.fromarray(normal_map(h)).save(here / "bricks_normal.png")
    wall_gltf(here)
    wall_obj(here)
    wall_usd(here)
    print(f"wrote samples in {here}")


if __name__ == "__main__":
    main()
