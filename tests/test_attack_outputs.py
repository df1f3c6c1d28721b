"""Attacks on the outputs: shared output folders, clashes, inputs in the way, bad manifests.
Every case runs the real CLI (tests/attack.py): exit code, one error line naming the file,
no traceback, inputs hashed before and after, outputs intact or absent. (Disk full:
tests/test_attack_diskfull.py; reports, --strict, kills and Ctrl-C: tests/test_attack_runs.py.)"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli, tree_hashes
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from PIL import Image

from csm_assets.formats import read_step_map


def _heights(path: Path, seed: int, shape=(32, 32)) -> np.ndarray:
    h = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    Image.fromarray(h).save(path)
    return h


def obj_scene(folder: Path, name: str, seed: int) -> Path:
    """An OBJ scene ``name`` in ``folder`` (the sample wall, its own MTL) whose height
    texture ``bricks_height.png`` holds random heights of ``seed``."""
    copy_samples(folder, OBJ_WALL)
    scene = folder / name
    (folder / "brick_wall.obj").rename(scene)
    _heights(folder / "bricks_height.png", seed)
    return scene


def mtl_statement(mtl: Path, keyword: str) -> str:
    return next(line.split()[-1] for line in mtl.read_text().splitlines() if line.startswith(keyword))


# ---- issue 11: one output folder, many scenes --------------------------------------------------

def test_scenes_one_after_the_other_never_share_a_step_map_of_other_content(tmp_path):
    """Height textures of one name and other content (given with --height, so not copied):
    each scene gets its own step map, and the manifest tells the truth for each."""
    scenes = {}
    for s, seed in (("a", 1), ("b", 2)):
        folder = copy_samples(tmp_path / s, OBJ_WALL)
        mtl = folder / f"wall_{s}.mtl"
        (folder / "brick_wall.mtl").rename(mtl)
        mtl.write_text("\n".join(x for x in mtl.read_text().splitlines() if not x.startswith("disp")) + "\n")
        scenes[s] = folder / f"wall_{s}.obj"
        (folder / "brick_wall.obj").rename(scenes[s])
        scenes[s].write_text(scenes[s].read_text().replace("brick_wall.mtl", mtl.name))
        _heights(folder / "height.png", seed)
    out = tmp_path / "out"
    with Attack(tmp_path / "a", tmp_path / "b"):
        for s in "ab":
            assert_clean_run(run_cli("convert", scenes[s], "-o", out, "--height",
                                     f"bricks={tmp_path / s / 'height.png'}"))
    maps = {s: out / mtl_statement(out / f"wall_{s}.mtl", "csm_map") for s in "ab"}
    assert maps["a"].name == "height_csm.png" and maps["b"].name == "height_csm_1.png"
    assert [mtl_statement(out / f"wall_{s}.mtl", "csm_map_levels") for s in "ab"] == \
        ["height_csm_levels.png", "height_csm_1_levels.png"]  # the default chain: levels of its own too
    for s in "ab":  # each scene's map holds its own heights (R = height)
        expect = np.asarray(Image.open(tmp_path / s / "height.png"))
        assert np.array_equal(read_step_map(maps[s])[..., 0], expect), s
    m = json.loads((out / "csm-manifest.json").read_text())["scenes"]
    assert set(m) == {"wall_a.obj", "wall_b.obj"}
    assert maps["a"].name in m["wall_a.obj"]["outputs"] and maps["b"].name in m["wall_b.obj"]["outputs"]
    for s in "ab":  # both fresh; a forced rerun of a keeps its own names
        assert_clean_run(run_cli("check", scenes[s], "-o", out, "--height", f"bricks={tmp_path / s / 'height.png'}"))
    assert_clean_run(run_cli("convert", scenes["a"], "-o", out, "--force", "--height",
                             f"bricks={tmp_path / 'a' / 'height.png'}"))
    assert mtl_statement(out / "wall_a.mtl", "csm_map") == "height_csm.png"
    assert np.array_equal(read_step_map(maps["b"])[..., 0], np.asarray(Image.open(tmp_path / "b" / "height.png")))


def test_copied_textures_of_one_name_and_other_content_are_renamed(tmp_path):
    """A texture copy that would replace another scene's file of other content is copied under
    a free name instead (issue 14): both scenes convert, each MTL names its own copy, the
    first scene's outputs stay as they were and fresh."""
    a = obj_scene(tmp_path / "a", "wall_a.obj", 1)
    b = obj_scene(tmp_path / "b", "wall_b.obj", 2)
    (tmp_path / "b" / "brick_wall.mtl").rename(tmp_path / "b" / "wall_b.mtl")
    b.write_text(b.read_text().replace("mtllib brick_wall.mtl", "mtllib wall_b.mtl"))
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", a, "-o", out))
    before = tree_hashes(out)
    with Attack(tmp_path / "a", tmp_path / "b"):
        assert_clean_run(run_cli("convert", b, "-o", out))
    after = tree_hashes(out)
    assert all(after[f] == h for f, h in before.items() if not f.endswith("csm-manifest.json"))
    assert mtl_statement(out / "brick_wall.mtl", "disp") == "bricks_height.png"
    assert mtl_statement(out / "wall_b.mtl", "disp") == "bricks_height_1.png"
    assert (out / "bricks_height_1.png").read_bytes() == (tmp_path / "b" / "bricks_height.png").read_bytes()
    assert (out / "bricks_color.png").read_bytes() == (tmp_path / "b" / "bricks_color.png").read_bytes()
    assert not (out / "bricks_color_1.png").exists()  # the same bytes: one shared file
    for scene in (a, b):
        assert_clean_run(run_cli("check", scene, "-o", out))


@pytest.mark.parametrize("cones", ["conservative", "quadrant"])
def test_scenes_sharing_one_mtl_library_share_it_when_identical(tmp_path, cones):
    """Two OBJ files of one folder naming one MTL (a common layout): both convert, sharing the MTL,
    the step map and its levels images (the default chain; a map that names its other files,
    levels or a quadrant map's second image, is shared when every one of them is identical)."""
    src = obj_scene(tmp_path / "in", "one.obj", 3)
    shutil.copy(src, tmp_path / "in" / "two.obj")
    out = tmp_path / "out"
    with Attack(tmp_path / "in"):
        assert_clean_run(run_cli("convert", src, "-o", out, "--cones", cones))
        before = tree_hashes(out)
        assert_clean_run(run_cli("convert", tmp_path / "in" / "two.obj", "-o", out, "--cones", cones))
    for scene in (src, tmp_path / "in" / "two.obj"):
        assert_clean_run(run_cli("check", scene, "-o", out, "--cones", cones))
    after = tree_hashes(out)
    assert all(after[f] == h for f, h in before.items() if not f.endswith("csm-manifest.json"))
    assert {Path(f).name for f in set(after) - set(before)} == {"two.obj"}  # the rest shared
    assert mtl_statement(out / "brick_wall.mtl", "csm_map_levels") == "bricks_height_csm_levels.png"
    scenes = json.loads((out / "csm-manifest.json").read_text())["scenes"]
    assert scenes["one.obj"]["outputs"].keys() - {"one.obj"} == scenes["two.obj"]["outputs"].keys() - {"two.obj"}
    assert "bricks_height_csm_levels.png" in scenes["two.obj"]["outputs"]


def test_same_named_scenes_one_after_the_other_into_one_folder_are_refused(tmp_path):
    a = obj_scene(tmp_path / "a", "wall.obj", 1)
    b = obj_scene(tmp_path / "b", "wall.obj", 2)
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", a, "-o", out))
    before = tree_hashes(out)
    with Attack(tmp_path / "a", tmp_path / "b"):
        r = run_cli("convert", b, "-o", out)
    assert "another scene" in assert_clean_error(r, 4, "wall.obj")
    assert tree_hashes(out) == before


def test_same_named_scenes_converted_together_go_to_distinct_folders(tmp_path):
    a = obj_scene(tmp_path / "a", "wall.obj", 1)
    b = obj_scene(tmp_path / "b", "wall.obj", 2)
    out = tmp_path / "out"
    with Attack(tmp_path / "a", tmp_path / "b"):
        r = run_cli("convert", a, b, "-o", out, "--json")
    assert_clean_run(r)
    dirs = sorted(Path(x["out_dir"]).relative_to(out).as_posix() for x in json.loads(r.stdout)["results"])
    assert dirs == ["a/wall_obj", "b/wall_obj"]
    for s in "ab":
        mtl = out / s / "wall_obj" / "brick_wall.mtl"
        got = read_step_map(mtl.parent / mtl_statement(mtl, "csm_map"))[..., 0]
        assert np.array_equal(got, np.asarray(Image.open(tmp_path / s / "bricks_height.png")))


# ---- name clashes inside one conversion --------------------------------------------------------

@pytest.mark.parametrize("texture", ["brick_wall.obj", "brick_wall.mtl", "csm-manifest.json"])
def test_a_texture_named_like_the_scene_mtl_or_manifest_gets_its_own_name(tmp_path, texture):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    (src / "tex").mkdir()
    shutil.copy(src / "bricks_color.png", src / "tex" / texture)
    mtl = src / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("map_Kd bricks_color.png", f"map_Kd tex/{texture}"))
    out = tmp_path / "out"
    with Attack(src):
        assert_clean_run(run_cli("convert", src / "brick_wall.obj", "-o", out))
    assert (out / "brick_wall.obj").read_text() == (src / "brick_wall.obj").read_text()
    assert "newmtl bricks" in (out / "brick_wall.mtl").read_text()
    copy = mtl_statement(out / "brick_wall.mtl", "map_Kd")
    assert copy != texture and (out / copy).read_bytes() == (src / "bricks_color.png").read_bytes()
    json.loads((out / "csm-manifest.json").read_text())
    assert_clean_run(run_cli("check", src / "brick_wall.obj", "-o", out))


def test_a_gltf_image_named_like_the_scene_gets_its_own_name(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    (src / "tex").mkdir()
    shutil.copy(src / "bricks_color.png", src / "tex" / "brick_wall.gltf")
    doc = json.loads((src / "brick_wall.gltf").read_text())
    for image in doc["images"]:
        if image["uri"] == "bricks_color.png":
            image["uri"] = "tex/brick_wall.gltf"
    (src / "brick_wall.gltf").write_text(json.dumps(doc))
    out = tmp_path / "out"
    with Attack(src):
        assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", out))
    written = json.loads((out / "brick_wall.gltf").read_text())
    uris = [i["uri"] for i in written["images"]]
    assert "brick_wall.gltf" not in uris and all((out / u).is_file() for u in uris)


# ---- inputs are never outputs ------------------------------------------------------------------

def test_mtl_library_in_the_output_folder_is_refused(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    (src / "lib").mkdir()
    (src / "brick_wall.mtl").rename(src / "lib" / "brick_wall.mtl")
    for png in ("bricks_color.png", "bricks_height.png", "bricks_normal.png"):
        shutil.move(src / png, src / "lib" / png)
    obj = src / "brick_wall.obj"
    obj.write_text(obj.read_text().replace("mtllib brick_wall.mtl", "mtllib lib/brick_wall.mtl"))
    with Attack(src):
        for _ in range(2):  # a rerun must not append either
            r = run_cli("convert", obj, "-o", src / "lib")
            line = assert_clean_error(r, 4, "would overwrite the input")
            assert line.split(": ")[2].startswith(str(src / "lib")), line
    assert sorted(p.name for p in (src / "lib").iterdir()) == [
        "brick_wall.mtl", "bricks_color.png", "bricks_height.png", "bricks_normal.png"]


def test_output_folder_linked_to_the_input_folder_is_refused(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    (tmp_path / "link").symlink_to(src, target_is_directory=True)
    with Attack(src):
        r = run_cli("convert", src / "brick_wall.obj", "-o", tmp_path / "link")
    assert_clean_error(r, 4, "link")


@pytest.mark.parametrize("which", ["scene", "texture", "output", "manifest"])
def test_report_never_overwrites_an_input_or_an_output(tmp_path, which):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    out = tmp_path / "out"
    target = {"scene": src / "brick_wall.obj", "texture": src / "bricks_height.png",
              "output": out / "brick_wall.mtl", "manifest": out / "csm-manifest.json"}[which]
    if which in ("output", "manifest"):
        assert_clean_run(run_cli("convert", src / "brick_wall.obj", "-o", out))
    before = tree_hashes(out) if out.exists() else {}
    with Attack(src):
        r = run_cli("convert", src / "brick_wall.obj", "-o", out, "--report", target, "--force")
    assert_clean_error(r, 4, target.name)
    if which in ("output", "manifest"):
        assert tree_hashes(out) == before or which == "output"  # --force may rewrite equal bytes
        assert_clean_run(run_cli("check", src / "brick_wall.obj", "-o", out))


# ---- manifests of the wrong shape, keys outside the scene -------------------------------------

@pytest.mark.parametrize("content", ["[]", '{"version": 3}', '{"version": "0.1.0", "scenes": []}',
                                     '{"version": "0.1.0", "scenes": {"brick_wall.obj": {"settings": {}, '
                                     '"inputs": [], "outputs": {}}}}', "not json"])
def test_manifest_of_the_wrong_shape_is_a_clear_error(tmp_path, content):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    out = tmp_path / "out"
    out.mkdir()
    (out / "csm-manifest.json").write_text(content)
    with Attack(src, out):
        r = run_cli("convert", src / "brick_wall.obj", "-o", out)
        line = assert_clean_error(r, 4, "csm-manifest.json")
        assert "not a csm-assets manifest" in line
        r = run_cli("check", src / "brick_wall.obj", "-o", out)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "not a csm-assets manifest" in r.stdout


def test_check_never_hashes_files_outside_the_scene_folder(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", src / "brick_wall.obj", "-o", out))
    fifo = tmp_path / "secret"
    os.mkfifo(fifo)  # hashing it would block forever
    m = json.loads((out / "csm-manifest.json").read_text())
    for key in ("../secret", str(fifo)):
        m["scenes"]["brick_wall.obj"]["inputs"][key] = "0" * 64
        (out / "csm-manifest.json").write_text(json.dumps(m))
        r = run_cli("check", src / "brick_wall.obj", "-o", out, timeout=60)
        assert r.returncode == 1 and "outside the scene's folder" in r.stdout, r
        del m["scenes"]["brick_wall.obj"]["inputs"][key]
    m["scenes"]["brick_wall.obj"]["outputs"]["../secret"] = "0" * 64
    (out / "csm-manifest.json").write_text(json.dumps(m))
    r = run_cli("check", src / "brick_wall.obj", "-o", out, timeout=60)
    assert r.returncode == 1 and "not a plain file name" in r.stdout
