"""The level-of-detail march: the renderer uploads a step map's chain as its mip levels, csm.glsl
marches one level a pixel chosen from its uv footprint, at level 0 exactly today's march."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import glsl_define, skip_without_gl
from csm_assets.map_file import load_packed
from csm_assets.render.renderer import Material, Renderer
from csm_assets.stepmap import StepMapSettings, make_step_map
from csm_assets.verify.distance import distance_view
from csm_assets.verify.march import (LEVEL_ACROSS, LEVEL_MAX_STEP, LEVEL_MIN_STEP, level_min_step, march_exact,
                                     march_level)
from csm_assets.verify.maps import sampled_heights

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
SIZE = 48


@pytest.fixture(scope="module", params=["bricks_height.png", "cobbles.png"])
def chained(request):
    """A real map's step map with its averaged chain (convert's settings: 8 bits, bilinear safe)."""
    skip_without_gl()
    packed, _, _, _ = load_packed(SAMPLES / request.param)
    sm = make_step_map(sampled_heights(packed).astype(np.float32), StepMapSettings(levels="average"))
    return sm


def draw(r, sm, texels, elevation, levels=None, min_step=0.25):
    view = distance_view(sm.pixels.shape, texels, elevation, 30.0, 0.1, SIZE)
    mat = Material(sm.pixels, max_ratio=sm.settings.max_ratio, depth=view.world_depth, tile=True,
                   uv_per_world=(view.uv_per_world,) * 2, min_step=min_step,
                   levels=tuple(sm.levels if levels is None else levels))
    return r.render(mat, view.camera, variant="exact", mesh=view.mesh)


@pytest.mark.parametrize("elevation", [90.0, 45.0, 20.0])
def test_at_a_texel_a_pixel_the_chain_changes_no_hit(chained, elevation):
    with Renderer((SIZE, SIZE)) as r:
        plain = draw(r, chained, 1.0, elevation, levels=())
        lod = draw(r, chained, 1.0, elevation)
    assert lod.covered.sum() > SIZE * SIZE // 3 and len(chained.levels) >= 6
    assert (lod.lod[lod.covered] == 0).all() and (plain.lod[plain.covered] == 0).all()
    for name in ("hit_uv", "hit_height", "ray_t", "iterations", "status"):  # bit for bit
        np.testing.assert_array_equal(getattr(lod, name), getattr(plain, name), err_msg=name)


@pytest.mark.parametrize("texels,level", [(6.0, 1), (12.0, 2), (28.0, 3)])
def test_the_level_is_one_finer_than_the_footprint(chained, texels, level):
    with Renderer((SIZE, SIZE)) as r:
        res = draw(r, chained, texels, 90.0)
        capped = draw(r, chained, texels, 90.0, levels=chained.levels[:1])
        none = draw(r, chained, texels, 90.0, levels=())
    centre = res.lod[SIZE // 4:-SIZE // 4, SIZE // 4:-SIZE // 4]  # footprint within ~10% of texels
    assert (centre == level).all(), np.unique(centre)
    assert (capped.lod[capped.covered] == 1).all()  # clamped to the levels there are
    assert (none.lod[none.covered] == 0).all()  # no chain: level 0, today's march


@pytest.mark.parametrize("texels", [8.0, 16.0])
def test_each_pixel_marches_its_level_with_that_level_s_texel(chained, texels):
    """The render's steps and hits are the CPU march of the level's own map (its cones; above level 0
    level_min_step of that level's texels), pixel by pixel; the level-0 march
    takes others."""
    with Renderer((SIZE, SIZE)) as r:
        res = draw(r, chained, texels, 45.0)
    ok = res.covered.ravel()
    dp, ds = res.ray_uv.reshape(-1, 2)[ok], res.ray_dir.reshape(-1, 3)[ok]
    lod, its = res.lod.ravel()[ok].astype(int), res.iterations.ravel()[ok]
    assert len(set(np.unique(lod)) - {0}) >= 2  # a 45-degree view spans two levels at least
    same = np.zeros(len(lod), bool)
    for k in np.unique(lod):
        sel = lod == k
        sc, _, steps, _ = march_level(chained.pixels, chained.levels, k, dp[sel], ds[sel],
                                      max_ratio=chained.settings.max_ratio, min_step=0.25, steps=True)
        same[sel] = steps == its[sel]
        assert same[sel].mean() >= 0.98, (k, same[sel].mean())
        close = np.abs(sc - res.ray_t.ravel()[ok][sel]) <= 1e-3 * np.abs(sc).max()
        assert close[same[sel]].mean() >= 0.98, (k, close.mean())  # the level's end, as the render's
    _, _, fine, _ = march_exact(chained.pixels, dp, ds, max_ratio=chained.settings.max_ratio, min_step=0.25,
                                steps=True)
    assert (fine == its).mean() < 0.9 and its.mean() < fine.mean()


def test_the_level_min_step_emulation_is_the_shaders():
    for name, value in (("CSM_LEVEL_MIN_STEP", LEVEL_MIN_STEP), ("CSM_LEVEL_ACROSS", LEVEL_ACROSS),
                        ("CSM_LEVEL_MAX_STEP", LEVEL_MAX_STEP)):
        assert glsl_define(name) == value, name


def test_a_level_s_min_step_crosses_the_texture_and_is_held_along_steep_rays():
    """Above level 0 the exact march steps LEVEL_MIN_STEP texels along the ray at least, and far
    enough to cross LEVEL_ACROSS texels, but no more than LEVEL_MAX_STEP for that; a larger
    min_step of the map's own wins."""
    across = np.array([0.9, 0.5, LEVEL_ACROSS / 2.0, 0.1, 0.0])  # |ds.xy|: grazing to straight down
    ds = np.column_stack([across * 0.6, across * 0.8, np.sqrt(1.0 - across ** 2)])
    want = [LEVEL_MIN_STEP, LEVEL_MIN_STEP, 2.0, LEVEL_MAX_STEP, LEVEL_MAX_STEP]
    np.testing.assert_allclose(level_min_step(ds, 0.25), want)
    np.testing.assert_allclose(level_min_step(ds, 5.0), 5.0)


def test_levels_of_the_wrong_shape_are_refused(chained):
    with Renderer((8, 8)) as r:
        with pytest.raises(ValueError, match="mip levels 1..n"):
            draw(r, chained, 1.0, 90.0, levels=chained.levels[1:])
        with pytest.raises(ValueError, match="mip levels 1..n"):
            draw(r, chained, 1.0, 90.0, levels=[lv.astype(np.float32) for lv in chained.levels])


def test_verify_distance_measures_the_chain_beside_today(chained):
    """At a texel a pixel the chain's march is today's (same fetches and tiles); far away it fetches
    less, from fewer cache tiles, and its footprint-shaded image is closer to the reference."""
    from csm_assets.verify.distance import verify_distance

    report = verify_distance(chained.pixels, max_ratio=chained.settings.max_ratio, min_step=0.25, size=32,
                             views=[(1.0, 45.0, 30.0), (16.0, 45.0, 30.0)], levels=chained.levels)
    near, far = report.views
    assert near.levels.fetches == near.today.fetches and near.levels.tiles == near.today.tiles
    assert near.levels.same_steps >= 0.99 and far.levels.same_steps >= 0.98  # emulated on the pixel's level
    assert far.levels.tiles < 0.45 * far.today.tiles and far.levels.fetches < 0.6 * far.today.fetches
    assert far.levels.rmse < far.today.rmse and far.levels.flicker < far.today.flicker
    plain = verify_distance(chained.pixels, max_ratio=chained.settings.max_ratio, min_step=0.25, size=32,
                            views=[(16.0, 45.0, 30.0)])
    assert plain.views[0].levels is None and plain.views[0].today == far.today


def test_a_quadrant_map_s_two_chains_march_together():
    """A quadrant map uploads both images' chains (``levels``, ``levels2``): near, the hits are those
    without them; far away each pixel marches its level, in fewer steps. One chain alone is refused."""
    skip_without_gl()
    packed, _, _, _ = load_packed(SAMPLES / "bricks_height.png")
    sm = make_step_map(sampled_heights(packed).astype(np.float32), StepMapSettings(levels="average", cones="quadrant"))
    assert len(sm.second_levels) == len(sm.levels) > 0
    runs = {}
    with Renderer((SIZE, SIZE)) as r:
        for texels in (1.0, 16.0):
            view = distance_view(sm.pixels.shape, texels, 45.0, 30.0, 0.1, SIZE)
            for chained in (False, True):
                mat = Material(sm.pixels, max_ratio=sm.settings.max_ratio, depth=view.world_depth, tile=True,
                               uv_per_world=(view.uv_per_world,) * 2, min_step=0.25, step_map2=sm.second,
                               levels=tuple(sm.levels) if chained else (),
                               levels2=tuple(sm.second_levels) if chained else ())
                runs[texels, chained] = r.render(mat, view.camera, variant="quadrant", mesh=view.mesh)
        with pytest.raises(ValueError, match="same number of levels"):
            r.render(Material(sm.pixels, step_map2=sm.second, levels=tuple(sm.levels)), view.camera,
                     variant="quadrant", mesh=view.mesh)
    for name in ("hit_uv", "iterations", "status"):
        np.testing.assert_array_equal(getattr(runs[1.0, True], name), getattr(runs[1.0, False], name))
    far, flat = runs[16.0, True], runs[16.0, False]
    assert (far.lod[far.covered] >= 2).all() and (flat.lod[flat.covered] == 0).all()
    assert far.iterations[far.covered].mean() < flat.iterations[flat.covered].mean()


@pytest.mark.parametrize("levels", ["average", "none"])
def test_verify_distance_reads_a_step_map_s_own_levels(tmp_path, levels):
    """A step map file brings its own chain (its levels image); one without levels reports null."""
    import json
    import subprocess
    import sys

    skip_without_gl()
    out = tmp_path / "bricks_csm.png"
    cli = [sys.executable, "-m", "csm_assets"]
    made = subprocess.run([*cli, "stepmap", str(SAMPLES / "bricks_height.png"), "-o", str(out), "--levels", levels],
                          capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr
    r = subprocess.run([*cli, "verify", str(out), "--distance", "--json", "--views", "45/30", "--size", "16"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    records = json.loads(r.stdout)
    if levels == "none":
        assert all(x["levels"] is None for x in records)
    else:
        assert all(x["levels"]["fetches"] <= x["today"]["fetches"] for x in records)
        assert records[0]["levels"]["tiles"] == records[0]["today"]["tiles"]  # 1 texel a pixel: level 0
