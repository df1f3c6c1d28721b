"""``verify --distance``: the map far away against a supersampled exact reference."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import skip_without_gl
from csm_assets.map_file import load_packed, load_step_maps
from csm_assets.verify.distance import distance_view, distance_views, tiles_per_block, verify_distance
from csm_assets.verify.march import under_run

BRICKS = Path(__file__).resolve().parents[1] / "samples" / "bricks_height.png"  # 128², tiles


def run(*args):
    return subprocess.run([sys.executable, "-m", "csm_assets", "verify", *map(str, args)], capture_output=True,
                          text=True, timeout=900)


def test_views_span_the_texels_per_pixel_asked_for():
    for tpp, el, az in distance_views():
        v = distance_view((128, 128), tpp, el, az, 0.1)
        o, d = v.camera.rays(v.size, v.size)
        centre = v.size // 2 * v.size + v.size // 2
        hit = [o[i] - d[i] * o[i, 2] / d[i, 2] for i in (centre, centre + 1)]  # two pixels side by side
        assert np.linalg.norm(hit[1] - hit[0]) * v.uv_per_world * 128 == pytest.approx(tpp, rel=0.02)
        assert v.world_depth * v.uv_per_world == pytest.approx(0.1)


def test_tiles_count_the_4x4_texel_tiles_each_8x4_block_touches():
    # block 0 (pixel 0): a fetch by the corner, whose bilinear footprint wraps to texels 63 and 0
    # (tiles 15 and 0 along each axis: 4), and one at a texel centre (texels 16, 17: 1 tile);
    # block 1 (pixel 8): one fetch between texels 3 and 4 on both axes (4 tiles)
    uv = np.array([[[0.1, 0.1], [16.5, 0.5]], [[3.5, 3.5], [np.nan, np.nan]]]) / 64
    assert tiles_per_block(uv, np.array([0, 8]), 64, (64, 64)) == pytest.approx((5 + 4) / 2)


def test_under_run_is_the_longest_stretch_a_ray_spends_under_the_surface():
    h = np.zeros((8, 8, 4), np.float32)  # a float map: filtered in float
    h[:, 4, 0] = 1.0  # a ridge along v: its bilinear surface 1 - |8u - 4.5| for 8u in [3.5, 5.5]
    dp, ds = np.array([[0.0, 0.5]]), np.array([[1.0, 0.0, 0.8]])  # u = t at height 1 - 0.8t
    run = under_run(h, dp, ds, np.array([0.0]), np.array([1.0]), 0.004)  # under for t in (4.5/8.8, 4.5/7.2)
    assert run[0] == pytest.approx(4.5 / 7.2 - 4.5 / 8.8, abs=0.001)
    assert under_run(h, dp, ds, np.array([0.55]), np.array([1.0]), 0.004)[0] == pytest.approx(0.075, abs=0.001)
    assert under_run(h, dp, ds, np.array([0.0]), np.array([0.5]), 0.004)[0] == 0.0  # above it before


@pytest.fixture(scope="module")
def noise(tmp_path_factory):
    skip_without_gl()
    path = tmp_path_factory.mktemp("noise") / "noise.png"
    Image.fromarray((np.random.default_rng(1).random((80, 80)) * 255).astype(np.uint8)).save(path)
    (sm,) = load_step_maps(path, bits=8, bilinear_safe=True).values()
    return sm


def test_a_tip_thinner_than_the_minimum_step_is_no_way_through(noise):
    # white noise at 20 degrees: the 0.25-texel minimum step steps over tips thinner than itself
    # (0.4-0.5% of pixels land more than a texel behind, under the surface by up to 0.025 of the
    # range: counted as through before 2026-12-07), as conventions.md says it may; nothing wider
    s = noise.settings
    report = verify_distance(noise.pixels, max_ratio=s.max_ratio, min_step=s.min_step, size=32,
                             views=[(t, 20.0, 30.0) for t in (1.0, 4.0)])
    assert report.passed and all(r.today.through == 0.0 for r in report.views)


@pytest.fixture(scope="module")
def bricks():
    skip_without_gl()
    packed, max_ratio, _, min_step = load_packed(BRICKS)
    return packed, max_ratio, min_step


def test_today_never_goes_through_and_the_emulation_takes_the_render_steps(bricks):
    packed, max_ratio, min_step = bricks
    report = verify_distance(packed, max_ratio=max_ratio, min_step=min_step,
                             views=[(t, 20.0, 30.0) for t in (1.0, 16.0)])
    near, far = (r.today for r in report.views)
    assert report.passed and near.through == far.through == 0.0
    assert near.same_steps >= 0.99 and far.same_steps >= 0.99  # the numbers are the shipped shader's
    assert near.rmse < 0.05 and near.flicker == pytest.approx(1.0, abs=0.1)  # a pixel per texel: no aliasing
    assert far.rmse > 3 * near.rmse and far.flicker > 1.5  # far away the one-sample image aliases
    assert far.tiles > 4 * near.tiles and far.fetches == pytest.approx(near.fetches, rel=0.3)


def test_too_wide_cones_go_through_and_fail(bricks):
    packed, max_ratio, min_step = bricks
    wide = packed.copy()
    wide[..., 1] = 255  # every cone the widest: rays step over the bricks' edges
    report = verify_distance(wide, max_ratio=max_ratio, min_step=min_step, views=[(4.0, 20.0, 30.0)])
    assert not report.passed and report.views[0].today.through > 0.01


def test_cli_json_lists_one_record_per_view(tmp_path):
    skip_without_gl()
    r = run(BRICKS, "--distance", "--json", "--views", "45/30", "--size", "32")
    assert r.returncode == 0, r.stderr
    records = json.loads(r.stdout)
    assert [(x["texels_per_pixel"], x["elevation"], x["azimuth"]) for x in records] == \
        [(t, 45.0, 30.0) for t in (1.0, 4.0, 8.0, 16.0)]
    for x in records:  # a height map: verify makes the averaged chain (--levels average) and measures it too
        for march in ("today", "levels"):
            assert set(x[march]) >= {"rmse", "p95", "flicker", "fetches", "tiles", "through", "seam"}
            assert all(isinstance(v, (int, float)) and math.isfinite(v) for k, v in x[march].items() if k != "seam")
        assert x["today"]["seam"] is None and x["today"]["seam_pairs"] == 0  # level 0 everywhere: no seam
    text = run(BRICKS, "--distance", "--views", "90", "--size", "16")
    assert text.returncode == 0 and "PASS" in text.stdout and "tex/px" in text.stdout, text.stderr


def test_cli_refuses_what_it_cannot_measure(tmp_path):
    relaxed = tmp_path / "relaxed.png"
    made = subprocess.run([sys.executable, "-m", "csm_assets", "stepmap", str(BRICKS), "-o", str(relaxed),
                           "--cones", "relaxed"], capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stderr
    for args, words in (((BRICKS, "--distance", "--no-tile"), "does not tile"),
                        ((BRICKS, "--distance", "--variant", "loop"), "--variant"),
                        ((relaxed, "--distance"), "relaxed cones"),
                        ((Path(__file__).resolve().parents[1] / "samples" / "brick_wall.gltf", "--distance"),
                         "is a scene")):
        r = run(*args)
        assert r.returncode == 2 and words in r.stderr, (args, r.stderr)


def test_cli_marches_a_step_maps_stored_levels(tmp_path):
    """A step map file is measured with the levels it stores (stepmap's default chain, or max), none
    made for it; a map written with --levels none has no chain to march (``levels`` null)."""
    skip_without_gl()
    for name, levels in (("avg.png", ()), ("max.png", ("--levels", "max")), ("none.png", ("--levels", "none"))):
        made = subprocess.run([sys.executable, "-m", "csm_assets", "stepmap", str(BRICKS), "-o", str(tmp_path / name),
                               *levels], capture_output=True, text=True, timeout=300)
        assert made.returncode == 0, made.stderr
    records = {}
    for name in ("avg.png", "max.png", "none.png"):
        r = run(tmp_path / name, "--distance", "--json", "--views", "45/30", "--size", "16")
        assert r.returncode in (0, 1), r.stderr
        records[name] = json.loads(r.stdout)
    assert all(x["levels"] is None for x in records["none.png"])
    assert all(x["levels"] is not None for x in records["avg.png"] + records["max.png"])
    far = [(a["levels"], b["levels"]) for a, b in zip(records["avg.png"], records["max.png"])
           if a["texels_per_pixel"] >= 8]
    assert far and any(a != b for a, b in far)  # the max chain stored in max.png, not an averaged one made here
    assert [x["today"] for x in records["avg.png"]] == [x["today"] for x in records["none.png"]]


def test_seam_contrast_sees_a_jump_where_the_level_changes_and_nothing_else():
    """A jump the reference does not have, along the line where the level steps, stands out
    (contrast >> 1); the same image without it, or noise alike on both sides, does not (about 1);
    no level change: NaN."""
    from csm_assets.verify.distance_seams import seam_contrast

    rng = np.random.default_rng(3)
    ref = np.linspace(0, 1, 48)[None, :].repeat(32, 0)
    image = ref + rng.normal(0, 0.01, ref.shape)
    lod = np.where(np.arange(48)[None, :] < 20, 2, 3).repeat(32, 0)
    valid = np.ones(ref.shape, bool)
    hidden, share = seam_contrast(image, ref, lod, valid)
    assert 0.7 < hidden < 1.4 and share == pytest.approx(32 / (32 * 47 + 31 * 48))
    jump = image + np.where(lod == 3, 0.1, 0.0)
    assert seam_contrast(jump, ref, lod, valid)[0] > 5
    assert math.isnan(seam_contrast(image, ref, np.zeros_like(lod), valid)[0])
    valid[:, 19:21] = False  # the pairs across the change not held by both images: no seam to see
    assert math.isnan(seam_contrast(jump, ref, lod, valid)[0])


def test_level_seams_stand_out_no_more_than_other_pixel_pairs(bricks):
    """Far away the level march steps from one level to the next along lines across the image;
    the image jumps there, against the reference, about as much as between any two neighbours
    (measured 0.74-1.15 on this map at 4 to 16 texels a pixel, 45 and 20 degrees)."""
    packed, max_ratio, min_step = bricks
    (sm,) = load_step_maps(BRICKS, levels="average").values()
    report = verify_distance(packed, max_ratio=max_ratio, min_step=min_step, levels=sm.levels,
                             views=[(t, el, 30.0) for t in (8.0, 16.0) for el in (45.0, 20.0)])
    for r in report.views:
        assert math.isnan(r.today.seam) and r.today.seam_pairs == 0
        assert r.levels.seam_pairs > 0.003 and r.levels.seam < 1.4, r  # a line or more of pairs
