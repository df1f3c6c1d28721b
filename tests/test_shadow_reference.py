"""The exact shadow reference against slow, obviously correct ones (no GL)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_field
from scipy.ndimage import map_coordinates

from csm_assets.verify.shadow_reference import (HEIGHT_TOLERANCE, TOLERANCE, disc_directions, edge_band,
                                                     entry_distance, hard_shadows, sample_surface,
                                                     soft_shadows)


def surface(h, u, v, tile):
    """Bilinear heights by scipy (REPEAT per tiled axis; a clamped coordinate is CLAMP_TO_EDGE)."""
    rows, cols = h.shape
    x, y = np.asarray(u) * cols - 0.5, np.asarray(v) * rows - 0.5
    x = x if tile[0] else np.clip(x, 0, cols - 1)
    y = y if tile[1] else np.clip(y, 0, rows - 1)
    return map_coordinates(h, [y, x], order=1, mode="grid-wrap")


def brute_lit(h, point, light, tile, samples=4000):
    """Lit by sampling the segment from the point towards the light finely: no sample
    beyond the tolerance is under the bilinear surface (scipy's, not the tracer's)."""
    rows, cols = h.shape
    if light[2] <= 0:
        return False
    top = (1.0 - point[2]) / light[2]
    for axis, tiled in enumerate(tile):
        if not tiled and light[axis] != 0:  # beyond a non-tiled side nothing lies
            top = min(top, max(((1.0 if light[axis] > 0 else 0.0) - point[axis]) / light[axis], 0.0))
    tol = max(TOLERANCE / max(rows, cols), HEIGHT_TOLERANCE / light[2])
    if top <= tol:  # the ray enters within the tolerance of the point
        return True
    d = np.linspace(tol, top, samples)[1:]
    q = point[None, :] + d[:, None] * light[None, :]
    return bool((q[:, 2] > surface(h, q[:, 0], q[:, 1], tile)).all())


def random_points(h, n, seed, tile):
    rng = np.random.default_rng(seed)
    uv = rng.random((n, 2))
    return np.column_stack([uv, sample_surface(h, uv, tile)])


def random_lights(n, seed):
    rng = np.random.default_rng(seed)
    el = rng.uniform(np.radians(5), np.radians(85), n)
    az = rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


@pytest.mark.parametrize("shape, seed, tile", [((12, 12), 1, (True, True)), ((10, 14), 2, (False, False)),
                                               ((16, 9), 3, (True, False))])
def test_hard_shadows_match_a_fine_march(shape, seed, tile):
    h = random_field(shape, seed, smooth=1.0).astype(np.float64)
    pts = random_points(h, 300, seed, tile)
    lights = random_lights(300, seed + 10)
    lit = hard_shadows(h, pts, lights, tile=tile)
    brute = np.array([brute_lit(h, p, d, tile) for p, d in zip(pts, lights)])
    assert 0.15 < lit.mean() < 0.95  # both answers occur
    assert (lit == brute).mean() >= 0.99, np.flatnonzero(lit != brute)


def test_light_straight_above_lights_a_heightfield_and_below_the_horizon_shadows():
    h = random_field(16, 4, smooth=1.0).astype(np.float64)
    pts = random_points(h, 200, 5, True)
    assert hard_shadows(h, pts, [0.0, 0.0, 1.0]).all()
    assert not hard_shadows(h, pts, [1.0, 0.0, 0.0]).any()
    assert not hard_shadows(h, pts, [0.6, 0.0, -0.8]).any()


def test_flat_map_is_lit_and_a_spike_casts_its_shadow_away_from_the_light():
    flat = np.full((8, 8), 0.5)
    assert hard_shadows(flat, random_points(flat, 50, 1, True), random_lights(50, 2)).all()
    h = np.zeros((16, 16))
    h[8, 8] = 1.0  # centre (8.5 / 16, 8.5 / 16)
    light = np.array([np.cos(np.radians(30)), 0.0, np.sin(np.radians(30))])  # from +u
    behind = [[7.0 / 16, 8.5 / 16, 0.0]]  # a texel on the far side of the spike
    front = [[10.0 / 16, 8.5 / 16, 0.0]]
    assert not hard_shadows(h, behind, light, tile=False)[0]
    assert hard_shadows(h, front, light, tile=False)[0]
    assert not hard_shadows(h, front, light, tile=True)[0]  # tiled, the ray comes round to the spike
    assert hard_shadows(h, behind, light * [-1, 1, 1], tile=False)[0]  # the light from -u: lit


def test_non_tiled_sides_do_not_shadow_but_tiling_wraps():
    h = np.zeros((16, 16))
    h[:, :2] = 1.0  # a wall along the left side
    light = np.array([np.cos(np.radians(20)), 0.0, np.sin(np.radians(20))])  # from +u, low
    near_right = [[15.5 / 16, 0.5, 0.0]]
    assert not hard_shadows(h, near_right, light, tile=True)[0]  # the wall wraps round
    assert hard_shadows(h, near_right, light, tile=False)[0]  # the ray leaves the right side
    assert entry_distance(near_right, light, False)[0] == pytest.approx((1.0 - 15.5 / 16) / light[0])


def test_disc_directions_cover_the_disc_evenly_in_world_space():
    scale = (1.0, 1.0, 0.1)
    centre = np.array([0.3, 0.0, 10 * 0.4])
    centre /= np.linalg.norm(centre)
    dirs = disc_directions(centre, scale, 0.1, 256)[0]
    w = dirs * scale
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    c = centre * scale
    c /= np.linalg.norm(c)
    ang = np.arccos(np.clip(w @ c, -1, 1))
    assert ang.max() <= 0.1 + 1e-9
    assert np.mean(ang <= 0.1 / np.sqrt(2)) == pytest.approx(0.5, abs=0.01)  # equal areas


def test_soft_share_of_a_straight_edge_through_the_disc_centre_is_a_half():
    # a long wall along v at u in [0.5, 0.75] of height 1; the point on the floor sees its
    # top edge exactly at the light's elevation: half the disc is hidden
    h = np.zeros((64, 64))
    h[:, 32:48] = 1.0
    size = 0.08
    p = np.array([[0.25, 0.5, 0.0]])
    edge_u = 31.5 / 64 + 0.5 / 64  # where the bilinear wall reaches its top
    el = np.arctan2(1.0, edge_u - 0.25)
    light = np.array([np.cos(el), 0.0, np.sin(el)])
    share = soft_shadows(h, p, light, (1.0, 1.0, 1.0), size, tile=False, rays=256)[0]
    assert share == pytest.approx(0.5, abs=1.5 / np.sqrt(256))
    assert soft_shadows(h, p, light, (1, 1, 1), 0.0)[0] == float(hard_shadows(h, p, light)[0])
    assert soft_shadows(h, p, [0, 0, 1.0], (1, 1, 1), size)[0] == 1.0


def test_edge_band_marks_points_near_a_shadow_edge():
    h = np.zeros((32, 32))
    h[:, 16] = 1.0
    light = np.array([np.cos(np.radians(45)), 0.0, np.sin(np.radians(45))])
    u = (np.arange(32) + 0.5) / 32
    pts = np.column_stack([u, np.full(32, 0.5), sample_surface(h, np.column_stack([u, np.full(32, 0.5)]))])
    lit, band = edge_band(h, pts, light)
    changes = np.flatnonzero(lit[1:] != lit[:-1])
    assert changes.size
    for c in changes:
        assert band[c] or band[c + 1]
    assert not band[[0, 5, 25]].any()
