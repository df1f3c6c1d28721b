"""Output names (issue 14): one free-name rule for every writer, so a scene converted into a
folder where another scene already put a file of the same name and other content gets a
copy under a free name (exit 0), while an output that would overwrite an input stays exit 4.
Every CLI case runs through tests/attack.py."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli, tree_hashes
from conftest import GLTF_WALL, copy_samples
from PIL import Image
from usd_stages import USD_WALL

from csm_assets.convert.output_folder import free_name


def _heights(path: Path, seed: int) -> None:
    Image.fromarray((np.random.default_rng(seed).random((32, 32)) * 255).astype(np.uint8)).save(path)


def test_free_name_counts_up_and_shares_identical_files(tmp_path):
    (tmp_path / "a.png").write_bytes(b"theirs")
    others = {"a.png": tmp_path / "a.png"}
    assert free_name("a", ".png", set()) == "a.png"
    assert free_name("a", ".png", {"a.png", "a_1.png"}) == "a_2.png"
    assert free_name("a", ".png", lambda n: n.startswith("a.")) == "a_1.png"
    assert free_name("a", ".png", set(), others, content=b"mine") == "a_1.png"
    assert free_name("a", ".png", set(), others, content=b"theirs") == "a.png"  # shared: same bytes
    assert free_name("a", ".png", set(), others) == "a_1.png"  # unknown content: never theirs
    (tmp_path / "mine.png").write_bytes(b"theirs")
    assert free_name("a", ".png", set(), others, content=tmp_path / "mine.png") == "a.png"
    assert free_name("a", ".png", set(), {"a.png": tmp_path / "gone.png"}) == "a.png"  # no file there now


def _two_scenes(tmp_path: Path, files, scene: str, ext: str) -> tuple[Path, Path]:
    paths = []
    for s, seed in (("a", 1), ("b", 2)):
        folder = copy_samples(tmp_path / s, files)
        _heights(folder / "bricks_height.png", seed)
        paths.append((folder / scene).rename(folder / f"wall_{s}{ext}"))
    return paths[0], paths[1]


def test_gltf_scenes_sharing_a_folder_get_their_own_texture_copies(tmp_path):
    a, b = _two_scenes(tmp_path, GLTF_WALL, "brick_wall.gltf", ".gltf")
    out = tmp_path / "out"
    with Attack(tmp_path / "a", tmp_path / "b"):
        assert_clean_run(run_cli("convert", a, "-o", out))
        first = tree_hashes(out)
        assert_clean_run(run_cli("convert", b, "-o", out))
    after = tree_hashes(out)
    assert all(after[f] == h for f, h in first.items() if not f.endswith("csm-manifest.json"))
    uris = {s: [im["uri"] for im in json.loads((out / f"wall_{s}.gltf").read_text())["images"]] for s in "ab"}
    assert "bricks_height.png" in uris["a"] and "bricks_height_1.png" in uris["b"]
    assert "bricks_color.png" in uris["b"]  # identical bytes: shared, not copied twice
    assert (out / "bricks_height_1.png").read_bytes() == (tmp_path / "b" / "bricks_height.png").read_bytes()
    buffers = json.loads((out / "wall_b.gltf").read_text())["buffers"]
    assert buffers[0]["uri"] == "brick_wall.bin" or (out / buffers[0]["uri"]).is_file()
    for s in (a, b):
        assert_clean_run(run_cli("check", s, "-o", out))
        assert_clean_run(run_cli("verify", out / s.name))


def test_usd_scenes_sharing_a_folder_get_their_own_texture_copies(tmp_path):
    from pxr import Usd, UsdShade

    a, b = _two_scenes(tmp_path, USD_WALL, "brick_wall.usda", ".usda")
    out = tmp_path / "out"
    with Attack(tmp_path / "a", tmp_path / "b"):
        assert_clean_run(run_cli("convert", a, "-o", out))
        assert_clean_run(run_cli("convert", b, "-o", out))
    stage = Usd.Stage.Open(str(out / "wall_b.usda"))
    files = {str(UsdShade.Shader(p).GetInput("file").Get().path) for p in stage.Traverse()
             if p.IsA(UsdShade.Shader) and UsdShade.Shader(p).GetInput("file")}
    assert "./bricks_height_1.png" in files, files
    assert (out / "bricks_height_1.png").read_bytes() == (tmp_path / "b" / "bricks_height.png").read_bytes()
    for s in (a, b):
        assert_clean_run(run_cli("check", s, "-o", out))


def test_an_output_over_an_input_is_still_refused(tmp_path):
    """The scene's texture lives in the output folder under the name its copy would take: the
    free-name rule does not rename around inputs, it refuses (exit 4), nothing written."""
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    out = tmp_path / "out"
    out.mkdir()
    scene = folder / "brick_wall.gltf"
    (out / "bricks_color.png").write_bytes((folder / "bricks_color.png").read_bytes())
    doc = json.loads(scene.read_text())
    for im in doc["images"]:
        if im["uri"] == "bricks_color.png":
            im["uri"] = "../out/bricks_color.png"
    scene.write_text(json.dumps(doc))
    before = tree_hashes(out)
    with Attack(folder, out / "bricks_color.png"):
        r = run_cli("convert", scene, "-o", out, "--allow-outside-paths")
    assert "overwrite the input" in assert_clean_error(r, 4, "bricks_color.png")
    assert tree_hashes(out) == before


# ---- material names on the command line: the empty name OBJ allows --------------------------------

def _unnamed_obj(folder: Path) -> Path:
    """The OBJ wall with its material named "" (``newmtl`` alone, ``usemtl`` alone)."""
    from conftest import OBJ_WALL

    copy_samples(folder, OBJ_WALL)
    mtl = folder / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("newmtl bricks", "newmtl"))
    obj = folder / "brick_wall.obj"
    obj.write_text(obj.read_text().replace("usemtl bricks", "usemtl"))
    return obj


@pytest.mark.parametrize("flags", [["--height", "=HEIGHT"], ["--height", '""=HEIGHT'],
                                   ["--depth-map", "=HEIGHT"], ["--height", "=HEIGHT", "--depth", "=0.2"],
                                   ["--height", '""=HEIGHT', "--depth", '""=0.2']])
def test_the_empty_material_name_is_addressable(tmp_path, flags):
    obj = _unnamed_obj(tmp_path / "in")
    height = tmp_path / "in" / "bricks_height.png"
    args = [f.replace("HEIGHT", str(height)) for f in flags]
    with Attack(tmp_path / "in"):
        assert_clean_run(run_cli("convert", obj, "-o", tmp_path / "out", *args))
    mtl = (tmp_path / "out" / "brick_wall.mtl").read_text().splitlines()
    assert "csm_map bricks_height_csm.png" in mtl
    if "--depth" in flags:
        assert "csm_depth 0.2" in mtl
    assert_clean_run(run_cli("check", obj, "-o", tmp_path / "out", *args))


def test_the_empty_name_through_the_library_with_a_height_input(tmp_path):
    """The library's ``heights`` takes a HeightInput for any format's reader, the empty name too."""
    from csm_assets.convert.pipeline import convert
    from csm_assets.scene import HeightInput, Texture

    obj = _unnamed_obj(tmp_path / "in")
    h = HeightInput(Texture("bricks_height", path=tmp_path / "in" / "bricks_height.png"), depth=0.05)
    report = convert(obj, tmp_path / "out", heights={"": h})
    assert list(report.step_maps) == ["bricks_height_csm"]


def test_a_material_name_no_scene_has(tmp_path):
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    with Attack(folder):
        r = run_cli("convert", folder / "brick_wall.gltf", "-o", tmp_path / "out", "--height",
                    f"={folder / 'bricks_height.png'}")
    line = assert_clean_error(r, 2, "brick_wall.gltf")
    assert "its materials: 'bricks'" in line and line.count("brick_wall.gltf") == 1, line


@pytest.mark.parametrize("flags, said", [
    (["--light-size", "-0.1", "--self-shadow"], "--light-size"), (["--light-size", "nan", "--self-shadow"], "--light-size"),
    (["--light-size", "inf", "--self-shadow"], "--light-size"), (["--light-size", "wide", "--self-shadow"], "--light-size"),
    (["--light-size", "0.1"], "--self-shadow")])
def test_bad_self_shadow_flags(tmp_path, flags, said):
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    with Attack(folder):
        r = run_cli("convert", folder / "brick_wall.gltf", "-o", tmp_path / "out", *flags)
    assert said in assert_clean_error(r, 2)
    assert not (tmp_path / "out").exists()


def test_self_shadow_flags_reach_the_material_and_the_manifest(tmp_path):
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    out = tmp_path / "out"
    scene = folder / "brick_wall.gltf"
    with Attack(folder):
        assert_clean_run(run_cli("convert", scene, "-o", out, "--self-shadow", "--light-size", "0.03"))
        ext = json.loads((out / "brick_wall.gltf").read_text())["materials"][0]["extensions"][
            "EXT_materials_cone_step_mapping"]
        assert ext["selfShadow"] is True and ext["lightSize"] == 0.03
        assert_clean_run(run_cli("check", scene, "-o", out, "--self-shadow", "--light-size", "0.03"))
        assert run_cli("check", scene, "-o", out).returncode == 1  # other settings: stale
