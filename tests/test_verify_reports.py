"""What verify shows (issue 23): a map's contact sheet, no step count for variants that take
none, long primitive names kept readable, the light size --shadows used in its header."""

from __future__ import annotations

import numpy as np
from PIL import Image

from attack import assert_clean_run, run_cli
from conftest import GLTF_WALL, SAMPLES, copy_samples
from csm_assets.verify.maps import VariantReport, ViewStats
from csm_assets.verify.scene import PrimitiveReport, SceneReport, format_scene_report
from csm_assets.verify.stats import fit


def test_a_maps_images_include_the_contact_sheet_and_exact_shows_no_steps(tmp_path):
    made = tmp_path / "s.png"
    assert_clean_run(run_cli("stepmap", SAMPLES / "bricks_height.png", "-o", made))
    r = run_cli("verify", made, "--images", tmp_path / "pics", "--views", "90", "10/45",
                "--variant", "exact", "--variant", "loop")
    assert r.returncode == 1 and "to fix: more --steps for loop" in r.stdout and "--bits" not in r.stdout, r.stdout
    sheet = Image.open(tmp_path / "pics" / "contact_sheet.png")
    assert sheet.size[0] >= 3 * 2 * 128 and sheet.size[1] > 2 * 128  # 4 pictures: a row of 3, then one
    rows = [line.split() for line in r.stdout.splitlines() if line.startswith(("exact", "loop"))]
    assert {row[1] for row in rows if row[0] == "exact"} == {"-"}
    assert {row[1] for row in rows if row[0] == "loop"} == {"16"}


def test_long_primitive_names_keep_their_start_and_end():
    name = "/World/Ship/Hull/Planks/Starboard/Plank_0042_LOD0_mesh"
    views = [ViewStats(10.0, 45.0, 100, 0.1, 0.2, 0.3, 0.0, 0.0, 5.0, 9)]
    prims = [PrimitiveReport(name, "Wood_Planks_Weathered", variants=[VariantReport("exact", 0, views)]),
             PrimitiveReport(name.replace("0042", "0043"), "Wood_Planks_Weathered",
                             variants=[VariantReport("exact", 0, views)])]
    text = format_scene_report(SceneReport("ship.usda", 128, 1.0, "llvmpipe", ["10/45"], prims))
    rows = [line for line in text.splitlines() if "_004" in line]
    assert len(rows) == 2 and rows[0] != rows[1]  # the two primitives stay apart
    assert all("/World/Ship" in r and "Wood_Planks_Weathered" in r for r in rows)
    assert fit("a" * 10, 10) == "a" * 10 and fit("abcdefghijkl", 9) == "ab...ijkl" and len(fit("x" * 99, 64)) == 64


def test_shadows_header_shows_the_materials_own_light_size(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", out, "--self-shadow", "--light-size", "0.05"))
    r = run_cli("verify", out / "brick_wall.gltf", "--shadows", "--views", "60", "--no-cameras", "--size", "48")
    header = next(line for line in r.stdout.splitlines() if line.startswith("verify --shadows"))
    assert "light size 0.05 rad (each material's own lightSize)" in header, header
    r = run_cli("verify", out / "brick_wall.gltf", "--shadows", "--views", "60", "--no-cameras", "--size", "48",
                "--light-size", "0")
    header = next(line for line in r.stdout.splitlines() if line.startswith("verify --shadows"))
    assert "light size 0 rad," in header, header
    assert np.isfinite(0.05)
