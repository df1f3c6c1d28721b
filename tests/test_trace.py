"""The exact tracer against a fine ray march, on random fields and at the extremes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from csm_assets import trace_heightfield, trace_heightfield_world
from csm_assets.verify.trace import rays_to_field
from ref_march import march, surface


def random_rays(rng, n, slope_max=3.0, z=1.0):
    """Rays from height ``z`` going down, horizontal run per unit drop up to ``slope_max``."""
    o = np.column_stack([rng.random(n), rng.random(n), np.full(n, z)])
    ang = rng.random(n) * 2 * np.pi
    run = rng.random(n) * slope_max
    d = np.column_stack([np.cos(ang) * run, np.sin(ang) * run, -np.ones(n)])
    return o, d


def thin_crossing(h, o, d, tile, t_hit, samples):
    """The march stepped over a crossing thinner than its spacing: check the tracer's.
    The ray must dip under the surface within 1e-3 after ``t_hit``, and a march of
    [0, t_hit] as fine as the first must find nothing earlier. Returns t_hit, or the
    march's earlier crossing (which then fails the caller's comparison)."""
    ts = t_hit + np.linspace(0.0, 1e-3, 20001)[1:]
    p = o[None, :] + ts[:, None] * d[None, :]
    assert (p[:, 2] <= surface(h, p[:, 0], p[:, 1], tile)).any(), "no dip under the surface"
    earlier = march(h, o, d, tile, t_hit * (1 - 1e-9), samples) if t_hit > 0 else np.inf
    return t_hit if not np.isfinite(earlier) else earlier


def check_against_march(h, o, d, tile, t_max, samples=20000):
    uv, t, hit = trace_heightfield(h, o, d, tile=tile)
    for k in range(len(o)):
        tm = march(h, o[k], d[k], tile, t_max, samples)
        if hit[k] and t[k] < tm - 1e-9:
            tm = thin_crossing(h, o[k], d[k], tile, t[k], samples)
        assert hit[k] == np.isfinite(tm), (k, t[k], tm)
        if hit[k]:
            assert t[k] == pytest.approx(tm, abs=1e-9), (k, o[k], d[k])
            p = o[k] + t[k] * d[k]
            assert uv[k] == pytest.approx(p[:2], abs=1e-12)
            if t[k] > 0:  # an origin under the surface hits at t = 0, off the surface
                assert p[2] == pytest.approx(surface(h, p[:1], p[1:2], tile)[0], abs=1e-9)
        else:
            assert np.isnan(uv[k]).all() and t[k] == np.inf


@pytest.mark.parametrize("tile", [True, False])
@pytest.mark.parametrize("shape", [(8, 8), (5, 11)])
def test_random_fields_match_fine_march(tile, shape):
    rng = np.random.default_rng(sum(shape) + tile)
    h = rng.random(shape)
    o, d = random_rays(rng, 40)
    check_against_march(h, o, d, tile, t_max=1.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 6), cols=st.integers(1, 6),
       tile=st.booleans(), slope=st.floats(0.0, 8.0))
@example(seed=55522138, rows=4, cols=5, tile=True, slope=7.322265625)  # a crossing 6e-5 long
def test_property_matches_march(seed, rows, cols, tile, slope):
    rng = np.random.default_rng(seed)
    h = rng.random((rows, cols))
    o, d = random_rays(rng, 6, slope_max=slope, z=rng.uniform(0.0, 1.2))
    check_against_march(h, o, d, tile, t_max=1.3, samples=8000)


def test_vertical_rays_hit_the_sampled_height():
    rng = np.random.default_rng(1)
    h = rng.random((16, 16))
    o = np.column_stack([rng.random(50), rng.random(50), np.full(50, 2.0)])
    for tile in (True, False):
        uv, t, hit = trace_heightfield(h, o, [0, 0, -1.0] * np.ones((50, 1)), tile=tile)
        assert hit.all()
        assert t == pytest.approx(2.0 - surface(h, o[:, 0], o[:, 1], tile), abs=1e-12)
        assert uv == pytest.approx(o[:, :2], abs=1e-15)


def test_grazing_rays_over_many_tiles():
    rng = np.random.default_rng(2)
    h = rng.random((6, 6)) * 0.5
    o, d = random_rays(rng, 8, z=0.6)
    d[:, :2] *= 40.0 / np.linalg.norm(d[:, :2], axis=1, keepdims=True)  # 40 uv per unit drop
    check_against_march(h, o, d, True, t_max=0.7, samples=200000)


def test_rays_leaving_an_untiled_field_miss():
    h = np.full((4, 4), 0.5)
    o = np.array([[0.5, 0.5, 1.0], [0.9, 0.1, 0.6]])
    d = np.array([[1.0, 0.0, -0.1], [0.0, -1.0, -0.05]])  # out through u = 1 / v = 0 above 0.5
    uv, t, hit = trace_heightfield(h, o, d, tile=False)
    assert not hit.any() and np.isinf(t).all() and np.isnan(uv).all()
    uv, t, hit = trace_heightfield(h, o, d, tile=True)  # repeating, they come down somewhere
    assert hit.all() and t == pytest.approx([5.0, 2.0])


def test_flat_maps_and_one_texel():
    for h in (np.full((7, 3), 0.25), np.array([[0.25]])):
        o = np.array([[0.3, 0.7, 1.0], [0.1, 0.1, 0.25], [0.5, 0.5, 0.9], [0.5, 0.5, 0.1]])
        d = np.array([[0.2, -0.3, -0.5], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
        for tile in (True, False):
            _, t, hit = trace_heightfield(h, o, d, tile=tile, max_cells=1000)
            assert hit.tolist() == [True, True, False, True]
            assert t[0] == pytest.approx(1.5) and t[1] == 0.0 and t[3] == 0.0


def test_horizontal_ray_inside_the_height_range_stops_after_max_cells():
    h = np.zeros((8, 8))
    h[3, 3] = 1.0
    # a horizontal ray at 0.5 along v = const through row 0's centre line never meets the spike:
    # still going after max_cells, it is unresolved (t NaN), not a miss
    _, t, hit = trace_heightfield(h, [0.0, 0.5 / 8, 0.5], [1.0, 0.0, 0.0], max_cells=500)
    assert not hit[0] and np.isnan(t[0])
    # along the spike's row it hits where the tent reaches 0.5: half a texel before its centre
    uv, t, hit = trace_heightfield(h, [0.0, 3.5 / 8, 0.5], [1.0, 0.0, 0.0], max_cells=500)
    assert hit[0] and uv[0, 0] == pytest.approx(3.0 / 8)


def test_spike_fields_match_march():
    h = np.zeros((9, 7))
    h[4, 3] = 1.0
    rng = np.random.default_rng(3)
    o = np.column_stack([rng.random(30), rng.random(30), rng.uniform(0.3, 1.0, 30)])
    target = np.array([3.5 / 7, 4.5 / 9, 0.0])
    d = target - o + np.column_stack([rng.normal(0, 0.05, (30, 2)), np.zeros(30)])
    for tile in (True, False):
        check_against_march(h, o, d, tile, t_max=1.2, samples=40000)


def test_ray_starting_under_the_surface_hits_at_once():
    h = np.full((4, 4), 0.8)
    _, t, hit = trace_heightfield(h, [[0.5, 0.5, 0.3]], [[0.1, 0.0, 1.0]])
    assert hit[0] and t[0] == 0.0


def test_directions_need_not_be_unit():
    rng = np.random.default_rng(4)
    h = rng.random((8, 8))
    o, d = random_rays(rng, 20)
    _, t1, _ = trace_heightfield(h, o, d)
    _, t2, _ = trace_heightfield(h, o, 2.5 * d)
    assert t2 == pytest.approx(t1 / 2.5, rel=1e-12)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r = np.eye(4)
    r[:3, :3] = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return r


def test_rotated_field_equals_rotated_camera():
    """POV-Ray's bug: a rotated field must look as the field seen by the inversely rotated camera."""
    rng = np.random.default_rng(5)
    h = rng.random((12, 10))
    place = np.diag([4.0, 3.0, 0.5, 1.0])  # field 4 x 3 world units, 0.5 deep
    place[:3, 3] = [-2.0, -1.5, 0.0]
    rot = _rotation([1.0, 2.0, 0.5], 1.1)
    rot[:3, 3] = [0.3, -0.2, 1.0]
    eye = np.array([0.5, -0.3, 3.0])
    px = rng.uniform(-1.5, 1.5, (200, 2))
    targets = np.column_stack([px, np.zeros(200)])
    d = targets - eye
    o = np.tile(eye, (200, 1))
    for tile in (True, False):
        # the field placed then rotated, seen by the camera as it is
        uv_a, t_a, hit_a = trace_heightfield_world(h, o @ rot[:3, :3].T + rot[:3, 3], d @ rot[:3, :3].T,
                                                   rot @ place, tile=tile)
        # the field unrotated, seen by the camera moved by the inverse rotation
        uv_b, t_b, hit_b = trace_heightfield_world(h, o, d, place, tile=tile)
        assert hit_a.tolist() == hit_b.tolist() and hit_a.sum() > 100
        assert t_a[hit_a] == pytest.approx(t_b[hit_b], rel=1e-9)
        assert uv_a[hit_a] == pytest.approx(uv_b[hit_b], abs=1e-9)
        # and the world hit point lies on the placed surface
        pw = o[hit_b] + t_b[hit_b, None] * d[hit_b]
        pf, _ = rays_to_field(pw, d[hit_b], place)
        assert pf[:, 2] == pytest.approx(surface(h, pf[:, 0], pf[:, 1], tile), abs=1e-9)


def test_rays_to_field_moves_points_not_directions():
    m = np.eye(4)
    m[:3, 3] = [5.0, 6.0, 7.0]
    m[0, 0] = 2.0
    o, d = rays_to_field([[7.0, 6.0, 8.0]], [[2.0, 1.0, 0.0]], m)
    assert o.tolist() == [[1.0, 0.0, 1.0]] and d.tolist() == [[1.0, 1.0, 0.0]]


@pytest.mark.parametrize("kwargs, match", [
    (dict(origins=[[0, 0]], directions=[[0, 0, -1]]), "origins"),
    (dict(origins=[[0, 0, 1]], directions=[[0, 0, 0]]), "non-zero"),
    (dict(origins=[[0, 0, np.nan]], directions=[[0, 0, -1]]), "NaN"),
    (dict(origins=[[0, 0, 1]] * 2, directions=[[0, 0, -1]]), "same shape"),
])
def test_bad_rays_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        trace_heightfield(np.zeros((2, 2)), **kwargs)


def test_bad_heights_are_refused():
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        trace_heightfield(np.full((2, 2), 2.0), [0, 0, 1], [0, 0, -1])
