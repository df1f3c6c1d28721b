"""Attack cases for USD scenes through the CLI (``convert``): composition arcs leaving the
scene's folder or missing, malformed topology, wrong-typed or non-finite shading inputs,
declared sizes over the limits. Each case asserts the exit code, one error line naming
the file, no traceback, inputs untouched and no outputs (or a counted warning and a
clean output). Crafted files are made here with pxr."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from usd_stages import edit, wall_folder

MAT = "/World/Looks/bricks"


@pytest.fixture
def scene(tmp_path):
    """The sample wall in ``tmp_path/in`` (a file beside it, ``tmp_path/outside.usda``)."""
    d = wall_folder(tmp_path)
    layer = Sdf.Layer.CreateNew(str(tmp_path / "outside.usda"))
    Sdf.CreatePrimInLayer(layer, "/Secret").specifier = Sdf.SpecifierDef
    layer.Save()
    return d / "brick_wall.usda"


def refused(path: Path, code: int, *names, extra=()) -> str:
    """Convert ``path``: exit ``code``, one line naming the file (and ``names``), inputs
    untouched, no outputs."""
    out = path.parent.parent / "out"
    with Attack(path.parent, path.parent.parent / "outside.usda"):
        r = run_cli("convert", path, "-o", out, *extra)
    line = assert_clean_error(r, code, path.name)
    for name in names:
        assert name in line, line
    assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())
    return line


def converted(path: Path, *extra) -> tuple[list[str], Path]:
    """Convert ``path``: exit 0, inputs untouched; the warnings and the output scene."""
    out = path.parent.parent / "out"
    with Attack(path.parent):
        r = run_cli("convert", path, "-o", out, *extra)
    warnings = assert_clean_run(r)
    text = (out / path.name).read_text()
    assert "nan" not in text.lower() and "inf" not in text.lower().replace("info", "")
    return warnings, out / path.name


# ------------------------------------------------------------------ arcs leaving the folder

def _arc(kind: str, asset: str):
    def change(stage):
        root = stage.GetRootLayer()
        if kind == "subLayer":
            root.subLayerPaths.append(asset)
        elif kind == "reference":
            stage.DefinePrim("/World/Ref").GetReferences().AddReference(asset, "/Secret")
        else:
            stage.DefinePrim("/World/Pay").GetPayloads().AddPayload(asset, "/Secret")
    return change


@pytest.mark.parametrize("kind", ["subLayer", "reference", "payload"])
@pytest.mark.parametrize("where", ["../outside.usda", "absolute"])
def test_arcs_outside_the_scene_folder_are_refused(scene, kind, where):
    asset = str(scene.parent.parent / "outside.usda") if where == "absolute" else where
    edit(scene, _arc(kind, asset))
    line = refused(scene, 3, asset, "refused")
    assert ("absolute" in line) == (where == "absolute")


@pytest.mark.parametrize("kind", ["subLayer", "reference", "payload"])
def test_arcs_outside_are_read_when_allowed(scene, kind):
    edit(scene, _arc(kind, "../outside.usda"))
    warnings, out = converted(scene, "--allow-outside-paths")
    stage = Usd.Stage.Open(str(out))
    assert stage.GetRootLayer().subLayerPaths == [] and not stage.GetRootLayer().GetCompositionAssetDependencies()
    if kind != "subLayer":  # flattened in: its content is there, no arc to outside remains
        assert stage.GetPrimAtPath(f"/World/{'Ref' if kind == 'reference' else 'Pay'}").IsValid()


@pytest.mark.parametrize("kind", ["subLayer", "reference", "payload"])
def test_missing_arcs_are_refused_not_dropped(scene, kind):
    edit(scene, _arc(kind, "./gone.usda"))
    refused(scene, 3, "gone.usda", "does not exist")


def test_unreadable_layer_is_refused(scene):
    (scene.parent / "broken.usda").write_text("#usda 1.0\ndef Xform \"x\" {\n  float3 a = (\n")
    edit(scene, _arc("payload", "./broken.usda"))
    line = refused(scene, 3, "broken.usda", "line 4, column 1 (in /x.a): parse error")
    assert "pxrInternal" not in line and "pegtl" not in line


def test_a_truncated_scene_says_where_it_stops_parsing(scene):
    """A text layer cut short (a copy interrupted, a download that stopped): the line and column
    where usd-core's parser gave up and the prim it was in, not its internal rule names (the
    reason was once a lone quote, the last line of the exception)."""
    text = scene.read_text()
    scene.write_text(text[:text.index("heightTex")] + "heightTex\"\n    {\n        uniform token info:id = \"UsdUV")
    line = refused(scene, 3, "is not a readable USD layer: line ")
    assert "): parse error" in line or "Expected" in line, line
    assert "pxrInternal" not in line and "pegtl" not in line and not line.endswith("'"), line


# ------------------------------------------------------------------ topology

def _mesh_attr(name, value):
    def change(stage):
        UsdGeom.Mesh.Get(stage, "/World/wall").GetPrim().GetAttribute(name).Set(value)
    return change


@pytest.mark.parametrize("name, value, says", [
    ("faceVertexCounts", Vt.IntArray([4, 4, 4, 4, 4, 4, 4, -4, 8]), "negative"),
    ("faceVertexCounts", Vt.IntArray([4] * 7), "add up to"),
    ("faceVertexIndices", Vt.IntArray([0, 1, 6, 5] * 7 + [0, 1, 99, 5]), "outside its 15 points"),
    ("faceVertexIndices", Vt.IntArray([0, 1, 6, 5] * 7 + [0, 1, -3, 5]), "outside its 15 points"),
])
def test_inconsistent_topology_is_refused(scene, name, value, says):
    edit(scene, _mesh_attr(name, value))
    refused(scene, 3, "/World/wall", says)


def test_small_usdc_declaring_20m_triangles_is_refused_before_reading_them(scene):
    usdc = scene.with_name("huge.usdc")
    Sdf.Layer.FindOrOpen(str(scene)).Export(str(usdc))  # relative asset paths kept
    stage = Usd.Stage.Open(str(usdc))
    mesh = UsdGeom.Mesh.Get(stage, "/World/wall")
    mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(np.full(20_000_000, 3, np.int32)))
    stage.GetRootLayer().Save()
    del stage, mesh
    assert usdc.stat().st_size < 1_000_000
    line = refused(usdc, 3, "/World/wall.faceVertexCounts", "60,000,000", "CSM_ASSETS_MAX_VERTICES")
    assert "limit" in line


def test_vertex_limit_comes_from_the_environment(scene, monkeypatch):
    monkeypatch.setenv("CSM_ASSETS_MAX_VERTICES", "20")
    refused(scene, 3, "/World/wall", "CSM_ASSETS_MAX_VERTICES")


# ------------------------------------------------------------------ non-finite numbers

@pytest.mark.parametrize("attr, value", [
    ("points", "nan"), ("points", "inf"), ("primvars:st", "nan"), ("normals", "-inf")])
def test_non_finite_geometry_is_refused(scene, attr, value):
    def change(stage):
        a = stage.GetPrimAtPath("/World/wall").GetAttribute(attr)
        v = np.array(a.Get())
        v[3, 0] = float(value)
        a.Set(type(a.Get()).FromNumpy(v.astype(np.float32)))
    edit(scene, change)
    refused(scene, 3, f"/World/wall.{attr}", "NaN or infinite")


@pytest.mark.parametrize("key, value", [("scale", Gf.Vec4f(math.nan, 1, 1, 1)),
                                        ("bias", Gf.Vec4f(math.inf, 0, 0, 0))])
def test_non_finite_scale_or_bias_is_refused(scene, key, value):
    def change(stage):
        UsdShade.Shader.Get(stage, f"{MAT}/heightTex").CreateInput(key, Sdf.ValueTypeNames.Float4).Set(value)
    edit(scene, change)
    refused(scene, 3, f"{MAT}/heightTex.inputs:{key}", "NaN or infinite")


# ------------------------------------------------------------------ shading networks

def test_scale_authored_as_a_float_is_a_counted_warning(scene):
    def change(stage):
        tex = UsdShade.Shader.Get(stage, f"{MAT}/heightTex").GetPrim()
        tex.RemoveProperty("inputs:scale")
        tex.CreateAttribute("inputs:scale", Sdf.ValueTypeNames.Float).Set(0.03)
    edit(scene, change)
    warnings, out = converted(scene)
    assert any("inputs:scale is a float" in w and "brick_wall.usda" in w for w in warnings), warnings
    assert not (out.parent / "bricks_height_csm.png").exists()


def test_connection_cycle_is_a_counted_warning(scene):
    def change(stage):
        tex = UsdShade.Shader.Get(stage, f"{MAT}/heightTex")
        ng = UsdShade.NodeGraph.Define(stage, f"{MAT}/loop")
        a, b = ng.CreateOutput("a", Sdf.ValueTypeNames.Float), ng.CreateOutput("b", Sdf.ValueTypeNames.Float)
        a.ConnectToSource(b)
        b.ConnectToSource(a)
        UsdShade.Shader.Get(stage, f"{MAT}/PreviewSurface").GetInput("displacement").ConnectToSource(a)
        del tex
    edit(scene, change)
    warnings, _ = converted(scene)
    assert any("cycle" in w for w in warnings), warnings


def test_displacement_connected_to_a_missing_prim_is_a_counted_warning(scene):
    def change(stage):
        ps = UsdShade.Shader.Get(stage, f"{MAT}/PreviewSurface").GetInput("displacement")
        ps.GetAttr().SetConnections([Sdf.Path(f"{MAT}/nowhere.outputs:r")])
    edit(scene, change)
    warnings, _ = converted(scene)
    assert any("nowhere" in w and "does not exist" in w for w in warnings), warnings


def test_wrongly_typed_tangents_are_replaced_with_a_warning(scene):
    def change(stage):
        UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall")).CreatePrimvar(
            "tangents", Sdf.ValueTypeNames.TokenArray, UsdGeom.Tokens.vertex).Set(Vt.TokenArray(["x"] * 15))
    edit(scene, change)
    warnings, out = converted(scene)
    assert any("primvars:tangents" in w for w in warnings), warnings
    stage = Usd.Stage.Open(str(out))
    pv = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/wall")).GetPrimvar("tangents")
    assert pv.GetTypeName() == Sdf.ValueTypeNames.Float3Array and np.isfinite(np.array(pv.Get())).all()
