"""relaxed_cone_ratios against the brute-force definition (tests/relaxed_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csm_assets import cone_ratios, relaxed_cone_ratios
from csm_assets.cones_relaxed import fall_flags
from conftest import checkerboard, spike
from relaxed_reference import cell_falls, relaxed_reference

TILINGS = [True, False, (True, False), (False, True)]


def check(h, tile=True, max_ratio=1.0, unit=None):
    """relaxed_cone_ratios(h) equals the reference (never wider), is float32 (H, W), and
    is never narrower than the conservative cone."""
    got = relaxed_cone_ratios(h, tile=tile, max_ratio=max_ratio)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    u = np.asarray(h, np.float64) if unit is None else unit
    want = relaxed_reference(u, tx, ty, max_ratio)
    assert got.dtype == np.float32 and got.shape == np.shape(h)
    assert (got.astype(np.float64) <= want * (1 + 1e-14)).all(), "a cone is wider than exact"
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    assert (got >= cone_ratios(h, tile=tile, max_ratio=max_ratio)).all()
    return got


# few levels make plateaus and equal heights (which never fall), many make noise
levels = st.sampled_from([2, 3, 5, 256])
fields = st.tuples(st.integers(1, 6), st.integers(1, 6), levels).flatmap(
    lambda s: arrays(np.int64, s[:2], elements=st.integers(0, s[2] - 1)).map(
        lambda a, n=s[2]: a / (n - 1)))


@settings(max_examples=30, deadline=None)
@given(fields, st.sampled_from(TILINGS), st.sampled_from([1.0, 0.3, 2.0]))
def test_random_fields_match_reference(h, tile, max_ratio):
    check(h, tile, max_ratio)


@settings(max_examples=15, deadline=None)
@given(st.tuples(st.integers(1, 6), st.integers(1, 6)).flatmap(
    lambda s: arrays(np.float64, s, elements=st.floats(0, 1))), st.sampled_from(TILINGS))
def test_any_floats_match_reference(h, tile):
    check(h, tile)


@pytest.mark.parametrize("dtype,scale", [(np.uint8, 255.0), (np.uint16, 65535.0)])
def test_integer_heights_are_scaled(dtype, scale):
    a = np.random.default_rng(5).integers(0, int(scale) + 1, (7, 6)).astype(dtype)
    check(a, True, unit=a / scale)
    check(a, False, unit=a / scale)


def test_float32_heights():
    h = np.random.default_rng(6).random((6, 7)).astype(np.float32)
    check(h, (True, False), unit=h.astype(np.float64))


@pytest.mark.parametrize("tile", TILINGS)
def test_one_by_one_and_flat_get_max_ratio(tile):
    assert relaxed_cone_ratios(np.array([[0.3]]), tile=tile, max_ratio=0.7)[0, 0] == np.float32(0.7)
    for v in (0.0, 0.4, 1.0):
        r = relaxed_cone_ratios(np.full((5, 4), v), tile=tile, max_ratio=2.5)
        assert (r == np.float32(2.5)).all()


@pytest.mark.parametrize("tile", TILINGS)
def test_single_spike_limits_like_the_conservative_cone(tile):
    """A spike's cells fall every way: every texel's relaxed cone is its conservative one."""
    h = spike((9, 7), (4, 3))
    got = check(h, tile)
    np.testing.assert_array_equal(got, cone_ratios(h, tile=tile))
    assert got[4, 3] == np.float32(1.0)


def test_ramp_never_limits_the_cones_below_it():
    """A ramp rising to the right, not tiled: rays towards it never leave the surface."""
    h = np.tile(np.linspace(0, 1, 8), (5, 1))
    got = check(h, False)
    assert (got == np.float32(1.0)).all()
    assert (cone_ratios(h, tile=False) < 1.0).sum() > 30  # the conservative cones are narrow


def test_tiled_ramp_has_a_falling_seam():
    """Tiled, the same ramp drops at the seam: that cell limits the cones again."""
    h = np.tile(np.linspace(0, 1, 8), (5, 1))
    got = check(h, True)
    assert (got < 1.0).sum() > 30


def test_far_image_on_the_torus_counts():
    """On a tiled axis a texel limits through its farther image too (its own direction)."""
    h = np.array([[0.0, 0.2, 0.9, 0.1, 0.0, 0.0]])
    check(h, True, max_ratio=2.0)
    check(h, (True, False), max_ratio=2.0)


def test_checkerboard_and_terraces():
    check(checkerboard((6, 8)), True)
    terraces = np.repeat(np.repeat(np.arange(4) / 3.0, 2)[None], 5, axis=0)
    check(terraces, True)
    check(terraces, False)


@pytest.mark.parametrize("tile", TILINGS)
def test_fall_flags_match_the_cell_rule(tile):
    h = np.random.default_rng(7).integers(0, 3, (5, 6)) / 2.0
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    flags = fall_flags(h, tx, ty)
    for r in range(5):
        for c in range(6):
            for sy in (-1, 1):
                for sx in (-1, 1):
                    bit = bool(flags[r, c] >> (2 * (sy > 0) + (sx > 0)) & 1)
                    assert bit == cell_falls(h, r, c, sx, sy, tx, ty)


def test_bigger_map_agrees_with_reference_on_sampled_texels():
    """32x24 noise with plateaus (the block search spans several blocks), every tiling."""
    h = np.random.default_rng(8).integers(0, 6, (24, 32)) / 5.0
    for tile in TILINGS:
        got = relaxed_cone_ratios(h, tile=tile)
        tx, ty = (tile, tile) if isinstance(tile, bool) else tile
        want = relaxed_reference(h, tx, ty, 1.0)
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)


@pytest.mark.parametrize("bad", [np.zeros((0, 3)), np.zeros(4), np.array([[np.nan]]),
                                 np.array([[1.5]]), np.zeros((2, 2), np.int32)])
def test_bad_heights_raise_value_error(bad):
    with pytest.raises(ValueError):
        relaxed_cone_ratios(bad)


@pytest.mark.parametrize("cap", [0.0, -1.0, float("inf"), float("nan")])
def test_bad_max_ratio_raises_value_error(cap):
    with pytest.raises(ValueError):
        relaxed_cone_ratios(np.zeros((2, 2)), max_ratio=cap)
