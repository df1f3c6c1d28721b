"""USD: heights through connection chains, geometry, tangents and the glslfx CSM shader out,
UsdValidation, .usdc and .usdz (textures inside the package), convert and the CLI."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdUtils, Vt

from csm_assets import load_heightfield, read_step_map, step_map
from csm_assets.convert.pipeline import ConvertOptions, convert, make_tangents
from csm_assets.formats import usd
from csm_assets.render.glsl import shader_path
from csm_assets.scene import CsmSettings
from csm_assets.stepmap import StepMapSettings
from csm_assets.tangents.frames import mikktspace_tangents
from usd_stages import edit, validation_errors, wall_folder

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
MAT = "/World/Looks/bricks"


@pytest.fixture
def wall(tmp_path):
    return wall_folder(tmp_path)


def by_hand(scene, out: Path, tile=(True, True)) -> list[Path]:
    """What convert() does, without computing a step map: a PNG stands in for it."""
    step = out / "bricks_height_csm.png"
    shutil.copy(SAMPLES / "bricks_height.png", step)
    for mat in scene.materials:
        if mat.height is not None:
            mat.csm = CsmSettings(step, 0.05, StepMapSettings(tile=tile, levels="none"), steps=12,  # a stand-in
                                  variant="loop")
    make_tangents(scene, ConvertOptions())
    return usd.write(scene, out)


# ------------------------------------------------------------------ reading

def test_reads_the_sample_wall(wall):
    scene = usd.read(wall / "brick_wall.usda")
    assert scene.format == "usda" and scene.warnings == []
    (mat,) = scene.materials
    h = mat.height
    assert (mat.name, mat.ref, h.origin) == ("bricks", MAT, "UsdPreviewSurface displacement")
    assert (h.scale, h.offset, h.channel, h.tile) == (pytest.approx(0.03), 0.0, 0, (True, True))
    assert h.texture.path == wall / "bricks_height.png"
    (mesh,) = scene.meshes
    assert mesh.uv_origin == "bottom-left"
    assert mesh.positions.shape == (15, 3) and mesh.faces.shape == (16, 3)  # 8 quads, welded
    np.testing.assert_allclose(mesh.uvs, np.column_stack([mesh.positions[:, 0] + 1, mesh.positions[:, 1]]))
    np.testing.assert_allclose(mesh.normals, np.tile([0, 0, 1], (15, 1)))
    p = mesh.positions[mesh.faces]
    area = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (area[:, 2] > 0).all() and area[:, 2].sum() / 2 == pytest.approx(2.0)  # counter-clockwise


def _through_nodegraph(stage):
    """displacement <- NodeGraph output <- texture inside it; the file comes from a
    material interface input, the scale from a NodeGraph interface input."""
    mat = UsdShade.Material.Get(stage, MAT)
    ps = UsdShade.Shader.Get(stage, f"{MAT}/PreviewSurface")
    ng = UsdShade.NodeGraph.Define(stage, f"{MAT}/Relief")
    tex = UsdShade.Shader.Define(stage, f"{MAT}/Relief/tex")
    tex.CreateIdAttr("UsdUVTexture")
    file_in = mat.CreateInput("heightFile", Sdf.ValueTypeNames.Asset)
    file_in.Set("./bricks_height.png")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).ConnectToSource(file_in)
    scale = ng.CreateInput("scale", Sdf.ValueTypeNames.Float4)
    scale.Set(Gf.Vec4f(0.5, 0.07, 0.5, 0.5))
    tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).ConnectToSource(scale)
    tex.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(0, -0.01, 0, 0))
    out = ng.CreateOutput("height", Sdf.ValueTypeNames.Float)
    out.ConnectToSource(tex.CreateOutput("g", Sdf.ValueTypeNames.Float))
    ps.GetInput("displacement").ConnectToSource(out)


def _through_transform2d(stage):
    """st: texture <- UsdTransform2d <- primvar reader of 'uv' (varname a plain value)."""
    mesh = UsdGeom.Mesh.Get(stage, "/World/wall")
    pv = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("uv", Sdf.ValueTypeNames.TexCoord2fArray,
                                            UsdGeom.Tokens.vertex).Set(pv.Get())
    pv.Set(Vt.Vec2fArray([Gf.Vec2f(0, 0)] * 15))  # st now would give zero-area uvs
    reader = UsdShade.Shader.Define(stage, f"{MAT}/uvReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("uv")
    xf = UsdShade.Shader.Define(stage, f"{MAT}/xf")
    xf.CreateIdAttr("UsdTransform2d")
    xf.CreateInput("in", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.CreateOutput("result", Sdf.ValueTypeNames.Float2))
    tex = UsdShade.Shader.Get(stage, f"{MAT}/heightTex")
    tex.GetInput("st").ConnectToSource(xf.CreateOutput("result", Sdf.ValueTypeNames.Float2))


def _displacement_terminal_only(stage):
    """No surface terminal: the preview surface is found through outputs:displacement."""
    mat = UsdShade.Material.Get(stage, MAT)
    mat.GetSurfaceOutput().GetAttr().GetPrim().RemoveProperty("outputs:surface")


@pytest.mark.parametrize("change, channel, scale, offset, primvar", [
    (_through_nodegraph, 1, 0.07, -0.01, "st"),
    (_through_transform2d, 0, 0.03, 0.0, "uv"),
    (_displacement_terminal_only, 0, 0.03, 0.0, "st"),
])
def test_connection_chains(wall, change, channel, scale, offset, primvar):
    scene = usd.read(edit(wall / "brick_wall.usda", change))
    assert scene.warnings == []
    h = scene.materials[0].height
    assert (h.channel, h.scale, h.offset) == (channel, pytest.approx(scale), pytest.approx(offset))
    assert h.texture.path == wall / "bricks_height.png"
    (mesh,) = scene.meshes
    assert np.ptp(mesh.uvs[:, 0]) == pytest.approx(2.0)  # the uvs of the primvar the chain names


def test_connection_cycle_is_refused_with_a_warning(wall):
    def cycle(stage):
        mat = UsdShade.Material.Get(stage, MAT)
        a = mat.CreateInput("a", Sdf.ValueTypeNames.Float)
        b = mat.CreateInput("b", Sdf.ValueTypeNames.Float)
        a.ConnectToSource(b)
        b.ConnectToSource(a)
        UsdShade.Shader.Get(stage, f"{MAT}/PreviewSurface").GetInput("displacement").ConnectToSource(a)

    scene = usd.read(edit(wall / "brick_wall.usda", cycle))
    assert scene.materials[0].height is None and scene.meshes == []
    assert any(f"'{MAT}'" in w and "cycle" in w and "inputs:" in w for w in map(str, scene.warnings)), scene.warnings


def _add_second_wall(stage, name: str, height_file: str | None):
    """Another material and a mesh bound to it (a copy of the wall's)."""
    src = Sdf.Path(MAT)
    layer = stage.GetRootLayer()
    Sdf.CopySpec(layer, src, layer, src.GetParentPath().AppendChild(name))
    Sdf.CopySpec(layer, "/World/wall", layer, f"/World/{name}Wall")
    new = UsdShade.Material.Get(stage, f"/World/Looks/{name}")
    UsdShade.MaterialBindingAPI(stage.GetPrimAtPath(f"/World/{name}Wall")).Bind(new)
    tex = UsdShade.Shader.Get(stage, f"/World/Looks/{name}/heightTex")
    if height_file is None:
        UsdShade.Shader.Get(stage, f"/World/Looks/{name}/PreviewSurface").GetInput(
            "displacement").GetAttr().ClearConnections()
    else:
        tex.GetInput("file").Set(height_file)


def test_missing_texture_warns_and_the_rest_converts(wall):
    scene = usd.read(edit(wall / "brick_wall.usda", lambda s: _add_second_wall(s, "lost", "./gone.png")))
    by_name = {m.name: m for m in scene.materials}
    assert by_name["bricks"].height is not None and by_name["lost"].height is None
    assert any("'/World/Looks/lost'" in w and "gone.png" in w for w in map(str, scene.warnings))
    assert [m.name for m in scene.meshes] == ["/World/wall"]
    # one warning for the missing height texture (CSM101, as glTF and OBJ say it), not a CSM404 beside it
    assert [n.code for n in scene.warnings if "gone.png" in n.text] == ["CSM101"], scene.warnings


def test_missing_other_asset_still_warns_csm404(wall):
    def other(stage):
        _add_second_wall(stage, "lost", "./gone.png")
        tex = UsdShade.Shader.Define(stage, "/World/Looks/bricks/colorTex")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./no_color.png")

    scene = usd.read(edit(wall / "brick_wall.usda", other))
    codes = [(n.code, "gone.png" in n.text) for n in scene.warnings if "gone.png" in n.text or "no_color" in n.text]
    assert sorted(codes) == [("CSM101", True), ("CSM404", False)], scene.warnings


def test_material_without_height_loads_no_geometry(wall):
    scene = usd.read(edit(wall / "brick_wall.usda", lambda s: _add_second_wall(s, "plain", None)))
    assert {m.name: m.height is None for m in scene.materials} == {"bricks": False, "plain": True}
    assert [m.name for m in scene.meshes] == ["/World/wall"] and scene.warnings == []


def test_mesh_without_the_uv_primvar_warns(wall):
    scene = usd.read(edit(wall / "brick_wall.usda", lambda s: s.GetPrimAtPath("/World/wall").RemoveProperty(
        "primvars:st")))
    assert scene.meshes == []
    assert any(f"'{MAT}'" in w and "primvars:st" in w and "/World/wall" in w for w in map(str, scene.warnings))


@pytest.mark.parametrize("subset_gets_heights", [False, True])
def test_geom_subsets_bound_to_materials(wall, tmp_path, subset_gets_heights):
    """Faces 0, 1, 4, 5 (the left half) in a materialBind subset; the mesh keeps the rest."""
    def subsets(stage):
        _add_second_wall(stage, "plain", None)
        stage.RemovePrim("/World/plainWall")
        mesh = stage.GetPrimAtPath("/World/wall")
        api = UsdShade.MaterialBindingAPI(mesh)
        left = api.CreateMaterialBindSubset("left", Vt.IntArray([0, 1, 4, 5]))
        UsdShade.MaterialBindingAPI.Apply(left.GetPrim())
        plain, bricks = UsdShade.Material.Get(stage, "/World/Looks/plain"), UsdShade.Material.Get(stage, MAT)
        UsdShade.MaterialBindingAPI(left.GetPrim()).Bind(bricks if subset_gets_heights else plain)
        api.Bind(plain if subset_gets_heights else bricks)

    scene = usd.read(edit(wall / "brick_wall.usda", subsets))
    (mesh,) = scene.meshes
    assert mesh.name == ("/World/wall/left" if subset_gets_heights else "/World/wall")
    assert mesh.faces.shape == (8, 3)
    left = mesh.positions[mesh.faces].mean(1)[:, 0] < 0
    assert (left if subset_gets_heights else ~left).all()
    out = tmp_path / "out"
    out.mkdir()
    by_hand(scene, out)
    stage = Usd.Stage.Open(str(out / "brick_wall.usda"))
    w = np.array(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall")).GetPrimvar("tangentSigns").Get())
    assert len(w) == 32 and (w == 1).all()
    assert validation_errors(out / "brick_wall.usda") == []


def test_height_override_by_material_name(wall):
    scene = usd.read(wall / "brick_wall.usda", heights={"bricks": wall / "bricks_color.png"})
    h = scene.materials[0].height
    assert h.origin == "command line" and h.texture.path == wall / "bricks_color.png"
    assert len(scene.meshes) == 1


# ------------------------------------------------------------------ geometry and tangents

def bumpy_mesh(stage, path="/World/wall", left_handed=False, face_varying=False):
    """Replace the wall by a curved sheet of triangles, quads and a pentagon, with uvs
    mirrored in its right half; orientation as asked; normals and st per vertex, or
    faceVarying (st then indexed)."""
    nx, ny = 6, 4
    xs, ys = np.meshgrid(np.linspace(-1, 1, nx + 1), np.linspace(0, 1, ny + 1))
    z = 0.3 * np.sin(2.5 * xs) * np.cos(2 * ys)
    pts = np.stack([xs.ravel(), ys.ravel(), z.ravel()], 1)
    u = np.abs(xs.ravel())  # mirrored at x = 0
    uv = np.stack([u, ys.ravel() * 1.3], 1)
    counts, idx = [], []
    for j in range(ny):
        for i in range(nx):
            a, b = j * (nx + 1) + i, j * (nx + 1) + i + 1
            c, d = b + nx + 1, a + nx + 1
            if (i + j) % 3 == 0:
                counts += [3, 3]
                idx += [a, b, c, a, c, d]
            else:
                counts.append(4)
                idx += [a, b, c, d]
    counts.append(5)  # a pentagon below the sheet
    base = len(pts)
    ang = np.linspace(0, 2 * np.pi, 6)[:-1]
    pts = np.vstack([pts, np.stack([0.3 * np.cos(ang), -0.5 + 0.3 * np.sin(ang), np.zeros(5)], 1)])
    uv = np.vstack([uv, np.stack([0.5 + 0.5 * np.cos(ang), 0.5 + 0.5 * np.sin(ang)], 1)])
    idx += list(range(base, base + 5))
    # vertex normals: the surface gradient (the pentagon faces +z)
    nrm = np.stack([-0.3 * 2.5 * np.cos(2.5 * xs) * np.cos(2 * ys), 0.3 * 2 * np.sin(2.5 * xs) * np.sin(2 * ys),
                    np.ones_like(xs)], -1).reshape(-1, 3)
    nrm = np.vstack([nrm, np.tile([0, 0, 1.0], (5, 1))])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    idx = np.array(idx)
    if left_handed:  # same surface, corners listed the other way round
        starts = np.cumsum(counts) - counts
        idx = np.concatenate([idx[s:s + c][::-1] for s, c in zip(starts, counts)])
        nrm = nrm  # normals stay: leftHanded keeps the same front face
    mesh = UsdGeom.Mesh.Get(stage, path)
    mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray(counts))
    mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(idx.astype(np.int32)))
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    st.Set(Vt.Vec2fArray.FromNumpy(uv.astype(np.float32)))
    if face_varying:
        nrm = nrm[idx]
        st.SetInterpolation(UsdGeom.Tokens.faceVarying)
        st.SetIndices(Vt.IntArray.FromNumpy(idx.astype(np.int32)))
    mesh.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(nrm.astype(np.float32)))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying if face_varying else UsdGeom.Tokens.vertex)
    if left_handed:
        mesh.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)


def fan_reference(path: Path, prim="/World/wall"):
    """Independently of the reader: per-corner positions, normals, uvs of the fan
    triangulation (right-handed order), and the face-vertex index of each corner."""
    stage = Usd.Stage.Open(str(path))
    mesh = UsdGeom.Mesh.Get(stage, prim)
    pts = np.array(mesh.GetPointsAttr().Get())
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    nrm = np.array(mesh.GetNormalsAttr().Get())
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    uv = np.array(st.Get())
    face_varying = mesh.GetNormalsInterpolation() == UsdGeom.Tokens.faceVarying
    left = mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded
    fv, s = [], 0
    for c in counts:
        for k in range(1, c - 1):
            tri = [s, s + k, s + k + 1]
            fv.append([tri[0], tri[2], tri[1]] if left else tri)
        s += c
    fv = np.array(fv)
    v = idx[fv]
    if face_varying:
        return pts[v], nrm[fv], uv[np.array(st.GetIndices())[fv]], fv
    return pts[v], nrm[v], uv[v], fv


@pytest.mark.parametrize("left_handed, face_varying", [(False, False), (True, False), (False, True)])
def test_round_trip_tangents_match_mikktspace(wall, tmp_path, left_handed, face_varying):
    src = edit(wall / "brick_wall.usda", lambda s: bumpy_mesh(s, left_handed=left_handed,
                                                              face_varying=face_varying))
    scene = usd.read(src)
    out = tmp_path / "out"
    out.mkdir()
    by_hand(scene, out)
    p, n, uv, fv = fan_reference(src)
    expected = mikktspace_tangents(p.reshape(-1, 3), n.reshape(-1, 3), uv.reshape(-1, 2))
    back = Usd.Stage.Open(str(out / "brick_wall.usda"))
    api = UsdGeom.PrimvarsAPI(back.GetPrimAtPath("/World/wall"))
    tan, sign = api.GetPrimvar("tangents"), api.GetPrimvar("tangentSigns")
    assert tan.GetInterpolation() == sign.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert tan.GetTypeName() == Sdf.ValueTypeNames.Float3Array
    t, w = np.array(tan.Get()), np.array(sign.Get())
    assert len(t) == len(w) == len(Usd.Stage.Open(str(src)).GetPrimAtPath("/World/wall").GetAttribute(
        "faceVertexIndices").Get())
    # every face-vertex holds the tangent of the first fan triangle that uses it
    flat_fv = fv.reshape(-1)
    _, first = np.unique(flat_fv, return_index=True)
    want = expected.reshape(-1, 4)[first]
    np.testing.assert_allclose(t[flat_fv[first]], want[:, :3], atol=1e-5)
    np.testing.assert_array_equal(w[flat_fv[first]], want[:, 3])
    assert set(np.unique(w)) == {-1.0, 1.0}  # the mirrored half flips handedness
    # and the reader hands the same frames to the writer: what convert computes is MikkTSpace
    np.testing.assert_allclose(scene.meshes[0].corner_tangents[:, :, :3], expected[..., :3], atol=1e-5)


def test_written_material_keeps_preview_surface_and_gains_glslfx_shader(wall, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    written = by_hand(usd.read(wall / "brick_wall.usda"), out, tile=(True, False))
    assert sorted(p.name for p in written) == ["brick_wall.usda", "bricks_color.png", "bricks_height.png",
                                               "csm.glslfx"]
    stage = Usd.Stage.Open(str(out / "brick_wall.usda"))
    mat = UsdShade.Material.Get(stage, MAT)
    fallback = mat.ComputeSurfaceSource()[0]
    assert fallback.GetShaderId() == "UsdPreviewSurface"
    assert fallback.GetInput("displacement").HasConnectedSource()
    csm = mat.ComputeSurfaceSource("glslfx")[0]
    assert csm.GetPath() == Sdf.Path(f"{MAT}/CsmSurface") and csm.GetShaderId() == usd.SHADER_ID
    assert csm.GetPrim().GetAttribute("info:glslfx:sourceAsset").Get().resolvedPath == str(out / "csm.glslfx")
    inputs = {i.GetBaseName(): i.Get() for i in csm.GetInputs()}
    assert inputs["stepMap"].resolvedPath == str(out / "bricks_height_csm.png")
    assert (inputs["depthScale"], inputs["maxRatio"], inputs["steps"], inputs["variant"]) == (
        pytest.approx(0.05), 1.0, 12, "loop")
    assert (inputs["tileU"], inputs["tileV"]) == (1, 0)
    assert (out / "csm.glslfx").read_text() == shader_path("csm.glslfx").read_text()
    # every asset resolves inside out_dir
    for prim in stage.Traverse():
        for attr in prim.GetAttributes():
            if attr.GetTypeName() == Sdf.ValueTypeNames.Asset and attr.HasAuthoredValue():
                assert Path(attr.Get().resolvedPath).parent == out, attr.GetPath()
    assert stage.GetMetadata("upAxis") == "Y" and stage.GetMetadata("metersPerUnit") == 1
    assert str(wall) not in (out / "brick_wall.usda").read_text()  # no input path leaks into the output


def test_output_passes_usd_validation(wall, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    by_hand(usd.read(wall / "brick_wall.usda"), out)
    assert validation_errors(wall / "brick_wall.usda") == []  # the sample itself
    assert validation_errors(out / "brick_wall.usda") == []


def test_usdc_in_usdc_out(wall, tmp_path):
    Sdf.Layer.FindOrOpen(str(wall / "brick_wall.usda")).Export(str(wall / "wall.usdc"))
    scene = usd.read(wall / "wall.usdc")
    assert scene.format == "usdc" and len(scene.meshes) == 1
    out = tmp_path / "out"
    out.mkdir()
    by_hand(scene, out)
    assert Sdf.FileFormat.FindByExtension("usdc").CanRead(str(out / "wall.usdc"))
    assert (out / "wall.usdc").read_bytes()[:8] == b"PXR-USDC"
    assert UsdGeom.PrimvarsAPI(Usd.Stage.Open(str(out / "wall.usdc")).GetPrimAtPath("/World/wall")).HasPrimvar(
        "tangents")


@pytest.fixture
def packaged(wall):
    """The sample as a .usdz with its textures inside (the loose copies removed)."""
    pkg = wall / "wall.usdz"
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(wall / "brick_wall.usda")), str(pkg))
    for name in ["brick_wall.usda", "bricks_color.png", "bricks_height.png"]:
        (wall / name).unlink()
    return pkg


def test_usdz_textures_come_from_the_package(packaged, tmp_path):
    scene = usd.read(packaged)
    assert scene.warnings == []
    tex = scene.materials[0].height.texture
    assert tex.path is None and tex.data == (SAMPLES / "bricks_height.png").read_bytes()
    out = tmp_path / "out"
    out.mkdir()
    assert [p.name for p in by_hand(scene, out)] == ["wall.usdz"]
    with zipfile.ZipFile(out / "wall.usdz") as z:
        names = z.namelist()
        assert names[0].endswith(".usdc")  # the root layer comes first
        assert set(names[1:]) == {"bricks_color.png", "bricks_height.png", "bricks_height_csm.png"}
        assert all(i.compress_type == zipfile.ZIP_STORED for i in z.infolist())
    back = usd.read(out / "wall.usdz")
    assert back.materials[0].height.texture.data == tex.data
    stage = Usd.Stage.Open(str(out / "wall.usdz"))
    assert UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall")).HasPrimvar("tangents")
    csm = UsdShade.Material.Get(stage, MAT).ComputeSurfaceSource("glslfx")[0]
    assert csm.GetShaderId() == usd.SHADER_ID  # by id only: a usdz may not hold a .glslfx
    assert not csm.GetPrim().HasAttribute("info:glslfx:sourceAsset")
    assert validation_errors(out / "wall.usdz") == []


# ------------------------------------------------------------------ the shipped shader files

def test_shipped_glslfx_is_the_projects_glsl():
    text = shader_path("csm.glslfx").read_text()
    assert text == usd.build_glslfx()
    assert text.startswith("-- glslfx version 0.1\n")
    config = text.split("-- configuration\n", 1)[1].split("\n-- glsl ", 1)[0]
    parsed = json.loads(config)
    assert set(parsed["parameters"]) == set(usd.GLSLFX_PARAMETERS) and "stepMap" in parsed["textures"]
    for section in ("CSM.Intersect", "CSM.Vertex", "CSM.Fragment"):
        assert f"\n-- glsl {section}\n" in text


def test_shader_definition_matches_the_written_inputs():
    usd.register_shader_definitions()
    usd.register_shader_definitions()  # idempotent
    from pxr import Sdr

    node = Sdr.Registry().GetShaderNodeByIdentifierAndType(usd.SHADER_ID, "glslfx")
    assert node.GetResolvedImplementationURI() == str(shader_path("csm.glslfx"))
    assert set(node.GetShaderInputNames()) == set(usd.GLSLFX_PARAMETERS) | {"stepMap", "stepMap2", "stepMapLevels",
                                                                           "stepMap2Levels", "variant"}
    assert list(node.GetShaderOutputNames()) == ["surface"]


# ------------------------------------------------------------------ end to end

def test_convert_the_sample_wall(wall, tmp_path):
    before = {p.name: p.read_bytes() for p in wall.iterdir()}
    out = tmp_path / "out"
    report = convert(wall / "brick_wall.usda", out)
    assert {p.name: p.read_bytes() for p in wall.iterdir()} == before  # inputs untouched
    assert report.warnings == [] and report.tangent_meshes == ["/World/wall"]
    expected = step_map(load_heightfield(SAMPLES / "bricks_height.png").exact_heights(), bilinear_safe=True)
    np.testing.assert_array_equal(read_step_map(out / "bricks_height_csm.png"), expected)
    stage = Usd.Stage.Open(str(out / "brick_wall.usda"))
    csm = UsdShade.Material.Get(stage, MAT).ComputeSurfaceSource("glslfx")[0]
    assert csm.GetInput("depthScale").Get() == pytest.approx(0.03)  # 2 m x 1 m over 2 x 1 uv
    t = np.array(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall")).GetPrimvar("tangents").Get())
    np.testing.assert_allclose(t, np.tile([1, 0, 0], (32, 1)), atol=1e-6)
    assert validation_errors(out / "brick_wall.usda") == []


def test_unreadable_texture_warns_and_the_rest_converts(wall, tmp_path):
    edit(wall / "brick_wall.usda", lambda s: _add_second_wall(s, "broken", "./broken.png"))
    (wall / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n not really")
    report = convert(wall / "brick_wall.usda", tmp_path / "out")
    assert any("'broken'" in w and "broken.png" in w for w in map(str, report.warnings)), report.warnings
    assert report.tangent_meshes == ["/World/wall"]
    stage = Usd.Stage.Open(str(tmp_path / "out" / "brick_wall.usda"))
    broken = UsdShade.Material.Get(stage, "/World/Looks/broken")
    assert broken.ComputeSurfaceSource("glslfx")[0].GetShaderId() == "UsdPreviewSurface"  # the fallback
    assert not broken.GetPrim().GetChild("CsmSurface")
    assert not UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/brokenWall")).HasPrimvar("tangents")
    assert validation_errors(tmp_path / "out" / "brick_wall.usda") == []


def test_cli_converts_usdz(packaged, tmp_path):
    before = packaged.read_bytes()
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(packaged), "-o", str(tmp_path / "o"),
                        "--json", "--depth", "0.2"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (rep,) = json.loads(r.stdout)["results"]
    assert rep["status"] == "converted" and str(tmp_path / "o" / "bricks_height_csm.png") in rep["written"]
    stage = Usd.Stage.Open(str(tmp_path / "o" / "wall.usdz"))
    csm = UsdShade.Material.Get(stage, MAT).ComputeSurfaceSource("glslfx")[0]
    assert csm.GetInput("depthScale").Get() == pytest.approx(0.2)
    assert csm.GetInput("stepMap").Get().resolvedPath.endswith("wall.usdz[bricks_height_csm.png]")
    assert packaged.read_bytes() == before


def test_cli_help_names_usd():
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", "--help"], capture_output=True,
                       text=True, timeout=60)
    assert ".usda" in r.stdout and ".usdc" in r.stdout and ".usdz" in r.stdout


@pytest.mark.parametrize("name, data", [("bad.usda", b"#usda 1.0\ndef Mesh \"x\" {\n  float3[] points = [(\n"),
                                         ("bad.usdc", b"PXR-USDC but not really"),
                                         ("bad.usdz", b"PK\x03\x04 broken")])
def test_malformed_files_raise_format_errors(tmp_path, name, data):
    from csm_assets import FormatError

    (tmp_path / name).write_bytes(data)
    with pytest.raises(FormatError, match=name):
        usd.read(tmp_path / name)
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(tmp_path / name), "-o",
                        str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 3 and name in r.stderr


@pytest.mark.parametrize("regenerate", [False, True])
def test_existing_tangents_are_kept_unless_regenerated(wall, tmp_path, regenerate):
    def tangents(stage):
        api = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall"))
        t = api.CreatePrimvar("tangents", Sdf.ValueTypeNames.Float3Array, UsdGeom.Tokens.vertex)
        t.Set(Vt.Vec3fArray([Gf.Vec3f(0, 1, 0)] * 15))
        api.CreatePrimvar("tangentSigns", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant).Set(
            Vt.FloatArray([-1.0]))

    scene = usd.read(edit(wall / "brick_wall.usda", tangents))
    np.testing.assert_array_equal(scene.meshes[0].tangents, np.tile([0, 1, 0, -1], (15, 1)))
    report = convert(wall / "brick_wall.usda", tmp_path / "out", regenerate_tangents=regenerate)
    assert report.tangent_meshes == (["/World/wall"] if regenerate else [])
    stage = Usd.Stage.Open(str(tmp_path / "out" / "brick_wall.usda"))
    api = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall"))
    t, w = api.GetPrimvar("tangents"), api.GetPrimvar("tangentSigns")
    if regenerate:
        assert t.GetInterpolation() == w.GetInterpolation() == UsdGeom.Tokens.faceVarying
        np.testing.assert_allclose(np.array(t.Get()), np.tile([1, 0, 0], (32, 1)), atol=1e-6)
        assert (np.array(w.Get()) == 1).all()
    else:  # as the file had them
        assert t.GetInterpolation() == UsdGeom.Tokens.vertex and list(w.Get()) == [-1.0]


@pytest.mark.parametrize("asset", ["../outside.png", "/etc/passwd"])
def test_assets_escaping_the_scene_are_refused(tmp_path, asset):
    from csm_assets import FormatError

    (tmp_path / "outside.png").write_bytes((SAMPLES / "bricks_height.png").read_bytes())
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    text = (SAMPLES / "brick_wall.usda").read_text().replace("./bricks_height.png", asset)
    assert text != (SAMPLES / "brick_wall.usda").read_text()
    (scene_dir / "wall.usda").write_text(text)
    for name in ["bricks_color.png", "bricks_height.png"]:
        shutil.copy(SAMPLES / name, scene_dir / name)
    with pytest.raises(FormatError, match="refused"):
        usd.read(scene_dir / "wall.usda")
