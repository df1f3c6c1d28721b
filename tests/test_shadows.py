"""Self-shadowing: the shader's csm_shadow against the exact shadows (verify --shadows)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import random_field, skip_without_gl

from csm_assets.verify import shadows as vs
from csm_assets.render.renderer import Renderer
from csm_assets.stepmap import DEFAULTS, make_step_map
from csm_assets.verify.maps import prepare, quad_view

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
VIEWS = ((90.0, 0.0), (40.0, 200.0))
LIGHTS = ((15.0, 0.0), (40.0, 100.0), (70.0, 250.0))


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()


def packed(h, bits=8, tile=True):
    sm = make_step_map(np.asarray(h, np.float32), DEFAULTS.replace(bits=bits, tile=tile))
    return sm.pixels, dict(max_ratio=sm.settings.max_ratio, tile=tile, min_step=sm.min_step)


def run(h, *, bits=8, tile=True, views=VIEWS, lights=LIGHTS, size=64, **kw):
    p, settings = packed(h, bits, tile)
    return vs.verify_shadows(p, **settings, views=views, lights=lights, size=size, soft_pixels=128, **kw)


def draw(h, light, *, tile=True, view=(90.0, 0.0), size=64, light_size=0.0):
    p, s = packed(h, tile=tile)
    _, height, mat = prepare(p, s["max_ratio"], tile, 0.1, s["min_step"])
    mat.light_size = light_size
    case = quad_view(height, *view, mat.tile)
    with Renderer((size, size)) as r:
        return vs.measure_shadows(r, mat, case, *light, world_scale=(1, 1, 0.1),
                                  light_tex=vs.quad_light(vs.light_vector(*light), 0.1))


@pytest.mark.parametrize("seed, bits, tile", [(1, 8, True), (2, 16, False), (3, 8, (True, False))])
def test_hard_shadows_agree_with_the_exact_ones(seed, bits, tile):
    report = run(random_field(48, seed, smooth=1.5), bits=bits, tile=tile)
    assert len(report.views) == len(VIEWS) * len(LIGHTS)
    for s in report.views:
        assert s.pixels > 1000, s
        assert 0.05 < s.lit_share or s.light_elevation > 60, s
        assert s.disagreement <= 0.01, s
        assert s.soft_mean_error < 0.1, s
        assert s.mean_fetches > s.mean_shadow_fetches > 0, s
    assert report.passed
    assert any(s.lit_share < 0.9 for s in report.views)  # there are shadows to get wrong


def test_the_shader_light_direction_is_the_quads():
    _, s = draw(random_field(32, 4), (35.0, 60.0))
    res, _ = draw(random_field(32, 4), (35.0, 60.0))
    d = res.light_dir[res.covered]
    want = vs.quad_light(vs.light_vector(35.0, 60.0), 0.1)
    assert np.abs(d - want).max() < 1e-5


def test_a_wrong_light_sign_fails(monkeypatch):
    h = random_field(48, 5, smooth=1.5)
    assert run(h, lights=((25.0, 60.0),)).passed
    right = vs.quad_light
    monkeypatch.setattr(vs, "quad_light", lambda lw, depth, k=(1.0, 1.0): right(lw, depth, k) * [1, -1, 1])
    report = run(h, lights=((25.0, 60.0),))
    assert not report.passed
    assert report.worst > 0.05


def test_a_forged_step_map_fails():
    h = random_field(48, 6, smooth=1.5)
    p, settings = packed(h)
    p = p.copy()
    p[..., 1] = 255  # every cone as wide as max_ratio: the shadow ray steps through occluders
    report = vs.verify_shadows(p, **settings, views=VIEWS, lights=((20.0, 0.0),), size=64, soft_pixels=64,
                               depth=0.3)
    assert not report.passed and report.worst > 0.05
    p, settings = packed(h)
    assert vs.verify_shadows(p, **settings, views=VIEWS, lights=((20.0, 0.0),), size=64, soft_pixels=64,
                             depth=0.3).passed  # the true map at the same views passes


def test_light_straight_above_lights_everything():
    for h in (random_field(32, 7, smooth=1.0), np.zeros((16, 16)), _spike()):
        res, s = draw(h, (90.0, 0.0))
        cov = res.covered
        assert (res.shadow[cov, 0] == 1.0).all()
        assert s.disagreement == 0.0 and s.lit_share == 1.0


def test_light_at_or_below_the_horizon_shadows_everything():
    for el in (0.0, -10.0):
        res, s = draw(random_field(32, 8), (el, 30.0))
        assert (res.shadow[res.covered, 0] == 0.0).all()
        assert (res.shadow[res.covered, 2] == 0).all()  # no steps spent
        assert s.disagreement == 0.0 and s.lit_share == 0.0


def test_flat_map_is_lit_even_at_a_grazing_light():
    res, s = draw(np.full((16, 16), 0.4), (3.0, 10.0), view=(30.0, 100.0))
    assert (res.shadow[res.covered, 0] == 1.0).all()
    assert s.disagreement == 0.0


def _spike():
    h = np.zeros((32, 32))
    h[16, 16] = 1.0
    return h


def test_spike_casts_a_shadow_away_from_the_light():
    light = (30.0, 0.0)  # from +u: the shadow falls to -u of the spike
    res, s = draw(_spike(), light, tile=False, size=128)
    assert s.disagreement <= 0.01
    uv = res.hit_uv[res.covered]
    dark = res.shadow[res.covered, 0] < 0.5
    assert dark.any()
    assert (uv[dark, 0] < 16.5 / 32 + 1 / 32).all()  # on the far side of the spike
    assert (np.abs(uv[dark, 1] - 16.5 / 32) < 1.5 / 32).all()


def test_non_tiled_sides_do_not_shadow():
    h = np.zeros((32, 32))
    h[:, :3] = 1.0  # a wall along the left side; the light comes low from +u
    light = (12.0, 0.0)
    tiled, st = draw(h, light, tile=True)
    clamped, sc = draw(h, light, tile=False)
    near_right = lambda res: res.covered & (res.hit_uv[..., 0] % 1.0 > 0.9) & (res.hit_height < 0.01)  # noqa: E731
    assert (tiled.shadow[near_right(tiled), 0] == 0).all()  # the wall wraps round
    assert (clamped.shadow[near_right(clamped), 0] == 1).all()
    assert near_right(clamped).sum() > 50
    assert st.disagreement <= 0.01 and sc.disagreement <= 0.01


def test_soft_shadows_are_between_and_near_the_exact_share():
    res, s = draw(random_field(48, 9, smooth=2.0), (30.0, 45.0), light_size=0.1)
    soft = res.shadow[res.covered, 1]
    assert ((soft > 0.05) & (soft < 0.95)).any()
    lit = res.shadow[res.covered, 0]
    assert (soft[lit == 1] >= 0.5).all() and (soft[lit == 0] <= 0.5).all()  # the penumbra centred on the edge
    assert ((lit == 0) & (soft > 0.05)).any()  # it reaches into the shadow
    assert s.soft_mean_error < 0.1 and s.soft_pixels > 0


def test_report_text_and_json():
    report = run(random_field(32, 10), views=((60.0, 0.0),), lights=((30.0, 0.0),))
    text = vs.format_shadow_report(report)
    assert "disagr" in text and text.splitlines()[-1].startswith("PASS")
    d = report.to_dict()
    assert d["passed"] and d["views"][0]["light_elevation"] == 30.0
    assert {"disagreement", "soft_mean_error", "soft_p95_error", "mean_fetches", "band_share"} <= set(d["views"][0])


@pytest.mark.parametrize("name", ["bricks2_disp.jpg", "toy_box_disp.png"])
def test_real_depth_maps_disagree_on_at_most_one_percent(name):
    path = SHARED_DATA / name
    if not path.is_file():
        pytest.skip("../shared/data is absent")
    from csm_assets.verify.maps import load_packed

    p, mr, tl, ms = load_packed(path, invert=True, as_step_map=False)
    report = vs.verify_shadows(p, max_ratio=mr, tile=tl, min_step=ms, views=((90.0, 0.0), (35.0, 200.0)),
                               lights=((10.0, 0.0), (45.0, 120.0), (80.0, 240.0)), size=96, soft_pixels=128)
    assert report.passed, vs.format_shadow_report(report)
    assert math.isfinite(report.worst)


def test_trade_counts_the_shadow_steps_in_the_cost():
    from csm_assets.bench.trade import measure_trade, pick_settings

    p, s = packed(random_field(32, 11, smooth=1.5))
    configs = (("exact", 0), ("loop", 8), ("fixed", 16))
    plain = measure_trade(p, **s, configs=configs, views=((60.0, 0.0),), size=32, draws=1)
    lit = measure_trade(p, **s, configs=configs, views=((60.0, 0.0),), size=32, draws=1, shadow_light=(30.0, 0.0))
    assert lit.shadow_light == (30.0, 0.0) and "self-shadowing" in lit.table()
    for a, b in zip(plain.rows, lit.rows):
        assert b.mean_iterations > a.mean_iterations + 1  # the shadow ray's steps
        assert b.p95_error == a.p95_error  # the view ray is the same
    row, met, report = pick_settings(p, 1.0, **s, configs=configs, shadow_light=(30.0, 0.0))
    assert report.shadow_light == (30.0, 0.0) and met


def test_cli_bench_trade_shadows(tmp_path, capsys):
    from PIL import Image

    from csm_assets.cli import main

    path = tmp_path / "h.png"
    Image.fromarray(np.round(random_field(32, 12) * 255).astype(np.uint8)).save(path)
    assert main(["bench", "trade", str(path), "--views", "60", "--size", "16", "--shadows", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["shadow_light"] == [45.0, 30.0]
    assert main(["bench", "trade", str(path), "--views", "60", "--shadows", "0/10"]) == 2
    assert "--shadows" in capsys.readouterr().err


def test_the_pick_draws_self_shadows_for_self_shadowed_materials(monkeypatch):
    """The pick measures a self-shadowed material with the pick's light on (the shadow ray's
    steps in its cost), others without: the real measurement, watched on its way in."""
    from types import SimpleNamespace

    from csm_assets.convert import pick as pick_scene
    from csm_assets.bench import trade

    seen, real = [], trade.pick_settings

    def watched(pixels, max_error, **kw):
        seen.append(kw.get("shadow_light"))
        return real(pixels, max_error, **kw)

    monkeypatch.setattr(trade, "pick_settings", watched)
    sm = make_step_map(np.zeros((8, 8), np.float32), DEFAULTS)
    for shadows in (False, True):
        opts = SimpleNamespace(variant=None, max_error=1.0, steps=0, self_shadow=shadows)
        variant, steps, min_step = pick_scene.pick(sm, "m", 0.1, opts)
        assert variant in trade.VARIANTS and min_step is None  # a flat map: any setting meets the budget
    assert seen == [None, vs.PICK_LIGHT]


def test_a_rough_map_whose_band_covers_most_pixels_passes():
    from csm_assets.bench import maps as bench_maps

    report = run(bench_maps.tiles(128) / 255.0, views=((30.0, 160.0),), lights=((10.0, 33.0), (25.0, 33.0)))
    assert max(s.band_share for s in report.views) > 0.5  # rough: nearly every pixel is near a shadow edge
    assert report.passed, vs.format_shadow_report(report)


def test_a_scene_s_reference_takes_the_shader_s_world_scale_along_u_and_v(tmp_path, monkeypatch):
    """Under an uneven texture scale (KHR_texture_transform scale [3, 1]: u repeats three times as
    often) the soft reference's light disc is measured with the world length of a unit along u and
    along v as surface_frag.glsl takes them (the columns of the march frame's inverse), not one
    isotropic scale for both."""
    skip_without_gl()
    from view_page import convert
    from view_scenes import two_material_scene

    from csm_assets.verify import shadows_scene

    scene = convert(two_material_scene(tmp_path / "src", transform={"scale": [3.0, 1.0]}), tmp_path / "out",
                    "--self-shadow")
    seen = {}

    def measuring(r, mat, case, *a, world_scale, **kw):
        seen.setdefault(case.name.split(":")[0], world_scale)
        return vs.measure_shadows(r, mat, case, *a, world_scale=world_scale, **kw)

    monkeypatch.setattr(shadows_scene, "measure_shadows", measuring)
    shadows_scene.verify_scene_shadows(scene, views=[(60.0, 30.0)], lights=[(45.0, 0.0)], size=16, cameras=False)
    (bricks,), (cobbles,) = ([v for k, v in seen.items() if k.startswith(q)] for q in ("quad0", "quad1"))
    assert bricks[0] / bricks[1] == pytest.approx(1 / 3, rel=1e-3)  # u spans a third of v's world length
    assert cobbles[0] / cobbles[1] == pytest.approx(1.0, rel=1e-3)
