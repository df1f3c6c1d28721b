"""Crafted OBJ + MTL scenes and --height/--depth misuse against the CLI (issues 11 and 13).

Each case: the documented exit code, one error line naming the file (and the line for
malformed geometry), no traceback, inputs untouched; or a clean run whose warnings are
counted and whose MTL keeps every byte but the lines the tool adds.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import OBJ_WALL, copy_samples


@pytest.fixture
def wall(tmp_path):
    return copy_samples(tmp_path / "in", OBJ_WALL)


def _append(path, text: str) -> None:
    path.write_bytes(path.read_bytes() + text.encode())


def _convert(wall, out, *extra):
    return run_cli("convert", wall / "brick_wall.obj", "-o", out, *extra)


@pytest.mark.parametrize("bad, what", [
    ("v 1 2", "'v' needs 3 numbers"),
    ("v 1 nan 0", "NaN or infinite"),
    ("v inf 0 0", "NaN or infinite"),
    ("vt 0.5 -inf", "NaN or infinite"),
    ("vn 0 1", "'vn' needs 3 numbers"),
    ("v 1 x 0", "not a number"),
    ("f 1/1/1 2/2/1 99/1/1", "out of range"),
    ("f 1/1/1 2/2/1 0/1/1", "out of range"),
    ("f 1/1/1 2/2/1 3/400/1", "out of range"),
    ("f 1/1/1 2/2/1 /3/1", "names no vertex"),
    ("f 1/1/1 2/2/1 a/3/1", "malformed 'f'"),
])
def test_malformed_geometry_is_exit_3_naming_file_and_line(wall, tmp_path, bad, what):
    _append(wall / "brick_wall.obj", bad + "\n")
    n = len((wall / "brick_wall.obj").read_text().splitlines())
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    line = assert_clean_error(r, 3, "brick_wall.obj")
    assert f"line {n}" in line and what in line, line
    assert not (tmp_path / "out" / "brick_wall.obj").exists()


@pytest.mark.parametrize("short", ["f 1/1/1", "f 1/1/1 2/2/1"])
def test_faces_with_fewer_than_three_vertices_are_skipped_with_a_warning(wall, tmp_path, short):
    _append(wall / "brick_wall.obj", f"{short}\n{short}\n")
    n = len((wall / "brick_wall.obj").read_text().splitlines())
    with Attack(wall):
        r = _convert(wall, tmp_path / "out", "--json")
    warnings = assert_clean_run(r)
    assert any(f"2 face(s) with fewer than three vertices skipped (first on line {n - 1})" in w for w in warnings)
    assert "csm_map" in (tmp_path / "out" / "brick_wall.mtl").read_text()


def test_mesh_without_uvs_gets_a_warning_and_no_csm_material(wall, tmp_path):
    obj = wall / "brick_wall.obj"
    lines = [line for line in obj.read_text().splitlines() if not line.startswith("vt")]
    obj.write_text(re.sub(r"(\d+)/\d+/(\d+)", r"\1//\2", "\n".join(lines) + "\n"))
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    warnings = assert_clean_run(r)
    assert any("material 'bricks'" in w and "no uvs, so no CSM material" in w for w in warnings), warnings
    mtl = (tmp_path / "out" / "brick_wall.mtl").read_bytes()
    assert mtl == (wall / "brick_wall.mtl").read_bytes()
    assert not list((tmp_path / "out").glob("*_csm.png"))


def test_mtl_is_kept_byte_for_byte_but_the_added_lines(wall, tmp_path):
    """CRLF endings, comments before and inside materials, odd spacing, unknown statements,
    bytes that are not UTF-8 and a last line without an ending all survive."""
    mtl = (b"# header comment\r\n#  second \xe9 latin-1 line\r\n\r\nnewmtl  other\r\nKd 1 0 0\r\n"
           b"illum 2  # trailing\r\nPr 0.5\r\nmap_Kd   bricks_color.png\r\n\r\n"
           b"newmtl bricks\r\nKa 0 0 0\r\n  Kd 0.8 0.8 0.8\r\n# inside\r\nmap_Kd bricks_color.png\r\n"
           b"map_Bump -bm 1 bricks_normal.png\r\ndisp -mm 0 0.03 bricks_height.png\r\n"
           b"Tf 1 1 1\r\n\r\n# trailer without ending")
    (wall / "brick_wall.mtl").write_bytes(mtl)
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert_clean_run(r)
    out = (tmp_path / "out" / "brick_wall.mtl").read_bytes()
    added = [line for line in out.split(b"\r\n") if line.startswith(b"csm_")]
    assert [a.split()[0] for a in added] == [b"csm_map", b"csm_map_levels", b"csm_depth", b"csm_max_ratio", b"csm_tile",
                                             b"csm_height_scale", b"csm_height_offset",
                                             b"csm_variant", b"csm_steps", b"csm_min_step"]
    assert out.replace(b"".join(a + b"\r\n" for a in added), b"") == mtl
    assert out.index(b"csm_map") == out.index(b"Tf 1 1 1\r\n") + len(b"Tf 1 1 1\r\n")
    assert (tmp_path / "out" / "brick_wall.obj").read_bytes() == (wall / "brick_wall.obj").read_bytes()


def test_obj_bytes_are_copied_as_they_are(wall, tmp_path):
    obj = wall / "brick_wall.obj"
    obj.write_bytes(b"# \xff\xfe not utf-8\r\n" + obj.read_bytes().replace(b"\n", b"\r\n"))
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert_clean_run(r)
    assert (tmp_path / "out" / "brick_wall.obj").read_bytes() == obj.read_bytes()


@pytest.mark.parametrize("statement, depth", [
    ("bump bricks_height.png", "0.1"),          # no -bm: the documented default, 0.1 texture widths
    ("disp bricks_height.png", "0.1"),          # no -mm: the same
    ("bump -bm 0.02 bricks_height.png", None),  # stated: from the factor and the mesh's size per uv
])
def test_bump_without_a_multiplier_gets_the_default_depth(wall, tmp_path, statement, depth):
    text = (wall / "brick_wall.mtl").read_text().replace("disp -mm 0 0.03 bricks_height.png", statement)
    (wall / "brick_wall.mtl").write_text(text)
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert_clean_run(r)
    line = next(x for x in (tmp_path / "out" / "brick_wall.mtl").read_text().splitlines()
                if x.startswith("csm_depth"))
    # the sample wall is 2 x 1 units over uv 2 x 1: one uv unit is one world unit
    assert float(line.split()[1]) == pytest.approx(float(depth) if depth else 0.02)


@pytest.mark.parametrize("bad", ["-bm nan", "-bm inf", "-mm 0 nan"])
def test_non_finite_factor_in_the_mtl_is_exit_3(wall, tmp_path, bad):
    key = "disp" if "-mm" in bad else "bump"
    text = (wall / "brick_wall.mtl").read_text().replace("disp -mm 0 0.03 bricks_height.png",
                                                         f"{key} {bad} bricks_height.png")
    (wall / "brick_wall.mtl").write_text(text)
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    line = assert_clean_error(r, 3, "brick_wall.mtl")
    assert "finite" in line and "line 9" in line


def test_height_naming_no_material_is_exit_2_listing_the_materials(wall, tmp_path):
    with Attack(wall):
        r = _convert(wall, tmp_path / "out", "--height", f"brick={wall / 'bricks_height.png'}")
    line = assert_clean_error(r, 2, "brick_wall.obj")
    assert "'brick'" in line and "its materials: 'bricks'" in line and "newmtl" in line
    with Attack(wall):
        r = _convert(wall, tmp_path / "out", "--depth", "walls=0.1")
    assert "'walls'" in assert_clean_error(r, 2, "brick_wall.obj")


@pytest.mark.parametrize("args, code", [
    (["--height", "bricks"], 2), (["--height", "=a.png"], 2), (["--depth", "bricks=-1"], 2),
    (["--depth", "bricks=nan"], 2), (["--depth", "0.1", "--depth", "0.2"], 2),
    (["--height", "bricks=missing.png"], 3),
    (["--height", "bricks=a.png", "--depth-map", "bricks=a.png"], 2),
])
def test_bad_height_and_depth_options(wall, tmp_path, args, code):
    (wall / "a.png").write_bytes((wall / "bricks_height.png").read_bytes())
    with Attack(wall):
        r = run_cli("convert", wall / "brick_wall.obj", "-o", tmp_path / "out", *args, cwd=wall)
    assert_clean_error(r, code)


def test_command_line_height_keeps_the_scenes_factor_and_depth_map_inverts(wall, tmp_path):
    from csm_assets.formats import read_step_map

    from csm_assets.formats import image

    depth_png = wall / "bricks_depth.png"
    h = image.read_unit_pixels(wall / "bricks_height.png")[0][..., 0]
    image._write_pixels(np.rint((1 - h) * 65535).astype(np.uint16)[..., None], depth_png)
    with Attack(wall / "brick_wall.mtl"):
        r = run_cli("convert", wall / "brick_wall.obj", "-o", tmp_path / "out", "--depth-map",
                    f"bricks={depth_png}")
    assert_clean_run(r)
    text = (tmp_path / "out" / "brick_wall.mtl").read_text()
    assert "csm_depth 0.03" in text  # disp -mm 0 0.03 still decides the depth
    with Attack(wall):
        assert_clean_run(run_cli("convert", wall / "brick_wall.obj", "-o", tmp_path / "ref"))
    a = read_step_map(tmp_path / "out" / "bricks_depth_csm.png")
    b = read_step_map(tmp_path / "ref" / "bricks_height_csm.png")
    assert np.abs(a[..., 0].astype(float) - b[..., 0].astype(float)).max() <= 1 / 255 + 1e-6
    r = run_cli("convert", wall / "brick_wall.obj", "-o", tmp_path / "d", "--depth-map",
                f"bricks={depth_png}", "--depth", "bricks=0.07")
    assert_clean_run(r)
    assert "csm_depth 0.07" in (tmp_path / "d" / "brick_wall.mtl").read_text()


def test_normal_map_named_with_height_is_refused_unless_a_channel_is(wall, tmp_path):
    """The user named it: exit 3 naming it (issue 23), not a warning and an unchanged scene;
    --channel says what to read of it."""
    with Attack(wall):
        r = _convert(wall, tmp_path / "out", "--height", f"bricks={wall / 'bricks_normal.png'}")
    msg = assert_clean_error(r, 3, "bricks_normal.png")
    assert "'bricks'" in msg and "tangent-space normal map" in msg and "--channel" in msg
    assert not (tmp_path / "out" / "brick_wall.mtl").exists()
    with Attack(wall):
        r = _convert(wall, tmp_path / "out2", "--height", f"bricks={wall / 'bricks_normal.png'}", "--channel", "2")
    assert_clean_run(r)
    assert "csm_map bricks_normal_csm.png" in (tmp_path / "out2" / "brick_wall.mtl").read_text()


def test_colour_photo_under_bump_warns_and_converts_from_luminance(wall, tmp_path):
    text = (wall / "brick_wall.mtl").read_text().replace("disp -mm 0 0.03 bricks_height.png",
                                                         "bump -bm 0.03 bricks_color.png")
    (wall / "brick_wall.mtl").write_text(text)
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    warnings = assert_clean_run(r)
    assert any("bricks_color.png is a colour image" in w and "luminance" in w for w in warnings), warnings
    assert "csm_map bricks_color_csm.png" in (tmp_path / "out" / "brick_wall.mtl").read_text()


def test_several_material_libraries(wall, tmp_path):
    mtl = (wall / "brick_wall.mtl").read_text()
    (wall / "extra.mtl").write_text("newmtl spare\nKd 1 1 1\n")
    obj = wall / "brick_wall.obj"
    obj.write_text(obj.read_text().replace("mtllib brick_wall.mtl", "mtllib extra.mtl brick_wall.mtl"))
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert_clean_run(r)
    assert (tmp_path / "out" / "extra.mtl").read_text() == "newmtl spare\nKd 1 1 1\n"
    assert (tmp_path / "out" / "brick_wall.mtl").read_text().startswith(mtl)


def test_command_line_height_where_the_scene_states_no_factor_gets_the_default(wall, tmp_path):
    text = (wall / "brick_wall.mtl").read_text()
    (wall / "brick_wall.mtl").write_text("\n".join(x for x in text.splitlines() if "bricks_height" not in x
                                                   and "normal" not in x) + "\n")
    with Attack(wall):
        r = _convert(wall, tmp_path / "out", "--height", f"bricks={wall / 'bricks_height.png'}")
    assert_clean_run(r)
    assert "csm_depth 0.1\n" in (tmp_path / "out" / "brick_wall.mtl").read_text()


@pytest.mark.parametrize("bad", ["v nan -nan nan", "v 1.#INF -1.#INF 1.#INF", "vn 0 Infinity 0"])
def test_non_finite_numbers_anywhere_are_exit_3(wall, tmp_path, bad):
    """Even in geometry whose material gets no step map (copied to the output as is)."""
    obj = wall / "brick_wall.obj"
    obj.write_text(obj.read_text() + f"usemtl other\n{bad}\n")
    n = len(obj.read_text().splitlines())
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert f"line {n}" in assert_clean_error(r, 3, "brick_wall.obj")


def test_byte_order_marks(wall, tmp_path):
    """A UTF-8 BOM before the first statement of the OBJ and the MTL (Windows editors) still
    reads; the bytes are kept."""
    mtl = wall / "brick_wall.mtl"
    mtl.write_bytes(b"\xef\xbb\xbf" + b"".join(mtl.read_bytes().splitlines(keepends=True)[1:]))
    obj = wall / "brick_wall.obj"
    obj.write_bytes(b"\xef\xbb\xbf" + b"".join(obj.read_bytes().splitlines(keepends=True)[1:]))
    assert obj.read_bytes().startswith(b"\xef\xbb\xbfmtllib") and mtl.read_bytes().startswith(b"\xef\xbb\xbfnewmtl")
    with Attack(wall):
        r = _convert(wall, tmp_path / "out")
    assert_clean_run(r)
    out = (tmp_path / "out" / "brick_wall.mtl").read_bytes()
    assert out.startswith(mtl.read_bytes()) and b"csm_map bricks_height_csm.png" in out
