"""``--strict`` on real third-party scenes. It fails only on warnings that mean the output may be
wrong or incomplete, so it passes on real scenes whose only warnings are informational, and fails on
one whose relief cannot be drawn.

- @pmndrs/assets' ``pmndrs.glb`` (a CC0 Draco cube made by glTF-Transform): its real uvs have
  triangles without uv area (CSM205, info): passes.
- the same real mesh in a USD stage that leaves USD's default subdivision scheme (catmullClark,
  CSM208, info; the material is the sample wall's UsdPreviewSurface): passes.
- ``bunny.glb`` from the same package has no uvs: its material cannot carry the relief (CSM202,
  CSM203, warnings): fails, exit 3, nothing written.

The relief is LearnOpenGL's ``toy_box_disp.png`` (a real depth map in ../shared/data). Before
warning codes, --strict failed all three."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from pmndrs import model
from usd_stages import edit, wall_folder

DEPTH = "toy_box_disp.png"


@pytest.fixture
def depth_map(shared_data, tmp_path):
    """The real depth map beside the scenes (inputs stay inside the scene's folder)."""
    folder = tmp_path / "in"
    folder.mkdir(exist_ok=True)
    return shutil.copy(shared_data / DEPTH, folder / DEPTH)


def _codes(lines: list[str]) -> list[tuple[str, str]]:
    """(level, code) of warning lines ``csm-assets: LEVEL: CODE ...``."""
    return [re.match(r"csm-assets: (\w+): (CSM\d{3}) ", line).groups() for line in lines]


def test_strict_passes_a_real_glb_whose_only_warning_is_informational(depth_map, tmp_path):
    scene = model("pmndrs", tmp_path / "in")
    with Attack(scene.parent):
        r = run_cli("convert", scene, "-o", tmp_path / "out", "--strict", "--depth-map", f"base={depth_map}")
    lines = assert_clean_run(r)
    assert _codes(lines) == [("info", "CSM205")], lines
    assert "without uv area" in lines[0] and (tmp_path / "out" / "pmndrs.glb").is_file()


def test_strict_passes_a_real_mesh_in_a_usd_stage_with_the_default_subdivision_scheme(depth_map, tmp_path):
    from csm_assets.formats import gltf
    from pxr import Gf, UsdGeom, Vt

    (mesh,) = gltf.read(model("pmndrs", tmp_path / "glb"), heights={"base": depth_map}).meshes
    usd = wall_folder(tmp_path) / "brick_wall.usda"  # beside the depth map: tmp_path / "in"

    def change(stage):
        m = UsdGeom.Mesh(stage.GetPrimAtPath("/World/wall"))
        m.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(mesh.positions.astype(np.float32)))
        m.GetFaceVertexCountsAttr().Set(Vt.IntArray([3] * len(mesh.faces)))
        m.GetFaceVertexIndicesAttr().Set(Vt.IntArray(mesh.faces.reshape(-1).tolist()))
        m.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(mesh.normals.astype(np.float32)))
        m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        st = np.column_stack([mesh.uvs[:, 0], 1 - mesh.uvs[:, 1]]).astype(np.float32)  # glTF v runs down
        UsdGeom.PrimvarsAPI(m).GetPrimvar("st").Set(Vt.Vec2fArray.FromNumpy(st))
        lo, hi = mesh.positions.min(0), mesh.positions.max(0)
        m.GetExtentAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
        m.GetSubdivisionSchemeAttr().Clear()  # as exporters leave it: USD's default, catmullClark

    edit(usd, change)
    with Attack(usd.parent):
        r = run_cli("convert", usd, "-o", tmp_path / "out", "--strict", "--depth-map", f"bricks={depth_map}")
    lines = assert_clean_run(r)
    assert ("info", "CSM208") in _codes(lines) and {level for level, _ in _codes(lines)} == {"info"}, lines
    assert any("catmullClark subdivision surface" in line for line in lines)
    assert (tmp_path / "out" / "brick_wall.usda").is_file()


def test_strict_fails_a_real_glb_whose_relief_cannot_be_drawn(depth_map, tmp_path):
    scene = model("bunny", tmp_path / "in")
    with Attack(scene.parent):
        r = run_cli("convert", scene, "-o", tmp_path / "out", "--strict", "--depth-map", f"base={depth_map}")
    error = assert_clean_error(r, 3, "bunny.glb")
    assert "--strict (CSM202, CSM203)" in error
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    r = run_cli("convert", scene, "-o", tmp_path / "out", "--depth-map", f"base={depth_map}")
    assert _codes(assert_clean_run(r)) == [("warning", "CSM202"), ("warning", "CSM203")]  # without: exit 0
