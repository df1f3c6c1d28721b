"""Huge and tiny depths everywhere a depth enters: refused up front naming where it came from, and
every exact trace bounded in cells (hangs: a subprocess timeout far above the bound, which is
seconds; before, convert --depth 1e30 ran past 200 s)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import SAMPLES, copy_samples, random_field

from csm_assets.depth import MAX_DEPTH_TEXELS, MIN_DEPTH_TEXELS, check_depth, depth_range, too_deep
from csm_assets.errors import OptionError
from csm_assets.stepmap import DEFAULTS, make_step_map
from csm_assets.verify.bits import choose_bits
from csm_assets.verify.trace import MIN_CELLS, trace_heightfield

HANG = 150  # seconds: far above the bound (each case here ends within seconds)
SCENE = ("brick_wall.glb", "brick_wall.bin", "bricks_height.png", "bricks_color.png", "bricks_normal.png")


# --- the library: the range, the tracer's budget, the bit choice ----------------------------

def test_range_is_2_to_the_24_texels_either_way_over_the_longer_side():
    lo, hi = depth_range((128, 512))
    assert (lo, hi) == (MIN_DEPTH_TEXELS / 512, MAX_DEPTH_TEXELS / 512)
    assert check_depth(hi, (128, 512)) == hi and check_depth(lo, (128, 512)) == lo
    for bad in (hi * 1.01, lo / 1.01, 1e30, 5e-324, 0.0, -1.0, math.inf, math.nan, "x"):
        with pytest.raises(OptionError, match="--depth"):
            check_depth(bad, (128, 512), "--depth")
    with pytest.raises(OptionError, match=r"2\^24 texels"):
        check_depth(1e30, (8, 8), "--depth")
    assert too_deep(hi, (128, 512)) == "" and "2^24" in too_deep(1e30, (128, 512))


def test_trace_budget_leaves_long_rays_unresolved_and_resolved_ones_exact():
    h = np.zeros((16, 16))
    h[3, 3] = 1.0
    n = 400
    rng = np.random.default_rng(3)
    o = np.column_stack([rng.random((n, 2)), np.ones(n)])
    d = np.column_stack([np.ones(n), np.zeros(n), -rng.uniform(1e-9, 1.0, n)])  # many nearly level rays
    uv, t, hit = trace_heightfield(h, o, d)
    uv_b, t_b, hit_b = trace_heightfield(h, o, d, budget=n * 40)
    unresolved = np.isnan(t_b)
    assert unresolved.any() and not hit_b[unresolved].any()
    assert np.array_equal(t_b[~unresolved], t[~unresolved]) and np.array_equal(hit_b[~unresolved], hit[~unresolved])
    # the level ones need more cells than the budget gives: a ray falling 1 in 1e9 uv runs 1.6e10 cells
    assert unresolved[np.abs(d[:, 2]) < 1e-3].all()


def test_trace_budget_gives_every_ray_min_cells():
    h = random_field(32, 5)
    n = 200
    rng = np.random.default_rng(4)
    o = np.column_stack([rng.random((n, 2)), np.ones(n)])
    d = np.column_stack([rng.normal(size=(n, 2)), -rng.uniform(0.05, 1.0, n)])
    _, t, _ = trace_heightfield(h, o, d)
    _, t_small, _ = trace_heightfield(h, o, d, budget=1)
    _, t_one, _ = trace_heightfield(h, o, d, max_cells=MIN_CELLS)
    assert not np.isnan(t).any()
    assert np.array_equal(np.isnan(t_small), np.isnan(t_one)) and np.isnan(t_small).sum() < n
    known = ~np.isnan(t_small)
    assert np.array_equal(t_small[known], t[known])


def test_bits_are_chosen_without_marching_where_nothing_can_be_measured():
    def pack(bits):
        return make_step_map(random_field(64, 9), DEFAULTS.replace(bits=bits)).pixels

    deep = choose_bits(pack, 1e30, allowed=(8, 16))
    assert "too deep to measure" in deep.reason and deep.bits in (8, 16)
    assert choose_bits(pack, 1e30, allowed=(8, 16), given=16).bits == 16
    shallow = choose_bits(pack, 1e-300, allowed=(8, 16))
    assert shallow.bits == 8 and "too shallow" in shallow.reason


def test_exporter_refuses_a_depth_nothing_can_be_measured_at():
    from csm_assets.exporters import convert_material

    for depth in (1e30, 3e38, 5e-324, math.inf):
        with pytest.raises(OptionError, match="depth_scale"):
            convert_material(random_field(16, 2), depth)


# --- the command line -----------------------------------------------------------------------

@pytest.mark.parametrize("depth", ["1e30", "5e-324", "1.7e308"])
def test_convert_refuses_huge_and_tiny_depth(tmp_path, depth):
    scene = copy_samples(tmp_path, SCENE) / "brick_wall.glb"
    with Attack(scene.parent):
        r = run_cli("convert", scene, "-o", tmp_path / "out", "--depth", depth, timeout=HANG)
    line = assert_clean_error(r, 2, "--depth")
    assert "nothing can be measured" in line and "2^24 texels" in line
    assert not (tmp_path / "out").exists()


def test_convert_bits_16_with_huge_depth_is_refused_too(tmp_path):
    scene = copy_samples(tmp_path, SCENE) / "brick_wall.glb"
    r = run_cli("convert", scene, "-o", tmp_path / "out", "--depth", "1e30", "--bits", "16", timeout=HANG)
    assert_clean_error(r, 2, "--depth")


def test_convert_deepest_accepted_depth_ends(tmp_path):
    """1e5 on the 128 x 128 bricks: 1.3e7 texels, inside the range; the bit choice's trace and march
    are bounded per view (about 8 s here, over 30 s before the march's budget)."""
    scene = copy_samples(tmp_path, SCENE) / "brick_wall.glb"
    r = run_cli("convert", scene, "-o", tmp_path / "out", "--depth", "1e5", "--bits", "16", timeout=HANG)
    assert_clean_run(r, 0)


def test_convert_material_depth_names_its_flag(tmp_path):
    scene = copy_samples(tmp_path, SCENE) / "brick_wall.glb"
    r = run_cli("convert", scene, "-o", tmp_path / "out", "--depth", "bricks=1e30", timeout=HANG)
    assert_clean_error(r, 2, "--depth bricks=D")


@pytest.mark.parametrize("toml", ["depth = 1e30\n", "depth = 5e-324\n", "[depth]\nbricks = 1e30\n"])
def test_config_depth_is_refused_naming_the_key_and_file(tmp_path, toml):
    folder = copy_samples(tmp_path, SCENE)
    (folder / "csm-assets.toml").write_text(toml)
    r = run_cli("convert", "brick_wall.glb", "-o", "out", timeout=HANG, cwd=folder)
    line = assert_clean_error(r, 2, "csm-assets.toml")
    assert "depth" in line and "nothing can be measured" in line


@pytest.mark.parametrize("args", [("verify", "--depth", "1e6"), ("verify", "--depth", "1e6", "--shadows"),
                                  ("bench", "trade", "--depth", "1e30"), ("bench", "trade", "--depth", "5e-324")])
def test_verify_and_bench_refuse_depths_before_drawing(args):
    height = SAMPLES / "bricks_height.png"
    r = run_cli(*args[:2 if args[0] == "bench" else 1], height, *args[2 if args[0] == "bench" else 1:], timeout=HANG)
    line = assert_clean_error(r, 2, "--depth")
    assert "128x128" in line


@pytest.mark.parametrize("factor", ["1e30", "1e-320", "0"])
def test_convert_refuses_a_scene_factor_nothing_can_be_measured_at_naming_the_material(tmp_path, factor):
    folder = copy_samples(tmp_path, ("brick_wall.obj", "brick_wall.mtl", "bricks_color.png", "bricks_normal.png",
                                     "bricks_height.png"))
    mtl = folder / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("disp -mm 0 0.03", f"disp -mm 0 {factor}"))
    r = run_cli("convert", folder / "brick_wall.obj", "-o", tmp_path / "out", timeout=HANG)
    line = assert_clean_error(r, 3, "material 'bricks'")
    assert "give --depth" in line and "NaN" not in line
    # --depth overrides the factor
    assert_clean_run(run_cli("convert", folder / "brick_wall.obj", "-o", tmp_path / "out", "--depth", "0.05",
                             timeout=HANG))


@pytest.mark.parametrize("scale", [1e30, 1e-30])
def test_stepmap_of_huge_and_tiny_altitudes_ends(tmp_path, scale):
    """stepmap has no depth (its bits are chosen at verify's 0.1): raw altitudes of any size end."""
    path = tmp_path / "z.txt"
    a = random_field(48, 7) * scale + (1.0 if scale < 1 else 0.0)
    path.write_text("\n".join(" ".join(f"{v:.17g}" for v in row) for row in a) + "\n")
    assert_clean_run(run_cli("stepmap", path, "-o", tmp_path / "z.png", timeout=HANG))


def test_verify_reports_a_stored_depth_too_deep_as_not_verifiable(tmp_path):
    import json

    from conftest import skip_without_gl

    skip_without_gl()
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", SAMPLES / "brick_wall.gltf", "-o", out, timeout=HANG))
    gltf = out / "brick_wall.gltf"
    d = json.loads(gltf.read_text())
    for m in d["materials"]:
        ext = m.get("extensions", {}).get("EXT_materials_cone_step_mapping")
        if ext:
            ext["depthScale"] = 1e30
    gltf.write_text(json.dumps(d))
    r = run_cli("verify", gltf, timeout=HANG)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "NOT VERIFIABLE" in r.stdout and "2^24 texels" in r.stdout
