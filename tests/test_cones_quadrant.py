"""quadrant_cone_ratios against the brute-force reference, on random fields and the extremes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csm_assets import cone_ratios, quadrant_cone_ratios
from conftest import checkerboard, spike
from reference import brute_quadrant_ratios

TILES = [True, False, (True, False), (False, True)]


def check(h, tile=True, max_ratio=1.0, unit=None):
    """quadrant_cone_ratios(h) equals the reference, is never wider than it, is float32
    (4, H, W), and its minimum over the quadrants is cone_ratios exactly."""
    got = quadrant_cone_ratios(h, tile=tile, max_ratio=max_ratio)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    want = brute_quadrant_ratios(np.asarray(h, np.float64) if unit is None else unit, tx, ty,
                                 max_ratio)
    assert got.dtype == np.float32 and got.shape == (4,) + np.shape(h)
    # the brute force rounds sqrt(dx^2 + dy^2) / dh in float64; allow that rounding, no more
    assert (got.astype(np.float64) <= want * (1 + 1e-14)).all(), "a cone is wider than exact"
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    np.testing.assert_array_equal(got.min(axis=0), cone_ratios(h, tile=tile, max_ratio=max_ratio))
    return got


fields = st.tuples(st.integers(1, 12), st.integers(1, 12)).flatmap(
    lambda s: arrays(np.float64, s, elements=st.floats(0, 1)))


@given(fields, st.sampled_from(TILES), st.sampled_from([1.0, 0.25, 4.0]))
def test_random_fields_match_reference(h, tile, max_ratio):
    check(h, tile, max_ratio)


@given(st.tuples(st.integers(1, 10), st.integers(1, 10)).flatmap(
    lambda s: arrays(np.uint8, s, elements=st.integers(0, 255))), st.sampled_from(TILES))
def test_uint8_is_divided_by_255(h, tile):
    check(h, tile, unit=h / 255.0)


@settings(max_examples=30)
@given(st.tuples(st.integers(1, 9), st.integers(1, 9)).flatmap(
    lambda s: arrays(np.uint16, s, elements=st.integers(0, 65535))), st.sampled_from(TILES))
def test_uint16_is_divided_by_65535(h, tile):
    check(h, tile, unit=h / 65535.0)


@settings(max_examples=30)
@given(st.tuples(st.integers(1, 9), st.integers(1, 9)).flatmap(
    lambda s: arrays(np.uint8, s, elements=st.sampled_from([0, 1, 128, 255]))),
    st.sampled_from(TILES))
def test_few_levels_and_ties(h, tile):
    """Equal heights do not narrow a cone (strictly higher only)."""
    check(h, tile, unit=h / 255.0)


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (2, 2), (5, 13), (17, 6)])
@pytest.mark.parametrize("tile", TILES)
def test_small_thin_and_non_square(shape, tile):
    h = np.random.default_rng(sum(shape)).random(shape)
    check(h, tile)


def test_larger_smooth_field_crosses_pyramid_levels():
    rng = np.random.default_rng(5)
    h = np.cumsum(np.cumsum(rng.random((37, 29)), 0), 1)
    check(h / h.max(), (True, False))


@pytest.mark.parametrize("value", [0.0, 0.5, 1.0])
def test_flat_maps_get_max_ratio(value):
    r = quadrant_cone_ratios(np.full((7, 5), value), max_ratio=2.5)
    assert (r == np.float32(2.5)).all()


def test_one_by_one():
    assert (quadrant_cone_ratios(np.array([[0.3]]), max_ratio=0.7) == np.float32(0.7)).all()


@pytest.mark.parametrize("tile", [True, False])
def test_spike_limits_only_the_quadrants_facing_it(tile):
    h = spike()  # (9, 7), spike at row 4, column 3
    r = check(h, tile)
    # one column left of the spike: the rays going +u meet it (the row is an axis of both
    # +u quadrants); the -u quadrants face away (and reach it only by wrapping round)
    assert r[0, 4, 2] == r[3, 4, 2] == pytest.approx(1 / 7, rel=1e-6)
    far = r[1, 4, 2]
    assert far == (pytest.approx(6 / 7, rel=1e-6) if tile else 1.0)
    # one row below: the -v quadrants (2, 3) meet it at 1/9
    assert r[2, 5, 3] == r[3, 5, 3] == pytest.approx(1 / 9, rel=1e-6)
    assert r[0, 5, 3] == (pytest.approx(8 / 9, rel=1e-6) if tile else 1.0)


def test_diagonal_neighbour_limits_one_quadrant_untiled():
    h = np.zeros((5, 5))
    h[1, 1] = 1.0
    r = quadrant_cone_ratios(h, tile=False)
    # texel (2, 2) sees the spike up-left: quadrant -u-v only
    assert r[2, 2, 2] == pytest.approx(np.hypot(0.2, 0.2), rel=1e-6)
    assert (r[[0, 1, 3], 2, 2] == 1.0).all()


def test_checkerboard():
    r = check(checkerboard(), True)
    low = checkerboard() == 0
    assert np.allclose(r[:, low], 1 / 8) and (r[:, ~low] == 1.0).all()


def test_float32_input_and_tiny_differences():
    h = np.full((6, 6), 0.5, np.float32)
    h[2, 3] = np.nextafter(np.float32(0.5), np.float32(1))
    check(h, unit=h.astype(np.float64))


@pytest.mark.parametrize("bad, why", [
    (np.zeros((0, 3)), "empty"), (np.array([[np.nan, 0.0]]), "NaN"), (np.array([[1.5]]), r"\[0, 1\]"),
])
def test_bad_heights_raise_value_error(bad, why):
    with pytest.raises(ValueError, match=why):
        quadrant_cone_ratios(bad)


def test_bad_max_ratio_and_tile():
    with pytest.raises(ValueError, match="max_ratio"):
        quadrant_cone_ratios(np.zeros((2, 2)), max_ratio=0)
    with pytest.raises(ValueError, match="tile"):
        quadrant_cone_ratios(np.zeros((2, 2)), tile=(True, False, True))


@pytest.mark.parametrize("method", ["ring", "pyramid", "levels"])
@pytest.mark.parametrize("kind", ["terrain", "noise"])
def test_minimum_is_every_exact_method_bit_for_bit(method, kind):
    """Every exact method gives the same float64 (the minimum of d / dh^2; blocks skipped
    only with slack), so the quadrants' minimum is cone_ratios whichever method runs."""
    from csm_assets.bench import maps
    from csm_assets.cones.exact import exact_ratios, round_down_f32
    from csm_assets.heightfield import unit_heights

    h = getattr(maps, kind)(96)[:, :80]
    want = round_down_f32(exact_ratios(unit_heights(h), True, False, 1.0, method=method))
    np.testing.assert_array_equal(quadrant_cone_ratios(h, tile=(True, False)).min(axis=0), want)


def test_seen_counts_the_blocks_examined_without_changing_the_ratios():
    """``quadrant_exact(..., seen=)`` reports the work (benchmarks/quadrant.py prints it per
    texel): none on a flat map, fewer than a search of the whole pyramid per texel on a
    smooth one, and the ratios are the same with or without it."""
    from csm_assets.cones.pyramid import build_pyramid
    from csm_assets.cones.quadrant import quadrant_exact

    seen = np.zeros(1, np.int64)
    quadrant_exact(np.full((16, 16), 0.5), True, True, 1.0, seen=seen)
    assert seen[0] == 0
    y, x = np.mgrid[:64, :48]
    h = 0.5 + 0.4 * np.sin(x / 5.0) * np.cos(y / 7.0)
    out = quadrant_exact(h, True, False, 1.0, seen=seen)
    assert np.array_equal(out, quadrant_exact(h, True, False, 1.0))
    assert 0 < seen[0] < h.size * build_pyramid(h)[0].size


@pytest.mark.parametrize("name", ["noise", "tiles"])
def test_rough_maps_are_searched_about_as_cheaply_as_conservative_cones(name):
    """On rough maps a 2x2 group's texels have very different cones (a local peak next to a
    pit); searched together, the group's bound is as loose as its widest cone with its lowest
    height, and white noise took 35 s at 512² (1472 blocks per texel at 128², 34 times a
    conservative search). Such groups are searched texel by texel: the work stays within a
    small factor of the conservative search's, measured in blocks (independent of load)."""
    from csm_assets.bench import maps
    from csm_assets.cones.pyramid import build_pyramid, sample_searches
    from csm_assets.cones.quadrant import quadrant_exact
    from csm_assets.heightfield import unit_heights

    h = unit_heights(getattr(maps, name)(128))
    seen = np.zeros(1, np.int64)
    quadrant_exact(h, True, True, 1.0, seen=seen)
    rows, cols = np.divmod(np.arange(h.size), h.shape[1])
    _, cold = sample_searches(h, build_pyramid(h), True, True, float(h.size) ** 2, rows, cols)
    assert seen[0] / h.size < 4 * cold.mean()
