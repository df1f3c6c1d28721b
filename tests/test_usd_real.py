"""USD as exporters write it (made here with pxr): tangents as Unity (float4, vertex) and
Omniverse-style tools (float3, faceVarying, indexed, with bitangents) store them, a
MaterialX ``.mtlx`` reference that usd-core cannot read, and a payload structure."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from attack import Attack, assert_clean_run, run_cli
from csm_assets.convert.pipeline import convert
from csm_assets.formats import usd
from usd_stages import edit, validation_errors, wall_folder

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
WALL = "/World/wall"


@pytest.fixture
def wall(tmp_path):
    return wall_folder(tmp_path) / "brick_wall.usda"


def primvar(path: Path, name: str):
    stage = Usd.Stage.Open(str(path))
    pv = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(WALL)).GetPrimvar(name)
    return (str(pv.GetTypeName()), str(pv.GetInterpolation()), pv.IsIndexed(),
            None if not pv.HasValue() else np.array(pv.ComputeFlattened(), np.float64))


# ------------------------------------------------------------------ tangents of any form

def _tangents(kind: str, interpolation: str, indexed: bool, sign: float = -1.0):
    """Tangents (0, 1, 0) with handedness ``sign`` in the given form."""
    n = {"vertex": 15, "faceVarying": 32, "uniform": 8, "constant": 1}[interpolation]

    def change(stage):
        api = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(WALL))
        count = 1 if indexed else n
        if kind == "float4":
            pv = api.CreatePrimvar("tangents", Sdf.ValueTypeNames.Float4Array, interpolation)
            pv.Set(Vt.Vec4fArray([Gf.Vec4f(0, 1, 0, sign)] * count))
        else:
            pv = api.CreatePrimvar("tangents", Sdf.ValueTypeNames.Float3Array, interpolation)
            pv.Set(Vt.Vec3fArray([Gf.Vec3f(0, 1, 0)] * count))
            if kind == "float3+signs":
                api.CreatePrimvar("tangentSigns", Sdf.ValueTypeNames.FloatArray, interpolation).Set(
                    Vt.FloatArray([sign] * n))
            elif kind == "float3+bitangents":  # normal (0, 0, 1) x tangent (0, 1, 0) = (-1, 0, 0)
                api.CreatePrimvar("bitangents", Sdf.ValueTypeNames.Float3Array, interpolation).Set(
                    Vt.Vec3fArray([Gf.Vec3f(-sign, 0, 0)] * n))
        if indexed:
            pv.SetIndices(Vt.IntArray([0] * n))
    return change


FORMS = [("float4", "vertex", False), ("float4", "faceVarying", True), ("float3+signs", "faceVarying", False),
         ("float3+signs", "uniform", True), ("float3+bitangents", "vertex", False),
         ("float3", "constant", False), ("float4", "constant", True)]


@pytest.mark.parametrize("kind, interpolation, indexed", FORMS)
def test_existing_tangents_of_any_form_are_read(wall, kind, interpolation, indexed):
    scene = usd.read(edit(wall, _tangents(kind, interpolation, indexed)))
    assert scene.warnings == []
    sign = 1.0 if kind == "float3" else -1.0
    np.testing.assert_array_equal(scene.meshes[0].tangents, np.tile([0, 1, 0, sign], (15, 1)))


@pytest.mark.parametrize("kind, interpolation, indexed", FORMS)
def test_existing_tangents_are_kept_or_replaced_in_their_own_form(wall, tmp_path, kind, interpolation, indexed):
    edit(wall, _tangents(kind, interpolation, indexed))
    before = primvar(wall, "tangents")
    kept = tmp_path / "kept"
    convert(wall, kept)
    after = primvar(kept / wall.name, "tangents")
    assert after[:3] == before[:3]
    np.testing.assert_array_equal(after[3], before[3])
    redone = tmp_path / "redone"
    convert(wall, redone, regenerate_tangents=True)
    out = redone / wall.name
    t = primvar(out, "tangents")
    assert t[:3] == ("float4[]" if kind == "float4" else "float3[]", "faceVarying", False)
    np.testing.assert_allclose(t[3][:, :3], np.tile([1, 0, 0], (32, 1)), atol=1e-6)
    if kind == "float4":
        assert (t[3][:, 3] == 1).all()
    else:
        s = primvar(out, "tangentSigns")
        assert s[:3] == ("float[]", "faceVarying", False) and (s[3] == 1).all()
    if kind == "float3+bitangents":  # rewritten to match: cross(n, t) * sign = (0, 1, 0)
        b = primvar(out, "bitangents")
        assert b[1] == "faceVarying"
        np.testing.assert_allclose(b[3], np.tile([0, 1, 0], (32, 1)), atol=1e-6)
    assert validation_errors(out) == []


def test_tangents_that_do_not_fit_are_replaced(wall, tmp_path):
    def change(stage):
        api = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(WALL))
        api.CreatePrimvar("tangents", Sdf.ValueTypeNames.Float3Array, "vertex").Set(
            Vt.Vec3fArray([Gf.Vec3f(0, 1, 0)] * 4))  # 15 points
    scene = usd.read(edit(wall, change))
    assert scene.meshes[0].tangents is None
    assert any("do not fit" in w for w in map(str, scene.warnings))


# ------------------------------------------------------------------ MaterialX and payloads

MTLX = """<?xml version="1.0"?>
<materialx version="1.38" fileprefix="./tex/">
  <nodegraph name="NG">
    <image name="base" type="color3"><input name="file" type="filename" value="bricks_color.png" /></image>
    <image name="gone" type="float"><input name="file" type="filename" value="missing.png" /></image>
  </nodegraph>
  <surfacematerial name="Brick" type="material" />
</materialx>
"""


def _with_mtlx(stage):
    """A Scope referencing a MaterialX document; a second wall bound to its material."""
    stage.DefinePrim("/World/MaterialX", "Scope").GetReferences().AddReference("./brick.mtlx", "/MaterialX")
    other = UsdGeom.Mesh.Define(stage, "/World/other")
    other.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0)])
    other.CreateFaceVertexCountsAttr([3])
    other.CreateFaceVertexIndicesAttr([0, 1, 2])
    UsdShade.MaterialBindingAPI.Apply(other.GetPrim()).GetDirectBindingRel().SetTargets(
        [Sdf.Path("/World/MaterialX/Materials/Brick")])


def test_mtlx_reference_is_kept_and_copied_and_its_material_counted_unresolved(wall):
    (wall.parent / "tex").mkdir()
    shutil.copy(SAMPLES / "bricks_color.png", wall.parent / "tex" / "bricks_color.png")
    (wall.parent / "brick.mtlx").write_text(MTLX)
    edit(wall, _with_mtlx)
    out = wall.parent.parent / "out"
    with Attack(wall.parent):
        r = run_cli("convert", wall, "-o", out)
    warnings = assert_clean_run(r)
    unresolved = [w for w in warnings if "brick.mtlx" in w and "unresolved" in w]
    assert len(unresolved) == 1 and "/World/MaterialX/Materials/Brick" in unresolved[0], warnings
    assert any("missing.png" in w for w in warnings), warnings
    assert (out / "bricks_height_csm.png").is_file()  # the rest converted
    layer = Sdf.Layer.FindOrOpen(str(out / wall.name))
    refs = layer.GetPrimAtPath("/World/MaterialX").referenceList.prependedItems
    assert [(r.assetPath, str(r.primPath)) for r in refs] == [("./brick.mtlx", "/MaterialX")]
    doc = ET.parse(out / "brick.mtlx").getroot()
    values = [e.get("value") for e in doc.iter("input")]
    assert values[0] != "bricks_color.png" and (out / values[0]).read_bytes() == (SAMPLES / "bricks_color.png").read_bytes()
    assert values[1] == "./tex/missing.png" and doc.get("fileprefix") is None


def test_mtlx_naming_a_file_outside_is_refused(wall):
    (wall.parent / "brick.mtlx").write_text(MTLX.replace("./tex/", "../"))
    edit(wall, _with_mtlx)
    with Attack(wall.parent):
        r = run_cli("convert", wall, "-o", wall.parent.parent / "out")
    assert r.returncode == 3 and "outside the scene's folder" in r.stderr and "brick.mtlx" in r.stderr


def test_payload_structure_is_flattened_with_its_textures(wall, tmp_path):
    """An asset as USD's asset structure guidelines lay it out: a root layer with a payload
    to geometry and a reference to materials, each in its own subfolder."""
    root = wall.parent
    full = Usd.Stage.Open(str(wall))
    for sub, prim in (("geo", "/World/wall"), ("mtl", "/World/Looks")):
        (root / sub).mkdir()
        stage = Usd.Stage.CreateNew(str(root / sub / f"{sub}.usda"))
        Sdf.CopySpec(full.GetRootLayer(), prim, stage.GetRootLayer(), f"/{Path(prim).name}")
        stage.GetRootLayer().Save()
    for name in ("bricks_color.png", "bricks_height.png"):
        shutil.move(root / name, root / "mtl" / name)
    asset = Usd.Stage.CreateNew(str(root / "asset.usda"))
    world = asset.DefinePrim("/World", "Xform")
    asset.SetDefaultPrim(world)
    UsdGeom.SetStageUpAxis(asset, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(asset, 1.0)
    asset.DefinePrim("/World/wall").GetPayloads().AddPayload("./geo/geo.usda", "/wall")
    asset.DefinePrim("/World/Looks").GetReferences().AddReference("./mtl/mtl.usda", "/Looks")
    UsdShade.MaterialBindingAPI.Apply(asset.GetPrimAtPath("/World/wall")).GetDirectBindingRel().SetTargets(
        [Sdf.Path("/World/Looks/bricks")])
    asset.GetRootLayer().Save()
    report = convert(root / "asset.usda", tmp_path / "out")
    assert report.warnings == [] and report.tangent_meshes == ["/World/wall"]
    out = tmp_path / "out" / "asset.usda"
    assert not Sdf.Layer.FindOrOpen(str(out)).GetCompositionAssetDependencies()
    assert validation_errors(out) == []


# ------------------------------------------------------------------ meshes without normals

def _slow_smooth_normals(points, counts, indices, left=False):
    """Per point: the sum over its polygons' fan triangles of their cross products, normalized."""
    acc = np.zeros((len(points), 3))
    start = 0
    for c in counts:
        face = indices[start:start + c]
        for k in range(1, c - 1):
            a, b, d = (face[0], face[k + 1], face[k]) if left else (face[0], face[k], face[k + 1])
            n = np.cross(points[b] - points[a], points[d] - points[a])
            for v in (a, b, d):
                acc[v] += n
        start += c
    return acc / np.linalg.norm(acc, axis=1, keepdims=True)


@pytest.mark.parametrize("left", [False, True])
def test_mesh_without_normals_gets_smooth_normals_and_subdivision_is_warned(wall, left):
    def change(stage):
        mesh = UsdGeom.Mesh.Get(stage, WALL)
        mesh.GetNormalsAttr().Clear()
        pts = np.array(mesh.GetPointsAttr().Get(), np.float64)
        pts[:, 2] = 0.3 * np.sin(3 * pts[:, 0]) * pts[:, 1]  # curved, so normals differ per point
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
        mesh.GetSubdivisionSchemeAttr().Set("catmullClark")
        if left:
            mesh.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
    scene = usd.read(edit(wall, change))
    (mesh,) = scene.meshes
    assert len(scene.warnings) == 1 and "catmullClark subdivision surface" in str(scene.warnings[0])
    stage = Usd.Stage.Open(str(wall))
    m = UsdGeom.Mesh.Get(stage, WALL)
    pts = np.array(m.GetPointsAttr().Get(), np.float64)
    expect = _slow_smooth_normals(pts, list(m.GetFaceVertexCountsAttr().Get()),
                                  list(m.GetFaceVertexIndicesAttr().Get()), left)
    for v in range(len(mesh.positions)):
        point = np.flatnonzero((pts == mesh.positions[v]).all(1))[0]
        np.testing.assert_allclose(mesh.normals[v], expect[point], atol=1e-6)
    assert (mesh.normals[:, 2] > 0).all() != left  # facing the viewer for right-handed winding


def test_variant_sets_flattened_to_their_selection_are_warned(wall, tmp_path):
    def change(stage):
        vs = stage.GetPrimAtPath("/World").GetVariantSets().AddVariantSet("look")
        for name in ("clean", "dirty"):
            vs.AddVariant(name)
        vs.SetVariantSelection("clean")
    report = convert(edit(wall, change), tmp_path / "out")
    (w,) = map(str, report.warnings)
    assert "1 variant set(s) (</World> look)" in w and "current selections" in w
    assert report.tangent_meshes == ["/World/wall"]


def test_metadata_no_plugin_declares_is_kept_in_a_single_layer_scene(wall, tmp_path):
    """Omniverse writes prim metadata fields usd-core has no schema for; Flatten cannot copy
    them, so a scene that is one plain layer is copied instead of flattened."""
    text = wall.read_text().replace('def Xform "World"\n', 'def Xform "World" (\n    hide_in_stage_window = false\n'
                                    '    no_delete = false\n)\n', 1)
    assert "no_delete" in text
    wall.write_text(text)
    report = convert(wall, tmp_path / "out")
    assert report.warnings == [] and report.tangent_meshes == ["/World/wall"]
    out = (tmp_path / "out" / wall.name).read_text()
    assert "hide_in_stage_window = false" in out and "no_delete = false" in out and "primvars:tangents" in out
    assert validation_errors(tmp_path / "out" / wall.name) == []


# ------------------------------------------------------------------ UDIM sets and missing assets

def _udim(file: str, tiles=(1001, 1002)):
    def change(stage):
        UsdShade.Shader.Get(stage, "/World/Looks/bricks/colorTex").GetInput("file").Set(file)
    return change, tiles


def test_udim_tiles_are_copied_under_one_pattern(wall, tmp_path):
    for tile in (1001, 1002, 1011):
        shutil.copy(SAMPLES / "bricks_color.png", wall.parent / f"bricks.{tile}.png")
    edit(wall, _udim("./bricks.<UDIM>.png")[0])
    report = convert(wall, tmp_path / "out")
    assert report.warnings == []
    out = tmp_path / "out"
    assert sorted(p.name for p in out.glob("bricks.*.png")) == ["bricks.1001.png", "bricks.1002.png",
                                                                "bricks.1011.png"]
    stage = Usd.Stage.Open(str(out / wall.name))
    assert stage.GetAttributeAtPath("/World/Looks/bricks/colorTex.inputs:file").Get().path == "./bricks.<UDIM>.png"
    assert validation_errors(out / wall.name) == []


def test_udim_tiles_outside_the_folder_are_refused(wall):
    shutil.copy(SAMPLES / "bricks_color.png", wall.parent.parent / "bricks.1001.png")
    edit(wall, _udim("../bricks.<UDIM>.png")[0])
    with pytest.raises(Exception, match="outside the scene's folder"):
        usd.read(wall)


@pytest.mark.parametrize("file, says", [("./gone.png", "resolves to nothing"),
                                        ("./gone.<UDIM>.png", "resolves to no UDIM tile")])
def test_missing_assets_are_counted_warnings(wall, tmp_path, file, says):
    edit(wall, _udim(file)[0])
    report = convert(wall, tmp_path / "out")
    (w,) = map(str, report.warnings)
    assert says in w and "colorTex.inputs:file" in w


def test_udim_height_gets_a_step_map_per_tile(wall, tmp_path):
    """(A warning, CSM105, before UDIM sets were converted; tests/test_udim.py holds the rest.)"""
    for tile in (1001, 1002):
        shutil.copy(SAMPLES / "bricks_height.png", wall.parent / f"h.{tile}.png")
    edit(wall, lambda stage: UsdShade.Shader.Get(stage, "/World/Looks/bricks/heightTex").GetInput("file").Set(
        "./h.<UDIM>.png"))
    report = convert(wall, tmp_path / "out")
    assert report.warnings == [] and sorted(report.step_maps) == ["h_csm.1001", "h_csm.1002"]


# ------------------------------------------------------------------ instancing

def test_instanced_assets_are_converted_once_in_their_prototype(wall, tmp_path):
    """Two instanceable references to the wall (as kit-bashed and Omniverse scenes are
    built): its material and mesh live in a prototype, edited once, seen by both."""
    stage = Usd.Stage.CreateNew(str(wall.parent / "scene.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(stage.DefinePrim("/Scene", "Xform"))
    for i in range(2):
        prim = stage.DefinePrim(f"/Scene/wall{i}", "Xform")
        prim.GetReferences().AddReference("./brick_wall.usda")
        prim.SetInstanceable(True)
    stage.GetRootLayer().Save()
    report = convert(wall.parent / "scene.usda", tmp_path / "out")
    assert report.warnings == [] and len(report.tangent_meshes) == 1 and len(report.step_maps) == 1
    out = tmp_path / "out" / "scene.usda"
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert [(p.name, p.specifier) for p in layer.rootPrims if p.name != "Scene"] == [
        ("Flattened_Prototype_1", Sdf.SpecifierOver)]  # still not rendered by itself
    assert not any(Path(d).is_absolute() for d in layer.GetExternalAssetDependencies())
    composed = Usd.Stage.Open(str(out))
    for i in range(2):
        mesh = composed.GetPrimAtPath(f"/Scene/wall{i}/wall")
        assert mesh.IsInstanceProxy() and UsdGeom.PrimvarsAPI(mesh).GetPrimvar("tangents").HasValue()
        surface = UsdShade.Material(composed.GetPrimAtPath(f"/Scene/wall{i}/Looks/bricks"))
        assert surface.GetSurfaceOutput("glslfx").HasConnectedSource()
    assert validation_errors(out) == []


def test_mtlx_reference_in_a_referenced_layer_is_kept_where_it_lands(tmp_path):
    """The OpenChessSet layout: each piece's look layer references its .mtlx; the scene
    references the piece twice. Each landing gets the arc again in the flattened output."""
    root = tmp_path / "in"
    (root / "piece").mkdir(parents=True)
    (root / "piece" / "piece.mtlx").write_text(MTLX.replace("./tex/", "").replace(
        '<input name="file" type="filename" value="missing.png" />', ""))
    shutil.copy(SAMPLES / "bricks_color.png", root / "piece" / "bricks_color.png")
    piece = Usd.Stage.CreateNew(str(root / "piece" / "piece.usda"))
    piece.SetDefaultPrim(piece.DefinePrim("/Piece", "Xform"))
    piece.DefinePrim("/Piece/Materials", "Scope").GetReferences().AddReference("./piece.mtlx", "/MaterialX")
    piece.GetRootLayer().Save()
    scene = Usd.Stage.CreateNew(str(root / "scene.usda"))
    UsdGeom.SetStageUpAxis(scene, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(scene, 1.0)
    scene.SetDefaultPrim(scene.DefinePrim("/Scene", "Xform"))
    for name in ("a", "b"):
        scene.DefinePrim(f"/Scene/{name}", "Xform").GetReferences().AddReference("./piece/piece.usda")
    scene.GetRootLayer().Save()
    with Attack(root):
        r = run_cli("convert", root / "scene.usda", "-o", tmp_path / "out")
    (warning,) = assert_clean_run(r)
    assert "'./piece.mtlx' at </Scene/a/Materials>, </Scene/b/Materials> is kept" in warning
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "out" / "scene.usda"))
    for name in ("a", "b"):
        refs = layer.GetPrimAtPath(f"/Scene/{name}/Materials").referenceList.prependedItems
        assert [(x.assetPath, str(x.primPath)) for x in refs] == [("./piece.mtlx", "/MaterialX")]
    assert (tmp_path / "out" / "piece.mtlx").is_file() and (tmp_path / "out" / "bricks_color.png").is_file()
