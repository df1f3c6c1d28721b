"""Every exact cone strategy (ring, pyramid, levels, auto) against the brute force."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from csm_assets.bench.maps import terrain, tiles
from csm_assets.cones.exact import METHODS, choose_method, cone_ratios, estimate_costs, exact_ratios
from csm_assets.heightfield import unit_heights
from conftest import examples
from exact_reference import assert_never_wider, exact_cone_squares
from reference import brute_cone_ratios
from tie_maps import tie_fields

ALL = sorted(METHODS) + ["auto"]
TILES = [(False, False), (True, True), (True, False), (False, True)]


def close(a, b):
    """Equal to float64 rounding (the kernels sum the same squares in another order)."""
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)


def check(h, tile, max_ratio, method):
    h = unit_heights(h)
    got = exact_ratios(h, tile[0], tile[1], max_ratio, method=method)
    assert got.dtype == np.float64 and got.shape == h.shape
    with np.errstate(over="ignore"):  # subnormal height steps: the brute ratio is inf
        want = brute_cone_ratios(h, tile[0], tile[1], max_ratio)
    close(got, want)


@pytest.mark.parametrize("method", ALL)
@examples(1.0)
@given(h=hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, max_side=9),
                    elements=st.floats(0, 1)),
       tile=st.sampled_from(TILES), max_ratio=st.sampled_from([0.3, 1.0, 5.0]))
def test_random_floats(method, h, tile, max_ratio):
    check(h, tile, max_ratio, method)


@pytest.mark.parametrize("method", ALL)
@examples(0.5)
@given(h=hnp.arrays(np.uint8, hnp.array_shapes(min_dims=2, max_dims=2, max_side=12),
                    elements=st.sampled_from([0, 1, 7, 128, 254, 255])),
       tile=st.sampled_from(TILES), max_ratio=st.sampled_from([0.3, 1.0, 5.0]))
def test_random_few_levels(method, h, tile, max_ratio):
    check(h, tile, max_ratio, method)


# Float64 rounding put these ratios on a float32 value just above the exact one (each
# method, before the kernels' results were made lower bounds): 1/16 uv over a rise of 0.1
# (the double 0.1 is above 1/10) is just under 0.625; 1/4 over the rise from 0.5's lower
# neighbour to 1 is just under 0.5; the same just under the cap 0.5, which they gave.
ROUNDED_UP_BEFORE = [(np.array([[0.0, 0.1] + [0.0] * 14]), (False, False), 1.0),
                     (np.array([[1.0, np.nextafter(0.5, 0), 0.5, 0.25]]), (True, True), 1.0),
                     (np.array([[np.nextafter(0.5, 0), 1.0, 0.5, 0.5]]), (False, False), 0.5)]


def _pinned(test):
    for h, tile, cap in ROUNDED_UP_BEFORE:
        test = example(h=h, tile=tile, max_ratio=cap)(test)
    return test


@pytest.mark.parametrize("method", ALL)
@examples(1.0)
@given(h=tie_fields(8), tile=st.sampled_from(TILES), max_ratio=st.sampled_from([0.3, 1.0, 5.0]))
@_pinned
def test_near_ties_are_lower_bounds_of_the_exact_ratios(method, h, tile, max_ratio):
    """Float maps of exact and near ties (tests/tie_maps.py): every float64 ratio is at most
    the exact one (rational arithmetic on the heights as they are), and within 1e-12 of it,
    so cone_ratios' float32 round-down never widens a cone."""
    got = exact_ratios(h, tile[0], tile[1], max_ratio, method=method)
    squares = exact_cone_squares(h, tile[0], tile[1], max_ratio)
    assert_never_wider(got, squares)
    close(got, np.vectorize(lambda q: float(q) ** 0.5, otypes=[np.float64])(squares))


def _extremes():
    rng = np.random.default_rng(7)
    spike = np.zeros((9, 11))
    spike[4, 6] = 1.0
    checker = (np.indices((8, 6)).sum(axis=0) % 2).astype(np.uint8) * 255
    return {
        "1x1": np.array([[0.5]]),
        "1xN": rng.random((1, 13)),
        "Nx1": rng.random((13, 1)),
        "flat": np.full((5, 7), 0.25),
        "spike": spike,
        "ones": np.ones((6, 6)),
        "checker": checker,
        "uint16": rng.integers(0, 65536, (10, 12), dtype=np.uint16),
        "float32": rng.random((11, 10)).astype(np.float32),
        "sea": terrain(48, seed=5),
        "bricks": tiles(40),
        "wide": rng.random((3, 40)),
    }


EXTREMES = _extremes()


@functools.lru_cache(maxsize=None)
def _brute_extreme(name, tile, max_ratio):
    return brute_cone_ratios(unit_heights(EXTREMES[name]), tile[0], tile[1], max_ratio)


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("tile", TILES)
@pytest.mark.parametrize("max_ratio", [0.3, 5.0])
@pytest.mark.parametrize("name", sorted(EXTREMES))
def test_extremes(name, max_ratio, tile, method):
    got = exact_ratios(unit_heights(EXTREMES[name]), tile[0], tile[1], max_ratio, method=method)
    close(got, _brute_extreme(name, tile, max_ratio))


def test_flat_and_tops_get_the_cap():
    for method in METHODS:
        assert (exact_ratios(np.full((4, 5), 0.3), True, True, 0.7, method=method) == 0.7).all()
        spike = np.zeros((5, 5))
        spike[2, 2] = 1.0
        assert exact_ratios(spike, False, False, 2.0, method=method)[2, 2] == 2.0


@pytest.mark.parametrize("tile", [False, True])
def test_terrain_with_sea_64(tile):
    """Wide cones over a flat sea: every method on the whole map."""
    h = unit_heights(terrain(64, seed=3))
    want = brute_cone_ratios(h, tile, tile, 1.0)
    for method in METHODS:
        close(exact_ratios(h, tile, tile, 1.0, method=method), want)


@pytest.mark.parametrize("kind", ["terrain", "noise16"])
def test_sample_texels_2048(kind):
    """A 2048x2048 map, auto-chosen method, a few texels against the brute force."""
    rng = np.random.default_rng(11)
    if kind == "terrain":
        h = unit_heights(terrain(2048, seed=4))
    else:  # 16-bit smooth bumps: many levels, not the levels method
        y, x = np.mgrid[0:2048, 0:2048] / 2048
        z = 0.5 + 0.25 * np.sin(2 * np.pi * 7 * x) * np.cos(2 * np.pi * 5 * y)
        z += rng.uniform(0, 0.2, z.shape)
        h = unit_heights(np.round(z * 65535).astype(np.uint16))
    got = exact_ratios(h, True, True, 1.0)
    rows = [0, 1023, 2047]
    cols = [0, 777, 2047]
    want = brute_cone_ratios(h, True, True, 1.0, rows=rows, columns=cols)
    close(got[np.ix_(rows, cols)], want[np.ix_(rows, cols)])


def test_pyramid_2048_untiled_samples():
    h = unit_heights(tiles(2048))
    got = exact_ratios(h, False, False, 1.0, method="pyramid")
    rows, cols = [5, 1500], [0, 1029, 2040]
    want = brute_cone_ratios(h, False, False, 1.0, rows=rows, columns=cols)
    close(got[np.ix_(rows, cols)], want[np.ix_(rows, cols)])


def test_auto_choice_follows_the_data():
    sea = unit_heights(terrain(256, seed=2))
    noise = unit_heights(np.random.default_rng(0).integers(0, 256, (256, 256), dtype=np.uint8))
    assert choose_method(sea, False, False, 1.0) != "ring"  # wide cones: ring is O(N^4)
    assert choose_method(noise, False, False, 1.0) == "ring"  # narrow cones
    costs = estimate_costs(sea, False, False, 1.0)
    assert set(costs) == set(METHODS) and costs["ring"] > 10 * costs["pyramid"]


@pytest.mark.parametrize("method", sorted(METHODS))
def test_progress_reaches_total(method):
    calls = []
    h = unit_heights(terrain(64, seed=1))
    exact_ratios(h, True, True, 1.0, progress=lambda d, t: calls.append((d, t)), method=method)
    assert calls and calls[-1][0] == calls[-1][1]
    assert all(a[0] <= b[0] for a, b in zip(calls, calls[1:]))


def test_unknown_method():
    with pytest.raises(ValueError, match="method"):
        exact_ratios(np.zeros((2, 2)), True, True, 1.0, method="fast")


def test_cone_ratios_uses_the_fast_path_and_rounds_down():
    h = terrain(96, seed=8)
    exact = brute_cone_ratios(unit_heights(h), True, False, 1.0)
    got = cone_ratios(h, tile=(True, False))
    assert got.dtype == np.float32
    assert (got.astype(np.float64) <= exact * (1 + 1e-12)).all()
    np.testing.assert_allclose(got, exact, rtol=1e-6)
