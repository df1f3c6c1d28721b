"""The speed/accuracy trade: the report against independent references, the auto-pick on
held-out maps, the CLI, and finite, capped results at the extremes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import random_field, skip_without_gl, spike

from csm_assets import step_map
from csm_assets.cli import main
from csm_assets.render.renderer import Renderer, quad_field_to_world
from csm_assets.bench.trade import BENCH_CONFIGS, DEFAULT_CONFIGS, measure_trade, pick_settings, trade_heights
from csm_assets.verify.trace import trace_heightfield_world
from csm_assets.verify.maps import verify_step_map, view_camera

FEW = (("exact", 0), ("loop", 8), ("fixed", 8), ("parallax", 0), ("pom", 8), ("relief", 8))
EXTREME_VIEWS = ((90.0, 0.0), (1.0, 30.0))
SIZE = 48


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()




def assert_finite_and_capped(report, max_iterations):
    """Every number finite (an error is infinite only where a non-tiled map lets one side
    leave it: hit against miss) and iterations within each variant's bound."""
    tiled = all(report.tile)
    for row in report.rows:
        for x in (row.mean_error, row.mean_iterations, row.frame_ms):
            assert math.isfinite(x), row
        if tiled:
            assert math.isfinite(row.p95_error) and math.isfinite(row.max_error), row
        assert 0.0 <= row.wrong_share <= 1.0 and 0.0 <= row.nonconverged_share <= 1.0, row
        cap = {"exact": max_iterations, "parallax": 1, "loop": row.steps, "fixed": row.steps,
               "pom": row.steps + 1, "relief": row.steps + 1 + 8}[row.variant]  # relief: 8 binary steps
        assert row.max_iterations <= cap, row
        assert row.pixels > 0, row


# ---------------------------------------------------------------- independent references
def test_flat_map_every_variant_hits_the_polygon_exactly():
    packed = step_map(np.ones((8, 8)), tile=True, bits=8)
    report = measure_trade(packed, views=((90.0, 0.0), (35.0, 200.0), (5.0, 45.0)), size=SIZE)
    assert [(r.variant, r.steps) for r in report.rows] == list(DEFAULT_CONFIGS)
    for row in report.rows:
        assert row.p95_error < 1e-3 and row.max_error < 1e-3, row
        assert row.wrong_share == 0.0 and row.nonconverged_share == 0.0, row


def analytic_plane_hits(o, d, a, b, depth):
    """Hits of world rays on the field-space plane height = a + b u under the unit quad
    (quad_field_to_world), solved in closed form: (uv (N, 2), t (N,))."""
    inv = np.linalg.inv(quad_field_to_world(1.0, depth))
    fo = o @ inv[:3, :3].T + inv[:3, 3]
    fd = d @ inv[:3, :3].T
    t = (a + b * fo[:, 0] - fo[:, 2]) / (fd[:, 2] - b * fd[:, 0])
    return fo[:, :2] + t[:, None] * fd[:, :2], t


@pytest.mark.parametrize("elevation, azimuth", [(90.0, 0.0), (40.0, 20.0), (20.0, 200.0)])
def test_tilted_plane_matches_the_analytic_intersection(elevation, azimuth):
    n, a, b, depth = 32, 0.2, 0.6, 0.1
    u = (np.arange(n) + 0.5) / n
    height = np.tile(a + b * u, (n, 1))
    packed = step_map(height.astype(np.float32), tile=False, bits=32)
    report = measure_trade(packed, tile=False, configs=(("exact", 0), ("loop", 64)), views=((elevation, azimuth),),
                           size=SIZE, depth=depth)
    cam = view_camera(0.5, elevation, azimuth)
    o, d = cam.rays(SIZE, SIZE)
    want, _ = analytic_plane_hits(o, d, a, b, depth)
    inside = np.all((want > 0.5 / n + 1e-3) & (want < 1 - 0.5 / n - 1e-3), axis=1)
    assert inside.sum() > 300
    # the tracer the report compares with agrees with the closed form
    ref_uv, _, ref_hit = trace_heightfield_world(packed[..., 0].astype(np.float64), o, d,
                                                 quad_field_to_world(1.0, depth), tile=False)
    assert ref_hit[inside].all()
    np.testing.assert_allclose(ref_uv[inside], want[inside], atol=1e-4)
    # the report's errors agree with the render's distance from the closed form
    from csm_assets.render.renderer import Material

    with Renderer((SIZE, SIZE)) as r:
        for row in report.rows:
            res = r.render(Material(packed, depth=depth, tile=False), cam, variant=row.variant,
                           steps=max(row.steps, 1), max_iterations=report.max_iterations)
            sel = inside & res.covered.ravel()  # the polygon in front of the hit (the report's pixels)
            assert sel.sum() > 300
            err = np.hypot(*((res.hit_uv.reshape(-1, 2)[sel] - want[sel]) * n).T)
            assert row.mean_error == pytest.approx(err.mean(), abs=0.02), row
            assert row.p95_error == pytest.approx(np.percentile(err, 95), abs=0.05), row


def test_fewer_steps_cost_less_and_err_more():
    report = trade_heights(random_field(48, 3), size=SIZE, views=((60.0, 10.0), (15.0, 100.0)),
                           configs=[("loop", n) for n in (1, 4, 16, 64)])
    its = [r.mean_iterations for r in report.rows]
    errs = [r.p95_error for r in report.rows]
    assert its == [1.0, 4.0, 16.0, 64.0]
    assert errs[0] > errs[-1] and errs[0] > 1.0


def test_a_longer_minimum_step_costs_fewer_fetches_up_to_the_shaders_bound():
    """min_step above one texel (benchmarks/relaxed_trade.py's sweep) reaches the shader:
    exact and relaxed stop sooner, relaxed's search still lands near the surface; the bound
    is csm.glsl's CSM_MAX_MIN_STEP, and a step outside (0, bound] is refused."""
    from csm_assets.render.glsl import shader_source
    from csm_assets.render.renderer import MAX_MIN_STEP

    assert f"#define CSM_MAX_MIN_STEP {MAX_MIN_STEP:.1f}" in shader_source("csm.glsl")
    sm = step_map(random_field(48, 3), bilinear_safe=True)
    kw = dict(size=SIZE, views=((35.0, 10.0), (15.0, 100.0)), configs=[("exact", 0), ("relaxed", 2)], draws=1)
    rows = {w: measure_trade(sm, min_step=w, **kw).rows for w in (1.0, 4.0, MAX_MIN_STEP)}
    for k in range(2):
        its = [rows[w][k].mean_iterations for w in rows]
        assert its[0] > its[1] > its[2], its
    assert rows[4.0][1].p95_error < 1.0 < rows[4.0][0].p95_error  # the search refines, exact backs off
    for bad in (0.0, -1.0, math.nan, MAX_MIN_STEP * 1.01):
        with pytest.raises(ValueError, match="min_step"):
            measure_trade(sm, min_step=bad, **kw)


# ---------------------------------------------------------------- the auto-pick on held-out maps
@pytest.mark.parametrize("seed", [101, 202])
@pytest.mark.parametrize("budget", [1.0, 0.3])
def test_pick_meets_the_budget_on_held_out_maps_and_views(seed, budget):
    packed = step_map(random_field(64, seed), tile=True, bits=8)
    row, met, report = pick_settings(packed, budget)
    assert met and row.p95_error <= budget
    assert all(r.mean_iterations >= row.mean_iterations for r in report.rows if r.p95_error <= budget)
    # checked at the full view set, a larger render, by verify
    check = verify_step_map(packed, variants=(row.variant,), steps=max(row.steps, 1), size=64, max_error=budget)
    assert check.passed, (row.label, [v.p95_error for v in check.variants[0].views])


def test_pick_refuses_a_bad_budget_and_says_when_none_meets_it():
    packed = step_map(random_field(32, 5), tile=True, bits=8)
    with pytest.raises(ValueError, match="max_error"):
        pick_settings(packed, 0.0)
    row, met, report = pick_settings(packed, 1e-9, configs=(("loop", 1), ("parallax", 0)))
    assert not met and row == report.best()


# ---------------------------------------------------------------- extremes
@pytest.mark.parametrize("name, heights, depth, tile", [
    ("flat", np.full((16, 16), 0.5), 0.1, True),
    ("spike", spike((16, 16), (8, 8)), 0.1, True),
    ("one texel", np.full((1, 1), 0.7), 0.1, True),
    ("shallow", random_field(32, 7), 0.001, True),
    ("deep", random_field(32, 7), 10.0, True),
    ("deep spike, not tiled", spike((16, 16), (8, 8)), 10.0, False),
])
@pytest.mark.parametrize("bits", [16, 32])
def test_extremes_are_finite_and_capped(name, heights, depth, tile, bits):
    cap = 512
    report = trade_heights(heights.astype(np.float32), bits=bits, tile=tile, configs=FEW, views=EXTREME_VIEWS,
                           size=32, depth=depth, max_iterations=cap)
    assert_finite_and_capped(report, cap)


def test_quantization_8_16_32_bits_all_within_a_texel_16_as_float():
    h = random_field(64, 9)
    views = ((70.0, 30.0), (20.0, 290.0))
    reps = {b: trade_heights(h, bits=b, configs=(("exact", 0), ("loop", 32)), views=views, size=SIZE)
            for b in (8, 16, 32)}
    for b, rep in reps.items():
        assert_finite_and_capped(rep, 4096)
        assert rep.rows[0].p95_error <= 1.0, (b, rep.rows[0])
    # 16-bit G and R are within 1/65535 of float: the same steps and errors
    for r16, r32 in zip(reps[16].rows, reps[32].rows):
        assert r16.mean_iterations == pytest.approx(r32.mean_iterations, rel=0.02)
        assert r16.p95_error == pytest.approx(r32.p95_error, abs=0.02)


# ---------------------------------------------------------------- command line
@pytest.fixture
def height_png(tmp_path):
    path = tmp_path / "h.png"
    save_png(random_field(32, 4), path)
    return path


def save_png(h, path):
    from PIL import Image

    Image.fromarray(np.round(h * 255).astype(np.uint8)).save(path)


def test_cli_bench_trade_table_json_and_plot(height_png, tmp_path, capsys):
    plot = tmp_path / "trade.png"
    assert main(["bench", "trade", str(height_png), "--views", "90", "20/290", "--size", "32",
                 "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "relief" in out and "frame time on" in out
    table, summary = out.split("cheapest within", 1)
    rows = [ln.split() for ln in table.splitlines() if ln.split()[:1] and ln.split()[0] in
            ("exact", "loop", "fixed", "parallax", "pom", "relief", "relaxed", "exact_interp", "quadrant")]
    # every setting on the conservative map (exact_interp too), the relaxed variant's on the map of
    # relaxed cones and the quadrant variant on the quadrant map
    assert len(rows) == len(BENCH_CONFIGS) + sum(v == "relaxed" for v, _ in DEFAULT_CONFIGS)
    assert sum(r[-1] == "relaxed" for r in rows) == sum(v == "relaxed" for v, _ in DEFAULT_CONFIGS)
    assert [r[-1] for r in rows if r[0] == "quadrant"] == ["quadrant"]
    assert "p95 <= 0.25 texel" in summary and "p95 <= 1 texel" in summary
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["bench", "trade", str(height_png), "--views", "45/10", "--size", "32", "--json",
                 "--bits", "8", "32"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [d["dtype"] for d in data] == ["uint8", "float32"]
    assert {(r["variant"], r["steps"]) for r in data[0]["rows"]} == set(BENCH_CONFIGS)
    assert [b["budget"] for b in data[0]["budgets"]] == [0.25, 1.0]
    assert main(["bench", "trade", str(height_png), "--views", "95"]) == 2
    assert main(["bench", "trade", str(tmp_path / "nope.png")]) == 3


def test_cli_convert_max_error_picks_and_variant_steps_override(tmp_path, capsys):
    from conftest import GLTF_WALL, copy_samples

    from csm_assets.formats import gltf_container as gc

    src = copy_samples(tmp_path / "in", GLTF_WALL)
    held_out = tmp_path / "held_out.png"
    save_png(random_field(48, 303), held_out)

    def ext_of(out):
        doc = gc.load(out / "brick_wall.gltf")
        return doc.json["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]

    base = ["convert", str(src / "brick_wall.gltf"), "--height", f"bricks={held_out}", "--depth", "0.1", "-q"]
    assert main([*base, "-o", str(tmp_path / "a"), "--max-error", "0.5"]) == 0
    picked = ext_of(tmp_path / "a")
    packed = step_map(np.round(random_field(48, 303) * 255).astype(np.uint8), tile=True, bits=8,
                      bilinear_safe=True)  # as convert makes it, drawn as the material says (minStep 0.25)
    check = verify_step_map(packed, variants=(picked["variant"],), steps=max(picked["steps"], 1), size=48,
                            max_error=0.5, min_step=0.25)
    assert check.passed, picked
    manifest = json.loads((tmp_path / "a" / "csm-manifest.json").read_text())["scenes"]["brick_wall.gltf"]
    assert manifest["settings"]["max_error"] == 0.5
    assert {k: manifest["picks"]["bricks"][k] for k in ("variant", "steps", "bits")} == \
        {"variant": picked["variant"], "steps": picked["steps"], "bits": 8}
    assert "within" in manifest["picks"]["bricks"]["bits_reason"]  # why 8 bits: verify.bits
    # both given: taken as they are; one given: the pick stays inside it
    assert main([*base, "-o", str(tmp_path / "b"), "--max-error", "0.5", "--variant", "fixed", "--steps", "3"]) == 0
    assert (ext_of(tmp_path / "b")["variant"], ext_of(tmp_path / "b")["steps"]) == ("fixed", 3)
    assert main([*base, "-o", str(tmp_path / "c"), "--max-error", "0.5", "--variant", "loop"]) == 0
    assert ext_of(tmp_path / "c")["variant"] == "loop"
    assert main([*base, "-o", str(tmp_path / "d"), "--variant", "relief", "--steps", "16"]) == 0
    assert (ext_of(tmp_path / "d")["variant"], ext_of(tmp_path / "d")["steps"]) == ("relief", 16)
    assert main([*base, "-o", str(tmp_path / "e"), "--max-error", "0"]) == 2


def test_pixel_stats_by_hand():
    from csm_assets.render.renderer import STATUS_CAP, STATUS_HIT, STATUS_MISS
    from csm_assets.verify.maps import pixel_stats

    err = np.array([0.0, 0.5, 2.0, np.inf, np.nan])  # inf: hit against miss; NaN: both missed
    status = np.array([STATUS_HIT, STATUS_HIT, STATUS_CAP, STATUS_MISS, STATUS_MISS])
    s = pixel_stats(err, status, np.array([1, 2, 3, 4, 10]))
    assert s == dict(pixels=5, mean_error=pytest.approx(2.5 / 3), p95_error=np.inf, max_error=np.inf,
                     wrong_share=pytest.approx(2 / 5), nonconverged_share=pytest.approx(1 / 5),
                     mean_iterations=pytest.approx(4.0), max_iterations=10, p99_iterations=10.0)
    empty = pixel_stats(np.array([]), np.array([], np.int8), np.array([], np.int32))
    assert empty["pixels"] == 0 and empty["p95_error"] == 0.0


def test_measure_file_of_heights_equals_its_two_maps_measured_apart(tmp_path):
    """measure_file makes a height map's conservative and relaxed maps from one read and one
    conservative cone pass: its rows are those of the two maps made apart (trade_heights),
    number for number but the frame times."""
    from PIL import Image

    from csm_assets import load_heightfield
    from csm_assets.bench.trade import RELAXED_CONFIGS, measure_file

    path = tmp_path / "h.png"
    Image.fromarray((random_field(24, 7) * 65535).astype(np.uint16)).save(path)
    configs = (("exact", 0), ("loop", 4), ("relaxed", 1), ("relaxed", 2))
    common = dict(views=((60.0, 30.0), (20.0, 200.0)), size=24, draws=1)
    for kw in ({}, {"bits": 16, "tile": False, "bilinear_safe": False}):
        got = measure_file(path, configs=configs, **common, **kw)
        hf = load_heightfield(path)
        want = (trade_heights(hf, configs=configs, **common, **kw).rows
                + trade_heights(hf, cones="relaxed", configs=RELAXED_CONFIGS[:2], **common, **kw).rows)

        def numbers(rows):
            return [{k: v for k, v in vars(r).items() if k != "frame_ms"} for r in rows]

        assert [r.cones for r in got.rows] == ["conservative"] * 4 + ["relaxed"] * 2
        assert numbers(got.rows) == numbers(want)


def test_measure_file_several_min_steps_measures_only_the_variants_they_change(tmp_path):
    """Several minimum steps: every config at the first, and again at each other only the
    variants a minimum step changes; each row records its minimum step, and the rows at the
    second equal a run made at it alone."""
    from PIL import Image

    from csm_assets.bench.trade import measure_file

    path = tmp_path / "h.png"
    Image.fromarray((random_field(24, 9) * 255).astype(np.uint8)).save(path)
    configs = (("exact", 0), ("loop", 4), ("exact_interp", 0), ("quadrant", 0))
    common = dict(views=((60.0, 30.0), (15.0, 200.0)), size=24, draws=1, configs=configs)
    got = measure_file(path, min_step=[0.5, 1.0, 0.5], **common)
    assert [(r.variant, r.cones, r.min_step) for r in got.rows] == [
        ("exact", "conservative", 0.5), ("loop", "conservative", 0.5), ("exact_interp", "conservative", 0.5),
        ("quadrant", "quadrant", 0.5),
        ("exact", "conservative", 1.0), ("exact_interp", "conservative", 1.0), ("quadrant", "quadrant", 1.0)]
    alone = measure_file(path, min_step=1.0, **common)

    def numbers(rows):
        return [{k: v for k, v in vars(r).items() if k != "frame_ms"} for r in rows if r.variant != "loop"]

    assert numbers(got.rows[4:]) == numbers(alone.rows)
    assert [r.min_step_text for r in got.rows[:2]] == ["0.5", "-"]


def test_budget_rule_takes_the_cheapest_within_p95_and_wrong_surface():
    """The budget's rule by hand: p95 at most the budget and no view over 0.5% wrong surface;
    the cheapest by fetches per (variant, cones); quadrant's saving against exact."""
    from types import SimpleNamespace as Row

    from csm_assets.bench.trade_budget import budget_summary, cheapest_by_variant, quadrant_savings, within

    def row(variant, cones, p95, fetches, block, wrongs, min_step=0.5):
        return Row(variant=variant, cones=cones, steps=0, p95_error=p95, mean_iterations=fetches, frame_ms=1.0,
                   block_cost=block, p99_iterations=fetches * 3, min_step=min_step,
                   views=[Row(wrong_share=w) for w in wrongs])

    rows = [row("exact", "conservative", 0.2, 5.0, 10.0, [0.0, 0.004]),
            row("exact", "conservative", 0.9, 4.0, 8.0, [0.0, 0.005], 1.0),
            row("exact", "conservative", 0.1, 3.0, 6.0, [0.0, 0.006]),   # cheap but skips walls
            row("quadrant", "quadrant", 0.24, 3.0, 5.0, [0.001, 0.002]),
            row("quadrant", "quadrant", 0.3, 2.0, 4.0, [0.0, 0.0], 1.0)]
    assert [within(r, 0.25) for r in rows] == [True, False, False, True, False]
    assert within(rows[1], 1.0) and not within(rows[2], 1.0)
    best = cheapest_by_variant(rows, 1.0)
    assert best[("exact", "conservative")] is rows[1] and best[("quadrant", "quadrant")] is rows[4]
    saved = quadrant_savings(rows, 0.25)
    assert saved["fetches"] == pytest.approx(1 - 3 / 5) and saved["block"] == pytest.approx(1 - 5 / 10)
    assert quadrant_savings(rows, 0.05) is None
    summary = budget_summary(rows)
    assert summary[1]["quadrant_saves"] == {"fetches": pytest.approx(0.5), "block_cost": pytest.approx(0.5)}
    assert [c["variant"] for c in summary[0]["cheapest"]] == ["quadrant", "exact"]


def test_cli_bench_trade_distance_columns_are_verify_distances(height_png, capsys):
    """``bench trade``'s distance columns: the conservative map at 1, 8 and 16 texels a pixel at
    45 and 20 degrees, today's march and the level chain's, the very records ``verify
    --distance`` gives at those views; left out with --no-distance, and said why for a map that
    does not tile."""
    from csm_assets.bench.trade import DISTANCE_VIEWS

    assert main(["bench", "trade", str(height_png), "--views", "45", "--size", "16", "--json"]) == 0
    far = json.loads(capsys.readouterr().out)["distance"]["views"]
    assert [(v["texels_per_pixel"], v["elevation"], v["azimuth"]) for v in far] == [tuple(v) for v in DISTANCE_VIEWS]
    assert {v[0] for v in DISTANCE_VIEWS} == {1.0, 8.0, 16.0} and {v[1] for v in DISTANCE_VIEWS} == {45.0, 20.0}
    assert all(v["levels"] is not None for v in far)
    near = [v for v in far if v["texels_per_pixel"] == 1.0]
    assert all(v["levels"]["fetches"] == v["today"]["fetches"] for v in near)  # one texel a pixel: today's hits
    assert main(["verify", str(height_png), "--distance", "--views", "45/30", "20/30", "--json"]) == 0
    verified = {(v["texels_per_pixel"], v["elevation"]): v for v in json.loads(capsys.readouterr().out)}
    for v in far:
        assert v == verified[(v["texels_per_pixel"], v["elevation"])]
    assert main(["bench", "trade", str(height_png), "--views", "45", "--size", "16"]) == 0
    out = capsys.readouterr().out
    assert "rmse today/levels" in out and "tiles today/levels" in out
    assert main(["bench", "trade", str(height_png), "--views", "45", "--size", "16", "--json", "--no-distance"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["distance"] is None and data["distance_note"] == ""
    assert main(["bench", "trade", str(height_png), "--views", "45", "--size", "16", "--no-tile"]) == 0
    assert "distance: not measured: the map does not tile" in capsys.readouterr().out
