"""relaxed_cone_ratios against the brute-force definition (tests/relaxed_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csm_assets import cone_ratios, relaxed_cone_ratios
from csm_assets.cones.exact import exact_ratios
from csm_assets.cones.relaxed import fall_flags, relaxed_exact
from csm_assets.heightfield import height_levels
from conftest import checkerboard, examples, spike
from csm_assets import trace_heightfield
from exact_reference import assert_never_wider
from ref_march import surface
from relaxed_reference import cell_falls, continuous_upper, relaxed_reference, relaxed_squares
from tie_maps import tie_fields

TILINGS = [True, False, (True, False), (False, True)]
LO, HI = np.nextafter(0.5, 0), np.nextafter(0.5, 1)  # the floats next to 0.5
QU = np.nextafter(0.25, 1)


def check(h, tile=True, max_ratio=1.0, unit=None):
    """relaxed_cone_ratios(h) is float32 (H, W), never wider than the exact reference
    (checked in rational arithmetic), equal to it to float32 rounding, and never narrower
    than the conservative cone."""
    got = relaxed_cone_ratios(h, tile=tile, max_ratio=max_ratio)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    u = np.asarray(h, np.float64) if unit is None else unit
    squares = relaxed_squares(u, tx, ty, max_ratio, levels=height_levels(h))
    assert got.dtype == np.float32 and got.shape == np.shape(h)
    assert_never_wider(got, squares, "a relaxed cone")
    want = np.vectorize(lambda q: float(q) ** 0.5, otypes=[np.float64])(squares)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    assert (got >= cone_ratios(h, tile=tile, max_ratio=max_ratio)).all()
    return got


# few levels make plateaus and equal heights (which never fall), many make noise
levels = st.sampled_from([2, 3, 5, 256])
fields = st.tuples(st.integers(1, 6), st.integers(1, 6), levels).flatmap(
    lambda s: arrays(np.int64, s[:2], elements=st.integers(0, s[2] - 1)).map(
        lambda a, n=s[2]: a / (n - 1)))


@examples(0.5)
@given(fields, st.sampled_from(TILINGS), st.sampled_from([1.0, 0.3, 2.0]))
def test_random_fields_match_reference(h, tile, max_ratio):
    check(h, tile, max_ratio)


# Issue 28: a float64 reference counted an exactly zero directional derivative as falling
# (-5.6e-17 at a rounded midpoint) and allowed 0.36 at texel (1, 1); exactly, nothing
# limits it below 0.6, which the library gives.
ISSUE_28 = np.array([[0.55448571, 0., 1., 1., 1.], [1., 0., 1., 1., 1.]])


@examples(0.5)
@given(st.tuples(st.integers(1, 6), st.integers(1, 6)).flatmap(
    lambda s: arrays(np.float64, s, elements=st.floats(0, 1))), st.sampled_from(TILINGS))
@example(ISSUE_28, True)
def test_any_floats_match_reference(h, tile):
    got = check(h, tile)
    if h.shape == ISSUE_28.shape and (h == ISSUE_28).all():
        assert got[1, 1] == pytest.approx(0.6, rel=1e-6)


# Maps where float64 rounding made the library's cones wider than exact (before the falling
# test and the rises above p were decided exactly): hypothesis found the first six, the
# last one a midpoint between h(p) and the next float up, a rise of 2^-54 that float64
# lost; (texel, library before, exact).
WIDER_BEFORE = [
    ([[LO], [QU], [0.5]], (False, True), 2.0),  # (1, 0) 2.0, 1.333
    ([[0.7263435885712525], [0.25], [0.5], [LO], [0.25]], False, 2.0),  # (1, 0) 1.2, 0.8
    ([[LO], [0.5], [LO], [0.0], [0.5]], True, 2.0),  # (3, 0) 0.6, 0.4
    ([[0.5, LO, 0.25], [0.75, 0.25, QU]], (False, True), 2.0),  # (0, 2) 1.667, 1.333
    ([[1.0, LO, LO, QU, QU], [0.5, 0.5, HI, 0.5, QU]], False, 2.0),  # (1, 3) 2.0, 1.562
    ([[0.0, 0.0, 0.25, 0.2985760566686799], [QU, LO, 0.5, LO]], False, 2.0),  # (0, 0) 1.6, 1.414
    ([[0.5, HI, 0.5, 1.0], [0.0, 0.0, 0.5, 1.0]], False, 2.0),  # (0, 2) 2.0, 0.5
]


def _pinned(test):
    for h, tile, cap in WIDER_BEFORE:
        test = example(np.array(h), tile, cap)(test)
    return test


@examples(1.0)
@given(tie_fields(5), st.sampled_from(TILINGS), st.sampled_from([1.0, 0.3, 2.0]))
@_pinned
def test_near_ties_match_the_exact_reference(h, tile, max_ratio):
    """Float maps of exact and near ties (tests/tie_maps.py), every decision exact."""
    check(h, tile, max_ratio)


@examples(0.5)
@given(tie_fields(5, np.float32), st.sampled_from(TILINGS), st.sampled_from([1.0, 2.0]))
def test_float32_near_ties_match_the_exact_reference(h, tile, max_ratio):
    check(h, tile, max_ratio)


@pytest.mark.parametrize("tile", TILINGS)
def test_integer_ties_are_exact(tile):
    """On 8- and 16-bit codes the falling test is exact: a directional derivative that is
    zero (slopes of 1/3 and 2/3 that cancel) does not limit, where float64 rounds it to
    -1e-16 and narrows the cone. Every 2x2 8-bit map of the levels 0, 1/3, 2/3, 1 against
    the reference, which tests on fractions."""
    import itertools

    for codes in itertools.product((0, 85, 170, 255), repeat=4):
        a = np.array(codes, np.uint8).reshape(2, 2)
        check(a, tile, 1.0, unit=a / 255.0)


@pytest.mark.parametrize("h, tile, max_ratio, texel, want", [
    ([[0, 170], [85, 170]], (False, True), 1.0, (0, 0), 1.0),
    ([[85, 255, 255, 85], [85, 85, 255, 85]], False, 0.5, (0, 0), 0.5),
])
def test_ties_found_by_a_clean_room_implementation(h, tile, max_ratio, texel, want):
    """Two maps an independent implementation of the documented rule disagreed on: a float64
    falling test counted an exactly level corner as falling (0.8385 and 0.375 here). The
    8/16-bit codes are tested exactly, and so are floats: k/255 rounded to float64 keeps
    these ties (2 * (85/255) == 170/255 in float64 too)."""
    a = np.array(h, np.uint8)
    assert check(a, tile, max_ratio, unit=a / 255.0)[texel] == pytest.approx(want, rel=1e-6)
    b = a.astype(np.uint16) * 257  # the same levels in 16 bits
    assert check(b, tile, max_ratio, unit=b / 65535.0)[texel] == pytest.approx(want, rel=1e-6)
    assert check(a / 255.0, tile, max_ratio)[texel] == pytest.approx(want, rel=1e-6)


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


def test_bigger_map_agrees_with_reference():
    """20x16 noise with plateaus (the block search spans several blocks), every tiling."""
    h = np.random.default_rng(8).integers(0, 6, (16, 20)) / 5.0
    for tile in TILINGS:
        got = relaxed_cone_ratios(h, tile=tile, max_ratio=0.5)
        tx, ty = (tile, tile) if isinstance(tile, bool) else tile
        want = relaxed_reference(h, tx, ty, 0.5)
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)


@pytest.mark.parametrize("split", [1, 3])
def test_other_splits_match_reference(split):
    """The kernel computes the definition for any sub-cell split (the library uses 2)."""
    h = np.random.default_rng(9).integers(0, 9, (7, 6)) / 8.0
    for tile in TILINGS:
        tx, ty = (tile, tile) if isinstance(tile, bool) else tile
        np.testing.assert_allclose(relaxed_exact(h, tx, ty, 1.0, split=split),
                                   relaxed_reference(h, tx, ty, 1.0, split=split), rtol=1e-9, atol=0)


@examples(0.3)
@given(fields, st.sampled_from(TILINGS))
def test_no_falling_point_inside_the_cone(h, tile):
    """Safety: wherever the relaxed cone is wider than the conservative one, no point of the
    bilinear surface inside it falls along the direction from p (where a ray inside the
    cone could leave the surface), sampled on a 9x9 grid per cell."""
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    got = relaxed_exact(h, tx, ty, 1.0)
    cons = exact_ratios(h, tx, ty, 1.0)
    upper = continuous_upper(h, tx, ty, 1.0)
    wider = got > cons
    assert (got[wider] <= upper[wider] * (1 + 1e-12)).all()


def test_falling_edge_rule_lets_a_ray_through_the_surface():
    """Why the rule is not the published falling-edge one: on this map the falling-edge cone
    of texel p holds a point e where the surface falls away from p (the limiting texel's
    cell rises to a higher corner first, above the texel's own height). A ray from above p
    enters the surface (the exact tracer's hit) and leaves it at e inside that cone, so a
    relaxed step would cross the surface twice; our cone stops short of e."""
    h = np.array([[0.2, 0.6, 0.0], [0.4, 0.5, 0.2], [0.2, 1.0, 1.0]])
    r, c, cap = 1, 0, 4.0
    fe = falling_edge_ratio(h, r, c, cap)
    e, ratio_e, slope = falling_point(h, r, c, 0.3)
    ours = relaxed_exact(h, False, False, cap)[r, c]
    assert ours <= ratio_e < fe / 1.5  # e lies inside the falling-edge cone, not inside ours
    # a ray from p's axis that descends at half the surface's fall and meets e on the surface
    H, W = h.shape
    p = np.array([(c + 0.5) / W, (r + 0.5) / H])
    rho = np.hypot(*(e - p))
    z0 = surface(h, [e[0]], [e[1]], False)[0] + 0.5 * slope * rho
    d = np.array([*(e - p) / rho, -0.5 * slope])
    _, t_hit, hit = trace_heightfield(h, np.array([*p, z0]), d, tile=False)
    assert hit[0] and t_hit[0] < (1 - 1e-3) * rho  # it entered the surface before e
    after = np.array([*p, z0]) + 1.001 * rho * d
    assert after[2] > surface(h, [after[0]], [after[1]], False)[0]  # and is above it past e


def falling_point(h, r, c, min_fall, n=200):
    """(uv of e, |e - p|_uv / (h(e) - h(p)), the surface's fall per uv along e - p) for the
    point e of the bilinear surface (sampled inside the map) that falls along e - p by more
    than ``min_fall`` per uv with the smallest ratio."""
    H, W = h.shape
    u, v = np.meshgrid(np.linspace(0.5 / W, 1 - 0.5 / W, n), np.linspace(0.5 / H, 1 - 0.5 / H, n))
    p = np.array([(c + 0.5) / W, (r + 0.5) / H])
    ex, ey = u - p[0], v - p[1]
    rho = np.hypot(ex, ey) + 1e-300
    step = 1e-6
    fall = (surface(h, u, v, False) - surface(h, u + step * ex / rho, v + step * ey / rho, False)) / step
    dh = surface(h, u, v, False) - h[r, c]
    q = np.where((fall > min_fall) & (dh > 0), rho / np.maximum(dh, 1e-300), np.inf)
    k = np.unravel_index(np.argmin(q), q.shape)
    return np.array([u[k], v[k]]), q[k], fall[k]


def falling_edge_ratio(h, r, c, max_ratio):
    """The published rule at one texel, not tiled: min |q - p| / (h(q) - h(p)) over higher
    texels q whose cell away from p has a falling edge."""
    H, W = h.shape
    best = max_ratio
    for qr in range(H):
        for qc in range(W):
            dh = h[qr, qc] - h[r, c]
            if dh <= 0 or (qr, qc) == (r, c):
                continue
            sides_x = (1,) if qc > c else (-1,) if qc < c else (-1, 1)
            sides_y = (1,) if qr > r else (-1,) if qr < r else (-1, 1)
            if any(cell_falls(h, qr, qc, sx, sy, False, False) for sx in sides_x for sy in sides_y):
                best = min(best, np.hypot((qc - c) / W, (qr - r) / H) / dh)
    return best


@pytest.mark.parametrize("bad", [np.zeros((0, 3)), np.zeros(4), np.array([[np.nan]]),
                                 np.array([[1.5]]), np.zeros((2, 2), np.int32)])
def test_bad_heights_raise_value_error(bad):
    with pytest.raises(ValueError):
        relaxed_cone_ratios(bad)


@pytest.mark.parametrize("cap", [0.0, -1.0, float("inf"), float("nan")])
def test_bad_max_ratio_raises_value_error(cap):
    with pytest.raises(ValueError):
        relaxed_cone_ratios(np.zeros((2, 2)), max_ratio=cap)


@pytest.mark.parametrize("tile", TILINGS)
def test_one_conservative_pass_serves_both_maps(tile, monkeypatch):
    """packing.step_maps makes the conservative and relaxed maps with one conservative cone
    pass, and each is the map step_map makes alone, byte for byte."""
    import csm_assets.cones.relaxed as cones_relaxed
    import csm_assets.packing as packing

    h = np.random.default_rng(11).random((9, 7))
    alone = {k: packing.step_map(h, tile=tile, bits=16, cones=k) for k in ("conservative", "relaxed")}
    passes = []
    for module in (packing, cones_relaxed):
        monkeypatch.setattr(module, "exact_ratios",
                            lambda *a, _real=module.exact_ratios, **k: passes.append(1) or _real(*a, **k))
    both = packing.step_maps(h, tile=tile, bits=16)
    assert len(passes) == 1 and list(both) == ["conservative", "relaxed"]
    for k, packed in both.items():
        assert packed.tobytes() == alone[k].tobytes(), k
    with pytest.raises(ValueError, match="cones must be"):
        packing.step_maps(h, cones=("conservative", "wide"))
