"""Real height sources read, or refused clearly (issue 23): wide and signed integer rasters with
their real range, nodata values as holes, a normal map named on the command line, an OBJ
without an MTL, USD displacement without an authored scale, a material behind a MaterialX
arc, a step map given as heights, a folder, a name wrong only by letter case."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import tifffile
from pxr import Sdf, Usd, UsdShade

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, OBJ_WALL, SAMPLES, copy_samples
from csm_assets.formats import load_heightfield, read_step_map, read_step_map_meta
from usd_stages import edit, wall_folder

NODATA = -32768


def dem(rows=48, cols=64, seed=3) -> np.ndarray:
    """An int16 elevation model as SRTM/USGS tiles hold them: metres 120..1850 over rolling
    terrain, a void of NODATA in one corner (GDAL_NODATA -32768)."""
    rng = np.random.default_rng(seed)
    f = np.zeros((rows, cols), complex)
    f[:3, :3] = rng.normal(size=(3, 3)) + 1j * rng.normal(size=(3, 3))
    z = np.real(np.fft.ifft2(f))
    z = 120 + (z - z.min()) / (z.max() - z.min()) * 1730
    z = np.rint(z).astype(np.int16)
    z[:6, :9] = NODATA
    return z


def write_tif(path, a, nodata=None):
    tags = [] if nodata is None else [(42113, "s", 0, str(nodata), True)]  # GDAL_NODATA, as GDAL writes it
    tifffile.imwrite(path, a, extratags=tags)
    return path


def test_an_int16_dem_is_read_with_its_real_range_and_its_nodata_as_holes(tmp_path):
    z = dem()
    src = write_tif(tmp_path / "dem.tif", z, NODATA)
    hf = load_heightfield(src)
    valid = z != NODATA
    assert (hf.mask == ~valid).all()
    lo, hi = int(z[valid].min()), int(z[valid].max())
    assert (hf.meta["height_offset"], hf.meta["height_scale"]) == (lo, hi - lo)
    np.testing.assert_allclose(hf.data[valid] * (hi - lo) + lo, z[valid], atol=1e-3)  # metres back
    r = run_cli("stepmap", src, "-o", tmp_path / "dem.png", "--json")
    assert not assert_clean_run(r)
    settings = json.loads(r.stdout)["settings"]
    assert (settings["height_offset"], settings["height_scale"]) == (lo, hi - lo)
    packed = read_step_map(tmp_path / "dem.png")
    assert (packed[..., 0][~valid] == 0).all() and packed[..., 0][valid].min() == 0  # holes: the lowest height
    assert_clean_run(run_cli("verify", tmp_path / "dem.png"))


@pytest.mark.parametrize("dtype", ["int32", "uint32", "int8"])
def test_wide_and_signed_integers_keep_their_range(tmp_path, dtype):
    a = (np.arange(12).reshape(3, 4) * (3 if dtype == "int8" else 100_000)).astype(dtype)
    if dtype == "int8":
        a -= 10
    hf = load_heightfield(write_tif(tmp_path / f"{dtype}.tif", a))
    assert hf.meta["height_scale"] == float(a.max()) - float(a.min()) and hf.meta["height_offset"] == a.min()
    np.testing.assert_allclose(hf.data, (a - float(a.min())) / (float(a.max()) - float(a.min())), atol=1e-6)


def test_a_nodata_option_and_float_maps_with_nodata(tmp_path):
    z = dem().astype(np.float32)
    z[z == NODATA] = -9999.0
    plain = write_tif(tmp_path / "plain.tif", z)  # no tag: -9999 would be a 10 km pit
    assert load_heightfield(plain).mask is None
    assert load_heightfield(plain, nodata=-9999).mask.sum() == 54
    tagged = z.copy()
    tagged[tagged == -9999] = np.nan
    assert load_heightfield(write_tif(tmp_path / "nan.tif", tagged, "nan")).mask.sum() == 54
    r = run_cli("stepmap", plain, "-o", tmp_path / "p.png", "--nodata", "-9999", "--json")
    assert json.loads(r.stdout)["settings"]["height_offset"] == pytest.approx(float(z[z > 0].min()))
    r = run_cli("verify", plain, "--nodata", "-9999")
    assert r.returncode == 0, r.stdout
    bad = run_cli("stepmap", SAMPLES / "bricks_height.png", "-o", tmp_path / "x.png", "--nodata", "0")
    assert bad.returncode == 0  # 8-bit codes: texels of code 0 are holes
    r = run_cli("stepmap", write_tif(tmp_path / "void.tif", np.full((4, 4), NODATA, np.int16), NODATA),
                "-o", tmp_path / "v.png")
    assert "no heights" in assert_clean_error(r, 3, "void.tif")


def test_a_normal_map_named_on_the_command_line_is_refused_unless_a_channel_is(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    shutil.copy(SAMPLES / "bricks_normal.png", src / "bricks_normal.png")
    args = ["convert", src / "brick_wall.gltf", "--height", f"bricks={src / 'bricks_normal.png'}"]
    msg = assert_clean_error(run_cli(*args, "-o", tmp_path / "a"), 3, "bricks_normal.png")
    assert "tangent-space normal map" in msg and "--channel" in msg
    assert not (tmp_path / "a" / "bricks_normal_csm.png").exists()
    assert_clean_run(run_cli(*args, "-o", tmp_path / "b", "--channel", "2"))
    assert (tmp_path / "b" / "bricks_normal_csm.png").is_file()
    assert run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "c", "--channel", "2").returncode == 2


def test_an_obj_without_mtl_takes_a_height_for_its_default_material(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    text = (SAMPLES / "brick_wall.obj").read_text()
    (src / "head.obj").write_text("".join(l for l in text.splitlines(True) if not l.startswith(("mtllib", "usemtl"))))
    shutil.copy(SAMPLES / "bricks_height.png", src / "bricks_height.png")
    out = tmp_path / "out"
    assert not assert_clean_run(run_cli("convert", src / "head.obj", "-o", out, "--height",
                                        f"={src / 'bricks_height.png'}"))
    lines = (out / "head.obj").read_text().splitlines()
    assert lines[:2] == ["mtllib head_default.mtl", "usemtl default"]
    assert lines[2:] == [l for l in text.splitlines() if not l.startswith(("mtllib", "usemtl"))]  # the rest as it was
    mtl = (out / "head_default.mtl").read_text()
    assert "newmtl default" in mtl and "csm_map bricks_height_csm.png" in mtl
    assert_clean_run(run_cli("verify", out / "head.obj"))
    r = run_cli("convert", src / "head.obj", "-o", tmp_path / "o2", "--height", f"nope={src / 'bricks_height.png'}")
    assert "the default material of the faces no usemtl names: =PATH" in assert_clean_error(r, 2, "head.obj")


def test_usd_displacement_without_an_authored_scale_gets_the_default_depth(tmp_path):
    wall = wall_folder(tmp_path) / "brick_wall.usda"

    def drop_scale(stage):
        stage.GetPrimAtPath("/World/Looks/bricks/heightTex").RemoveProperty("inputs:scale")

    def depth_of(folder):
        stage = Usd.Stage.Open(str(folder / "brick_wall.usda"))
        shaders = [UsdShade.Shader(p) for p in stage.Traverse() if p.IsA(UsdShade.Shader)]
        return next(s.GetInput("depthScale").Get() for s in shaders if s.GetInput("depthScale"))

    assert_clean_run(run_cli("convert", wall, "-o", tmp_path / "kept"))
    assert depth_of(tmp_path / "kept") == pytest.approx(0.03)  # the authored factor: 0.03 m over 1 m per uv
    edit(wall, drop_scale)
    assert_clean_run(run_cli("convert", wall, "-o", tmp_path / "none"))
    assert depth_of(tmp_path / "none") == pytest.approx(0.1)  # no factor stated: the default, not 1 m


def test_a_height_for_a_material_behind_a_materialx_reference_says_so(tmp_path):
    wall = wall_folder(tmp_path) / "brick_wall.usda"
    (wall.parent / "brick.mtlx").write_text('<?xml version="1.0"?>\n<materialx version="1.38">\n'
                                            '  <surfacematerial name="Brick" type="material" />\n</materialx>\n')

    def add(stage):
        stage.DefinePrim("/World/MaterialX", "Scope").GetReferences().AddReference("./brick.mtlx", "/MaterialX")
        stage.GetPrimAtPath("/World/wall").GetRelationship("material:binding").SetTargets(
            [Sdf.Path("/World/MaterialX/Materials/Brick")])

    edit(wall, add)
    r = run_cli("convert", wall, "-o", tmp_path / "out", "--height", f"Brick={wall.parent / 'bricks_height.png'}")
    msg = assert_clean_error(r, 2, "brick_wall.usda")
    assert "'Brick' is behind the reference './brick.mtlx' at </World/MaterialX>" in msg and ".mtlx" in msg


def test_small_clear_refusals(tmp_path):
    made = tmp_path / "made.png"
    assert_clean_run(run_cli("stepmap", SAMPLES / "bricks_height.png", "-o", made))
    msg = assert_clean_error(run_cli("stepmap", made, "-o", tmp_path / "again.png"), 3, "made.png")
    assert "is a step map made by csm-assets" in msg and "(bricks_height.png)" in msg
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    (src / "textures").mkdir()
    r = run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "o", "--height", f"bricks={src / 'textures'}")
    assert "is a folder" in assert_clean_error(r, 3, "textures")
    r = run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "o", "--height",
                f"bricks={src / 'BRICKS_HEIGHT.PNG'}")
    assert "bricks_height.png exists: the names differ only by letter case" in assert_clean_error(r, 3)


def test_an_mtl_naming_a_texture_in_other_letter_case_says_which_file_exists(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    mtl = src / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("bricks_height.png", "BRICKS-HEIGHT.PNG"))
    (src / "bricks_height.png").rename(src / "bricks-height.png")
    warnings = assert_clean_run(run_cli("convert", src / "brick_wall.obj", "-o", tmp_path / "out"))
    assert any("BRICKS-HEIGHT.PNG is missing (bricks-height.png exists: the names differ only by letter case)" in w
               for w in warnings), warnings
