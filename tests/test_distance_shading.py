"""The shading fetch at the hit far away (csm.glsl's ``csm_shading_grads``, ``csm_visible_taps``): the
shorter axis of the pixel's visible footprint, far away four taps weighted by their projected area,
the same in the shader and in ``verify --distance``'s emulation
(:mod:`csm_assets.verify.distance_shading`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import glsl_define, skip_without_gl
from csm_assets.render.renderer import STATUS_MISS, Material, Renderer
from csm_assets.stepmap import StepMapSettings, make_step_map
from csm_assets.verify.distance import distance_view
from csm_assets.verify.distance_shading import (FAR_SHARPEN, NORMAL_SHARPEN, QUAD_SHARE, QUAD_SHARE_FAR,
                                                TAP_SHRINK, TAP_SPREAD, diffs, quad_share, quad_weight,
                                                shading_grad, slope_chain, tap_spread, tapped, trilinear,
                                                visible_taps)

BRICKS = Path(__file__).resolve().parents[1] / "samples" / "bricks_height.png"  # 128², tiles
SIZE = 64


def flat_slopes(n=16, su=0.0, sv=0.0):
    """A one-level slope chain of a plane rising ``su``, ``sv`` per texel along u and v."""
    return [np.broadcast_to(np.array([su, sv]), (n, n, 2)).astype(np.float64)]


def test_on_a_flat_surface_it_is_the_polygons_shorter_axis():
    dx, dy = np.array([[0.5, 0.0], [0.0, 0.1]]), np.array([[0.0, 0.2], [0.3, 0.0]])
    ds = np.array([[0.6, 0.0, 0.8], [0.0, 0.6, 0.8]])
    g = shading_grad(flat_slopes(), np.full((2, 2), 0.5), ds, dx, dy)
    assert np.allclose(g, [[0.0, 0.2], [0.0, 0.1]])


def test_a_wall_facing_the_eye_narrows_it_and_a_slope_turned_away_widens_it():
    """A ray along +u at 45 degrees: a plane rising s per texel along u (dh/du = s n) moves the hit
    of a ray shifted v along u by v / (1 + s n); the footprint's other axis is 8 texels."""
    n = 16
    ds = np.array([[np.sqrt(0.5), 0.0, np.sqrt(0.5)]])
    dx, dy = np.array([[4.0 / n, 0.0]]), np.array([[0.0, 8.0 / n]])
    for s, texels in ((1.0 / n, 2.0), (0.0, 4.0), (-0.25 / n, 4.0 / 0.75), (-0.9 / n, 8.0), (-2.0 / n, 8.0)):
        g = shading_grad(flat_slopes(n, s), np.full((1, 2), 0.5), ds, dx, dy)
        assert np.isclose(np.hypot(*g[0]) * n, texels), (s, g)
    # turned away more steeply than the ray (hidden from the eye): the divisor held at 0.1 ds.z,
    # 4 (1 + 2 / 0.1) texels
    g = shading_grad(flat_slopes(n, -2.0 / n), np.full((1, 2), 0.5), ds, dx, np.array([[0.0, 100.0 / n]]))
    assert np.isclose(np.hypot(*g[0]) * n, 84.0)


def test_beyond_8_texels_a_pixel_it_shrinks_half_a_level_an_octave_two_at_most():
    """On a flat surface the footprint is the polygon's shorter axis up to 8 texels a pixel, then
    FAR_SHARPEN of a level finer per octave of that axis: 16 texels read as 16 / 2^0.5, 32 and more
    as 32 / 2 (and 64 as 32)."""
    n = 256
    ds = np.array([[0.6, 0.0, 0.8]])
    for texels, shaded in ((1.0, 1.0), (8.0, 8.0), (16.0, 16.0 * 2 ** -FAR_SHARPEN),
                           (32.0, 32.0 * 2 ** (-2 * FAR_SHARPEN)), (64.0, 64.0 * 2 ** (-2 * FAR_SHARPEN))):
        g = shading_grad(flat_slopes(n), np.full((1, 2), 0.5), ds, np.array([[texels / n, 0.0]]),
                         np.array([[0.0, 2 * texels / n]]))
        assert np.isclose(np.hypot(*g[0]) * n, shaded), texels


def test_the_emulations_constants_are_the_shaders():
    for name, value in (("CSM_FAR_SHARPEN", FAR_SHARPEN), ("CSM_QUAD_SHARE", QUAD_SHARE),
                        ("CSM_QUAD_SHARE_FAR", QUAD_SHARE_FAR), ("CSM_NORMAL_SHARPEN", NORMAL_SHARPEN),
                        ("CSM_TAP_SPREAD", TAP_SPREAD), ("CSM_TAP_SHRINK", TAP_SHRINK)):
        assert glsl_define(name) == value, name


@pytest.fixture(scope="module", params=[8.0, 16.0])
def bricks_far(request):
    """The bricks sample with its averaged chain drawn at 8 or 16 texels per pixel, 45 degrees, lit
    by a directional light: (step map, view, render)."""
    skip_without_gl()
    sm = make_step_map(np.asarray(Image.open(BRICKS), np.float32) / 255.0, StepMapSettings(levels="average"))
    view = distance_view(sm.pixels.shape, request.param, 45.0, 30.0, 0.1, SIZE)
    mat = Material(sm.pixels, depth=view.world_depth, tile=True, uv_per_world=(view.uv_per_world,) * 2,
                   min_step=0.25, levels=tuple(sm.levels), light_direction=(0.3, -0.4, 0.87))
    with Renderer((SIZE, SIZE)) as r:
        res = r.render(mat, view.camera, variant="exact", mesh=view.mesh)
        assert r.ctx.error == "GL_NO_ERROR"
    return sm, view, res


def lit_of(sm, view, su, sv):
    """The shader's diffuse N·L of stored slopes ``su``, ``sv`` (B - 0.5, 0.5 - A) in the bricks' view."""
    rows, cols = sm.pixels.shape[:2]
    scale = view.uv_per_world * view.world_depth
    n = np.column_stack([-su * cols * scale, sv * rows * scale, np.ones(len(su))])
    light = np.array([0.3, -0.4, 0.87]) / np.linalg.norm([0.3, -0.4, 0.87])
    return np.maximum((n / np.linalg.norm(n, axis=1, keepdims=True)) @ light, 0.0)


def lit_at(sm, view, res, ok, dx, dy):
    """The shader's diffuse N·L at the hits of ``ok``, its slopes fetched with gradients dx, dy."""
    slopes = slope_chain(sm.pixels, sm.levels)
    uv = res.hit_uv.reshape(-1, 2)[ok]
    return lit_of(sm, view, *(trilinear([s[..., k] for s in slopes], uv, dx, dy) for k in (0, 1)))


def test_the_quad_share_blends_each_pixel_with_its_quads_neighbours_far_away_only():
    img = np.arange(16.0).reshape(4, 4)
    img[3, 3] = np.nan
    out = quad_share(img, np.full((4, 4), 0.25))
    assert out[0, 0] == 0.5 * 0 + 0.25 * 1 + 0.25 * 4  # across: column 1, down: row 1
    assert out[1, 3] == 0.5 * 7 + 0.25 * 6 + 0.25 * 3
    assert out[2, 3] == 0.75 * 11 + 0.25 * 10  # its neighbour down is NaN: its own value
    size = np.array([128.0, 128.0])
    texels = np.array([1.0, 2.0, 2.0 ** 1.5, 4.0, 8.0, 2.0 ** 3.5, 16.0, 64.0])
    w = quad_weight(np.column_stack([texels / 128, 0 * texels]), np.column_stack([0 * texels, 2 * texels / 128]), size)
    half = 0.5 * (QUAD_SHARE + QUAD_SHARE_FAR)
    assert np.allclose(w, [0.0, 0.0, 0.5 * QUAD_SHARE, QUAD_SHARE, QUAD_SHARE, half, QUAD_SHARE_FAR, QUAD_SHARE_FAR])


def test_the_shader_shades_with_the_visible_footprints_shorter_axis(bricks_far, monkeypatch):
    """The render's diffuse term is the emulation's (csm_shading_grads, csm_visible_taps and
    csm_quad_share against shading_grad, visible_taps and quad_share), and not what the polygon's
    footprint (GL's longer axis), the same without the share, one fetch half a level finer at the
    hit (the shader before the taps), or (at 16 texels a pixel) without the far sharpening gives."""
    sm, view, res = bricks_far
    ok = (res.covered & (res.status != STATUS_MISS)).ravel()
    dx, dy = diffs(res.ray_uv)
    shaded = (res.color[..., 0].ravel()[ok] - 0.2) / 0.8
    size = np.array(sm.pixels.shape[1::-1], np.float64)
    weight = quad_weight(dx, dy, size).reshape(res.covered.shape)
    assert weight[ok.reshape(weight.shape)].min() >= QUAD_SHARE  # 8 texels a pixel or more: all far away
    slopes, uv, ds = slope_chain(sm.pixels, sm.levels), res.hit_uv.reshape(-1, 2)[ok], res.ray_dir.reshape(-1, 3)[ok]

    def emulated(taps=True):
        g = shading_grad(slopes, uv, ds, dx[ok], dy[ok])
        image = np.full(ok.shape, np.nan)
        if taps:
            image[ok] = lit_of(sm, view, *visible_taps(slopes, uv, ds, g, tap_spread(dx[ok], dy[ok], size))[2].T)
        else:
            image[ok] = lit_at(sm, view, res, ok, g * 2.0 ** -NORMAL_SHARPEN, g * 2.0 ** -NORMAL_SHARPEN)
        return image, np.abs(shaded - quad_share(image.reshape(weight.shape), weight).ravel()[ok])

    image, visible = emulated()
    others = [np.abs(shaded - lit_at(sm, view, res, ok, dx[ok], dy[ok])), np.abs(shaded - image[ok]),
              emulated(taps=False)[1]]
    if view.texels_per_pixel >= 16:
        monkeypatch.setattr("csm_assets.verify.distance_shading.FAR_SHARPEN", 0.0)
        others.append(emulated()[1])
    assert np.percentile(visible, 90) < 0.03  # measured 0.009 and 0.009 (llvmpipe: derivatives per pixel)
    for other in others:  # measured 0.29, 0.20, 0.09 at 8; 0.27, 0.20, 0.13, 0.11 at 16
        assert np.percentile(other, 90) > 3 * np.percentile(visible, 90), [np.percentile(o, 90) for o in others]


def plane_slopes(n, su, sv):
    """A one-level slope chain of ``n``² texels: (su, sv) per texel (B - 0.5, 0.5 - A) left of
    u = 0.5, their negatives right of it."""
    s = np.empty((n, n, 2))
    s[:, : n // 2] = su, sv
    s[:, n // 2:] = -su, -sv
    return [s]


def test_each_tap_weighs_its_projected_area_towards_the_eye():
    """Taps on a slope facing the ray weigh ds.z + grad h . ds.xy (per uv unit), those on a slope
    turned away from it less, nothing past grazing; on one plane all four alike."""
    n = 64
    ds = np.array([[0.6, 0.0, 0.8]])
    g = np.array([[16.0 / n, 0.0]])  # the taps 4 texels either side of the hit along u
    for su, expect in ((0.01, [0.8 + 0.6 * 0.64, 0.8 - 0.6 * 0.64]), (0.05, [0.8 + 0.6 * 3.2, 0.0])):
        taps, gt, slope = visible_taps(plane_slopes(n, su, 0.0), np.array([[0.5, 0.5]]), ds, g, np.ones(1))
        w = np.array([w[0] for _, w in taps])
        assert np.allclose(w[[0, 2]], expect[0] / (2 * sum(expect)))  # the taps left of the hit: facing
        assert np.allclose(w[[1, 3]], expect[1] / (2 * sum(expect)))
        assert np.allclose(slope[0, 0], su * (w[0] + w[2]) - su * (w[1] + w[3]))
        assert np.allclose(gt, g * TAP_SHRINK)
    taps, _, _ = visible_taps(flat_slopes(n, 0.01, -0.02), np.array([[0.5, 0.5]]), ds, g, np.ones(1))
    assert np.allclose([w for _, w in taps], 0.25)


def test_the_projected_area_is_the_density_of_parallel_rays_hits():
    """Brute force: parallel rays on a grid, each marched in small steps to a plane of slope grad h,
    land ds.z / (ds.z + grad h . ds.xy) as far apart as they start (the weight's inverse)."""
    ds = np.array([0.5, 0.3, 0.81])
    ds /= np.linalg.norm(ds)
    for grad in ((0.0, 0.0), (0.4, 0.1), (-0.3, 0.2)):
        start = np.stack(np.meshgrid(np.linspace(0, 0.1, 11), np.linspace(0, 0.1, 11)), -1).reshape(-1, 2)
        t = np.arange(0, 4.0, 1e-4)
        uv = start[:, None, :] + t[None, :, None] * ds[:2]
        above = 1.0 - ds[2] * t[None, :] - (0.2 + uv @ np.array(grad))
        first = np.argmax(above <= 0, axis=1)
        hit = uv[np.arange(len(start)), first].reshape(11, 11, 2)
        area = abs(np.cross(hit[0, -1] - hit[0, 0], hit[-1, 0] - hit[0, 0])) / 0.01
        assert np.isclose(area, ds[2] / (ds[2] + np.dot(grad, ds[:2])), rtol=2e-3), grad


def test_near_the_taps_are_one_fetch_and_spread_with_the_quad_share():
    n = 32
    rng = np.random.default_rng(1)
    slopes = [rng.uniform(-0.05, 0.05, (n, n, 2))]
    chain = [rng.uniform(0, 1, (n, n))]
    uv, ds, g = rng.uniform(0, 1, (5, 2)), np.tile([[0.3, 0.2, 0.93]], (5, 1)), np.tile([[1.5 / n, 0.0]], (5, 1))
    taps, gt, slope = visible_taps(slopes, uv, ds, g, np.zeros(5))
    assert np.allclose(tapped(chain, taps, gt), trilinear(chain, uv, g, g))
    fine = g * 2.0 ** -NORMAL_SHARPEN
    assert np.allclose(slope, np.column_stack([trilinear([slopes[0][..., c]], uv, fine, fine) for c in (0, 1)]))
    texels = np.array([1.0, 2.0, 2.0 ** 1.5, 4.0, 64.0])
    spread = tap_spread(np.column_stack([texels / n, 0 * texels]), np.column_stack([0 * texels, 2 * texels / n]),
                        np.array([n, n], np.float64))
    assert np.allclose(spread, [0.0, 0.0, 0.5, 1.0, 1.0])
