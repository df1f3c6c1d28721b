"""OBJ + MTL: heights from disp/bump, normal maps recognised, statements kept, CSM statements added."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from csm_assets import FormatError
from csm_assets.convert.pipeline import convert
from csm_assets.formats import obj
from csm_assets.scene import CsmSettings
from csm_assets.stepmap import StepMapSettings

from conftest import OBJ_WALL, SAMPLES, copy_samples


@pytest.fixture
def wall(tmp_path):
    return copy_samples(tmp_path / "in", OBJ_WALL)


def test_reads_disp_with_scale_and_geometry(wall):
    scene = obj.read(wall / "brick_wall.obj")
    (mat,) = scene.materials
    h = mat.height
    assert (h.origin, h.scale, h.offset, h.texture.path.name) == ("mtl disp", 0.03, 0.0,
                                                                   "bricks_height.png")
    (mesh,) = scene.meshes
    assert mesh.positions.shape == (15, 3) and mesh.faces.shape == (16, 3)
    assert mesh.uv_origin == "bottom-left"
    # every triangle keeps its corners: positions and uvs as the file has them
    np.testing.assert_allclose(mesh.uvs[:, 0], mesh.positions[:, 0] + 1)
    np.testing.assert_allclose(mesh.uvs[:, 1], mesh.positions[:, 1])


def test_normal_map_under_map_bump_is_not_a_height(wall):
    text = (wall / "brick_wall.mtl").read_text().replace("disp -mm 0 0.03 bricks_height.png\n", "")
    (wall / "brick_wall.mtl").write_text(text)
    report = convert(wall / "brick_wall.obj", wall.parent / "out")
    assert report.step_maps == {}
    assert any("'bricks'" in w and "bricks_normal.png is a tangent-space normal map" in w for w in map(str, report.warnings))
    assert "csm_map" not in (wall.parent / "out" / "brick_wall.mtl").read_text()


def test_bump_height_with_multiplier_and_channel(wall):
    text = (wall / "brick_wall.mtl").read_text()
    text = text.replace("disp -mm 0 0.03 bricks_height.png\n", "")
    text = text.replace("map_Bump -bm 1 bricks_normal.png", "bump -imfchan g -bm 0.25 bricks_height.png")
    (wall / "brick_wall.mtl").write_text(text)
    h = obj.read(wall / "brick_wall.obj").materials[0].height
    assert (h.origin, h.scale, h.channel) == ("mtl bump", 0.25, 1)


@pytest.mark.parametrize("line, keyword, options, file", [
    ("map_Bump -bm 0.5 -o 0 0 0 my tex.png", "map_Bump", {"-bm": ["0.5"], "-o": ["0", "0", "0"]},
     "my tex.png"),
    ("disp -mm 0.1 2 -clamp on h.tga", "disp", {"-mm": ["0.1", "2"], "-clamp": ["on"]}, "h.tga"),
    ("bump -s 2 h.png", "bump", {"-s": ["2"]}, "h.png"),
    ("map_Kd -type sphere diffuse.jpg", "map_Kd", {"-type": ["sphere"]}, "diffuse.jpg"),
    ("map_bump -imfchan r bumpmap2.jpg -bm 1.5", "map_bump", {"-imfchan": ["r"], "-bm": ["1.5"]}, "bumpmap2.jpg"),
    ("map_bump -colorspace linear -bm 3 bump map.jpg", "map_bump", {"-colorspace": ["linear"], "-bm": ["3"]},
     "bump map.jpg"),
    ("bump -bm 2", "bump", {"-bm": []}, "2"),  # the last word is the file
])
def test_parse_map_statement(line, keyword, options, file):
    parts = line.split()
    st = obj.parse_map(parts[0], parts[1:], 1)
    assert (st.keyword, st.options, st.file) == (keyword, options, file)


def test_writes_obj_as_is_and_mtl_with_csm_statements(wall, tmp_path):
    scene = obj.read(wall / "brick_wall.obj")
    out = tmp_path / "out"
    out.mkdir()
    step = out / "bricks_height_csm.png"
    shutil.copy(SAMPLES / "bricks_height.png", step)
    scene.materials[0].csm = CsmSettings(step, 0.03, StepMapSettings(tile=(True, False), levels="none"))  # a stand-in
    obj.write(scene, out)
    assert (out / "brick_wall.obj").read_text() == (wall / "brick_wall.obj").read_text()
    mtl = (out / "brick_wall.mtl").read_text().splitlines()
    for kept in ["Kd 0.8 0.8 0.8", "map_Kd bricks_color.png", "map_Bump -bm 1 bricks_normal.png",
                 "disp -mm 0 0.03 bricks_height.png"]:
        assert kept in mtl
    for added in ["csm_map bricks_height_csm.png", "csm_depth 0.03", "csm_max_ratio 1", "csm_tile 1 0",
                  "csm_variant exact", "csm_steps 0"]:
        assert added in mtl
    for name in ["bricks_color.png", "bricks_normal.png", "bricks_height.png"]:
        assert (out / name).read_bytes() == (wall / name).read_bytes()


@pytest.mark.parametrize("ref", ["/etc/passwd", "../../../../etc/passwd", "C:\\Windows\\x.png"])
def test_paths_escaping_the_scene_are_refused(wall, ref):
    text = (wall / "brick_wall.mtl").read_text().replace("map_Kd bricks_color.png", f"map_Kd {ref}")
    (wall / "brick_wall.mtl").write_text(text)
    with pytest.raises(FormatError, match="refused"):
        obj.read(wall / "brick_wall.obj")


def test_textures_outside_are_copied_in_with_safe_names(wall, tmp_path):
    (wall / "sub").mkdir()
    shutil.move(wall / "brick_wall.obj", wall / "sub" / "brick_wall.obj")
    shutil.move(wall / "brick_wall.mtl", wall / "sub" / "brick_wall.mtl")
    text = (wall / "sub" / "brick_wall.mtl").read_text().replace(" bricks_", " ../bricks_")
    (wall / "sub" / "brick_wall.mtl").write_text(text)
    with pytest.raises(FormatError, match="outside the scene's folder"):
        obj.read(wall / "sub" / "brick_wall.obj")
    scene = obj.read(wall / "sub" / "brick_wall.obj", allow_outside=True)
    assert scene.materials[0].height is not None
    out = tmp_path / "out"
    out.mkdir()
    obj.write(scene, out)
    mtl = (out / "brick_wall.mtl").read_text()
    assert "../" not in mtl and "map_Kd bricks_color.png" in mtl
    assert sorted(p.name for p in out.iterdir()) == ["brick_wall.mtl", "brick_wall.obj", "bricks_color.png",
                                                     "bricks_height.png", "bricks_normal.png"]


def test_missing_texture_and_library_warn(wall):
    (wall / "bricks_height.png").unlink()
    scene = obj.read(wall / "brick_wall.obj")
    assert scene.materials[0].height is None
    assert any("'bricks'" in w and "bricks_height.png" in w for w in map(str, scene.warnings))
    (wall / "brick_wall.mtl").unlink()
    assert any("brick_wall.mtl is missing" in w for w in map(str, obj.read(wall / "brick_wall.obj").warnings))


@pytest.mark.parametrize("bad", ["f 1/1/1 2/2/1 99/1/1", "v 1 x 0", "f 1/1/1 2/2/1 3/400/1"])
def test_malformed_geometry_names_file_and_line(wall, bad):
    (wall / "brick_wall.obj").write_text((wall / "brick_wall.obj").read_text() + bad + "\n")
    with pytest.raises(FormatError, match=r"brick_wall.obj: line \d+"):
        obj.read(wall / "brick_wall.obj")
