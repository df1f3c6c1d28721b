"""verify --shadows and bench trade --shadows against the real CLI: exit codes, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import copy_samples, random_field, skip_without_gl

from csm_assets.stepmap import DEFAULTS, make_step_map, save_step_map

FAST = ("--size", "32", "--views", "90", "40/200")


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()


@pytest.fixture
def height_png(tmp_path):
    from PIL import Image

    path = tmp_path / "h.png"
    Image.fromarray(np.round(random_field(32, 21, smooth=1.5) * 255).astype(np.uint8)).save(path)
    return path


def test_verify_shadows_passes_with_json(height_png):
    with Attack(height_png):
        r = run_cli("verify", height_png, *FAST, "--shadows", "--light-elevation", "20", "70",
                    "--light-azimuth", "0", "--json")
    assert_clean_run(r, 0)
    d = json.loads(r.stdout)
    assert d["passed"] and d["shadows"]["passed"]
    rows = d["shadows"]["views"]
    assert [(v["elevation"], v["light_elevation"]) for v in rows] == [(90, 20), (90, 70), (40, 20), (40, 70)]
    assert all(v["disagreement"] <= 0.01 and v["mean_fetches"] > v["mean_shadow_fetches"] > 0 for v in rows)


def test_verify_shadows_fails_on_a_forged_step_map(tmp_path):
    sm = make_step_map(random_field(48, 6, smooth=1.5), DEFAULTS)
    sm.pixels[..., 1] = 255  # every cone widened to max_ratio: shadow rays step through occluders
    path = tmp_path / "forged_csm.png"
    save_step_map(sm, path)
    r = run_cli("verify", path, "--size", "64", "--views", "90", "40/200", "--depth", "0.3", "--shadows",
                "--light-elevation", "20",
                "--light-azimuth", "0", "--max-error", "1000")
    assert_clean_run(r, 1)
    assert r.stdout.splitlines()[-1].startswith("FAIL: worst disagreement")


@pytest.mark.parametrize("args, what", [
    (("--shadows", "--light-elevation", "91"), "--light-elevation"),
    (("--shadows", "--light-elevation", "nan"), "--light-elevation"),
    (("--shadows", "--light-azimuth", "inf"), "--light-azimuth"),
    (("--shadows", "--light-size", "-0.1"), "--light-size"),
    (("--shadows", "--max-disagreement", "101"), "--max-disagreement"),
    (("--light-elevation", "30"), "--shadows"),
    (("--shadows", "--light-elevation", "x"), "--light-elevation"),
])
def test_bad_shadow_options_are_exit_2(height_png, args, what):
    with Attack(height_png):
        r = run_cli("verify", height_png, "--size", "16", "--views", "90", *args)
    assert what in assert_clean_error(r, 2)


def test_bench_trade_shadows_bad_light_is_exit_2(height_png):
    r = run_cli("bench", "trade", height_png, "--views", "90", "--shadows", "95/0")
    assert "--shadows" in assert_clean_error(r, 2)


def test_verify_shadows_on_a_converted_scene(tmp_path):
    src = copy_samples(tmp_path / "in", ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png",
                                         "bricks_height.png"))
    assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "out", "-q"), 0)
    scene = tmp_path / "out" / "brick_wall.gltf"
    with Attack(scene):
        r = run_cli("verify", scene, *FAST, "--shadows", "--light-elevation", "25", "--light-azimuth", "0", "180",
                    "--json", "--images", tmp_path / "pics")
    assert_clean_run(r, 0)
    d = json.loads(r.stdout)["shadows"]
    assert d["passed"] and len(d["views"]) == 4 and all(v["pixels"] > 100 for v in d["views"])
    assert sorted(p.name for p in (tmp_path / "pics").glob("shadow_*.png"))
