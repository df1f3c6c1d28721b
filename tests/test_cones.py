"""cone_ratios against the brute-force reference, on random fields and the extremes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csm_assets import cone_ratios
from csm_assets.heightfield import height_levels
from conftest import checkerboard, examples, spike
from exact_reference import assert_never_wider, exact_cone_squares
from reference import brute_cone_ratios
from tie_maps import tie_fields


def check(h, tile=True, max_ratio=1.0, unit=None):
    """cone_ratios(h) equals the reference, never exceeds it, and is float32 (H, W)."""
    got = cone_ratios(h, tile=tile, max_ratio=max_ratio)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    want = brute_cone_ratios(np.asarray(h, np.float64) if unit is None else unit, tx, ty, max_ratio)
    assert got.dtype == np.float32 and got.shape == np.shape(h)
    # the brute force rounds in float64 too: 170/255 high, 3/6 away is exactly 0.75, which
    # it gives as 0.7499999999999999 (found by hypothesis); allow that rounding, no more
    assert (got.astype(np.float64) <= want * (1 + 1e-14)).all(), "a cone is wider than exact"
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    return got


fields = st.tuples(st.integers(1, 12), st.integers(1, 12)).flatmap(
    lambda s: arrays(np.float64, s, elements=st.floats(0, 1)))


@given(fields, st.sampled_from([True, False, (True, False), (False, True)]),
       st.sampled_from([1.0, 0.25, 4.0]))
def test_random_fields_match_reference(h, tile, max_ratio):
    check(h, tile, max_ratio)


@given(st.tuples(st.integers(1, 10), st.integers(1, 10)).flatmap(
    lambda s: arrays(np.uint8, s, elements=st.integers(0, 255))))
def test_uint8_is_divided_by_255(h):
    check(h, unit=h / 255.0)


@examples(0.5)
@given(st.one_of(tie_fields(6), tie_fields(6, np.float32)), st.sampled_from([True, False, (True, False)]))
@example(np.array([[0.0, 0.1] + [0.0] * 14]), False)  # 1/16 over 0.1: just under 0.625, which it gave
def test_near_ties_never_wider_than_exact(h, tile):
    """Float32 and float64 maps of exact and near ties: each float32 ratio is at most the
    exact one, in rational arithmetic on the heights as they are."""
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    assert_never_wider(check(h, tile), exact_cone_squares(h, tx, ty, 1.0, levels=height_levels(h)))


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (2, 2), (5, 13)])
@pytest.mark.parametrize("tile", [True, False])
def test_small_and_thin_shapes(shape, tile):
    h = np.random.default_rng(sum(shape)).random(shape)
    check(h, tile)


def test_one_by_one_has_no_higher_texel():
    assert cone_ratios(np.array([[0.3]]), max_ratio=0.7)[0, 0] == np.float32(0.7)


@pytest.mark.parametrize("value", [0.0, 0.5, 1.0])
def test_flat_and_all_ones_get_max_ratio(value):
    r = cone_ratios(np.full((7, 5), value), max_ratio=2.5)
    assert (r == np.float32(2.5)).all()


@pytest.mark.parametrize("tile", [True, False])
def test_single_spike(tile):
    h = spike()
    r = check(h, tile)
    # the texel beside the spike: one column away (1/7 uv), one unit lower
    assert r[4, 2] == pytest.approx(1 / 7, rel=1e-6)
    assert r[4, 3] == 1.0


def test_spike_seen_across_the_corner_only_when_tiling():
    h = spike((10, 10), (0, 0))
    tiled = cone_ratios(h)
    assert tiled[9, 9] == pytest.approx(np.hypot(0.1, 0.1), rel=1e-6)
    assert cone_ratios(h, tile=False)[9, 9] == 1.0
    assert cone_ratios(h, tile=(True, False))[0, 9] == pytest.approx(0.1, rel=1e-6)


def test_checkerboard():
    r = check(checkerboard(), True)
    low = checkerboard() == 0
    assert np.allclose(r[low], 1 / 8) and (r[~low] == 1.0).all()


def test_non_square_uses_uv_distance():
    h = np.zeros((4, 16))
    h[0, 0] = 1.0
    r = cone_ratios(h, tile=False)
    assert r[0, 1] == pytest.approx(1 / 16, rel=1e-6)  # one column = 1/W
    assert r[1, 0] == pytest.approx(1 / 4, rel=1e-6)   # one row = 1/H


def test_uint16_and_float32_input():
    rng = np.random.default_rng(7)
    h16 = rng.integers(0, 65536, (11, 9), dtype=np.uint16)
    check(h16, unit=h16 / 65535.0)
    h32 = rng.random((9, 11)).astype(np.float32)
    check(h32, unit=h32.astype(np.float64))


def test_tiny_height_differences_stay_exact():
    h = np.full((6, 6), 0.5)
    h[2, 3] = 0.5 + 1e-9
    r = check(h)
    assert r[2, 2] == 1.0  # 1/6 uv over 1e-9 height: far beyond the cap


@pytest.mark.parametrize("bad, why", [
    (np.zeros((0, 3)), "empty"), (np.zeros(4), "2-D"), (np.zeros((2, 2, 2)), "2-D"),
    (np.array([[np.nan, 0.0]]), "NaN"), (np.array([[1.5]]), r"\[0, 1\]"),
    (np.array([[-0.1]]), r"\[0, 1\]"), (np.zeros((2, 2), np.int32), "dtype"),
])
def test_bad_heights_raise_value_error(bad, why):
    with pytest.raises(ValueError, match=why):
        cone_ratios(bad)


@pytest.mark.parametrize("max_ratio", [0, -1, float("nan"), float("inf")])
def test_bad_max_ratio(max_ratio):
    with pytest.raises(ValueError, match="max_ratio"):
        cone_ratios(np.zeros((2, 2)), max_ratio=max_ratio)


def test_bad_tile():
    with pytest.raises(ValueError, match="tile"):
        cone_ratios(np.zeros((2, 2)), tile=(True, False, True))
