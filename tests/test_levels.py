"""The level chain of a step map (csm_assets.step_levels): GL sizes, averaged and max-filtered
heights, exact cones per level against the slow references, and the storage round trip."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from exact_reference import exact_cone_squares
from reference import brute_quadrant_ratios
from relaxed_reference import relaxed_squares
from csm_assets.errors import FormatError
from csm_assets.packing import DTYPES, neighbourhood_min, step_map
from csm_assets.step_levels import (atlas, atlas_shape, level_chain, level_shapes, max_support, mean_weights,
                                    reduce_max, split_atlas)
from csm_assets.stepmap import (StepMapSettings, levels_path, load_step_map, make_step_map, save_step_map,
                                second_path)


def field(shape=(12, 10), seed=3, sigma=1.0):
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(seed).random(shape), sigma, mode="wrap")
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32)


def level0(h, bits, tile=True, cones="conservative", bilinear_safe=True):
    """Packed level 0 (H, W, 4) as make_step_map stores it (a quadrant map: its R, B, A)."""
    p = step_map(h, bits=bits, tile=tile, cones=cones, bilinear_safe=bilinear_safe)
    return p if p.shape[2] == 4 else p[..., [0, 1, 6, 7]]


def top(dtype) -> float:
    return 1.0 if dtype == np.float32 else float(np.iinfo(dtype).max)


def unit(codes) -> np.ndarray:
    return np.asarray(codes, np.float64) / top(codes.dtype)


def test_level_shapes_follow_gl_down_to_one_texel():
    assert level_shapes((8, 8)) == [(4, 4), (2, 2), (1, 1)]
    assert level_shapes((13, 20)) == [(6, 10), (3, 5), (1, 2), (1, 1)]
    assert level_shapes((1, 7)) == [(1, 3), (1, 1)]
    assert level_shapes((1, 1)) == []
    assert atlas_shape((13, 20)) == (6, 18) and atlas_shape((1, 1)) == (0, 0)


@pytest.mark.parametrize("n", range(1, 12))
def test_mean_weights_cover_each_footprint(n):
    idx, w = mean_weights(n)
    m = max(1, n // 2)
    assert idx.shape[0] == m and np.allclose(w.sum(axis=1), 1.0)
    share = np.zeros(n)
    np.add.at(share, idx.ravel(), w.ravel())
    assert np.allclose(share, m / n)  # every fine texel counted by its area, once
    if n % 2 == 0:  # even: exactly the pair 2i, 2i+1 at 1/2 each
        assert all(set(idx[i][w[i] > 0]) == {2 * i, 2 * i + 1} for i in range(m))
        assert np.all(w[w > 0] == 0.5)


@pytest.mark.parametrize("bits", [8, 16, 32])
@pytest.mark.parametrize("shape", [(16, 12), (4, 2)])
def test_average_levels_are_the_2x2_mean_of_the_stored_level_above(bits, shape):
    """Even sizes: R, B and A of level k are the 2x2 mean of level k-1's stored values, rounded to the
    nearest code (ties to even; float maps: the mean rounded to float32)."""
    h = field(shape)
    p = level0(h, bits)
    chain = level_chain(p, ("conservative",), mode="average", tile=(True, True), max_ratio=1.0,
                        bilinear_safe=True)["conservative"]
    above = p
    for lv in chain:
        if above.shape[0] % 2 or above.shape[1] % 2:
            break
        a = above.astype(np.float64)
        mean = (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]) / 4
        want = mean.astype(np.float32) if bits == 32 else np.rint(mean).astype(p.dtype)
        np.testing.assert_array_equal(lv[..., [0, 2, 3]], want[..., [0, 2, 3]])
        above = lv


@pytest.mark.parametrize("shape", [(7, 5), (1, 9), (9, 1), (3, 3)])
def test_odd_and_thin_sizes_take_area_weighted_means(shape):
    h = field(shape, sigma=0.5)
    p = level0(h, 16, tile=False)
    lv = level_chain(p, ("conservative",), mode="average", tile=(False, False), max_ratio=1.0,
                     bilinear_safe=True)["conservative"]
    assert [x.shape[:2] for x in lv] == level_shapes(shape)
    iy, wy = mean_weights(shape[0])
    ix, wx = mean_weights(shape[1])
    r = p[..., 0].astype(np.float64)
    want = np.array([[sum(wy[i, a] * wx[j, b] * r[iy[i, a], ix[j, b]] for a in range(3) for b in range(3))
                      for j in range(len(ix))] for i in range(len(iy))])
    np.testing.assert_array_equal(lv[0][..., 0], np.rint(want).astype(np.uint16))


def coded_g(g, dtype) -> list:
    """Stored G values as exact Fractions of one."""
    t = top(dtype)
    return np.vectorize(lambda x: Fraction(int(x), int(t)) if t > 1 else Fraction(float(x)), otypes=[object])(g)


def assert_exact(g, squares, dtype, max_ratio=1.0, tight=True):
    """Stored G never wider than the exact squared ratios ``squares`` (ratio = G^2 max_ratio, so
    (G^2 max_ratio)^2 <= square), and (integers, ``tight``) one code more would be wider."""
    cap = Fraction(float(max_ratio))
    fr = coded_g(g, dtype)
    wide = [i for i, x in np.ndenumerate(fr) if (x * x * cap) ** 2 > squares[i]]
    assert not wide, f"cones wider than exact at {wide[:5]}"
    if tight and dtype != np.float32:
        t = int(top(dtype))
        loose = [i for i, x in np.ndenumerate(fr) if x < 1 and x * t >= 1
                 and ((x + Fraction(1, t)) ** 2 * cap) ** 2 <= squares[i]]
        assert not loose, f"cones narrower than the exact one's code at {loose[:5]}"


CHAIN_CASES = [("average", 8, True), ("average", 32, (False, True)), ("max", 8, (True, False)), ("max", 16, False)]


@pytest.mark.parametrize("mode,bits,tile", CHAIN_CASES)
def test_each_level_holds_the_exact_cones_of_its_own_heights(mode, bits, tile):
    """Conservative cones of every level (without the safety pass) against the exact rational
    brute force on that level's stored heights; with the pass, their 3x3 minimum."""
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    h = field((12, 10))
    raw = level_chain(level0(h, bits, tile), ("conservative",), mode=mode, tile=(tx, ty), max_ratio=0.5,
                      bilinear_safe=False)["conservative"]
    safe = level_chain(level0(h, bits, tile), ("conservative",), mode=mode, tile=(tx, ty), max_ratio=0.5,
                       bilinear_safe=True)["conservative"]
    for lv, sl in zip(raw, safe):
        levels = 0 if bits == 32 else int(top(lv.dtype))
        squares = exact_cone_squares(lv[..., 0], tx, ty, 0.5, levels)
        assert_exact(lv[..., 1], squares, lv.dtype, 0.5)
        np.testing.assert_array_equal(sl[..., 0], lv[..., 0])
        np.testing.assert_array_equal(sl[..., 1], neighbourhood_min(lv[..., 1], tx, ty))


@pytest.mark.parametrize("bits,tile", [(8, True), (32, (True, False))])
def test_relaxed_levels_hold_exact_relaxed_cones(bits, tile):
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    h = field((10, 8))
    chain = level_chain(level0(h, bits, tile, "relaxed"), ("relaxed",), mode="average", tile=(tx, ty),
                        max_ratio=1.0, bilinear_safe=False)["relaxed"]
    for lv in chain[:2]:
        levels = 0 if bits == 32 else int(top(lv.dtype))
        squares = relaxed_squares(unit(lv[..., 0]), tx, ty, 1.0, levels=levels)
        assert_exact(lv[..., 1], squares, lv.dtype)


@pytest.mark.parametrize("bits,tile", [(8, True), (16, (False, True))])
def test_quadrant_levels_hold_four_exact_cones_in_two_images(bits, tile):
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    h = field((12, 8))
    chain = level_chain(level0(h, bits, tile, "quadrant"), ("quadrant", "conservative"), mode="average",
                        tile=(tx, ty), max_ratio=1.0, bilinear_safe=False)
    step = 1.0 / top(np.dtype(DTYPES[bits]))
    for lv, cons in zip(chain["quadrant"], chain["conservative"]):
        assert lv.shape[2] == 8
        np.testing.assert_array_equal(lv[..., 4], lv[..., 0])
        np.testing.assert_array_equal(lv[..., 6:], cons[..., 2:])
        exact = brute_quadrant_ratios(unit(lv[..., 0]), tx, ty, 1.0)
        stored = np.stack([unit(lv[..., k]) ** 2 for k in (1, 2, 3, 5)])
        assert (stored <= exact * (1 + 1e-12)).all(), "a level's quadrant cone is wider than exact"
        assert (np.sqrt(stored) >= np.sqrt(exact) - step - 1e-7).all()
        np.testing.assert_array_equal(lv[..., [1, 2, 3, 5]].min(axis=-1), cons[..., 1])


def bilinear(a, u, v, tx, ty):
    """GL's LINEAR sample of ``a`` (H, W) at uv (arrays), REPEAT or CLAMP_TO_EDGE per axis."""
    H, W = a.shape
    x, y = u * W - 0.5, v * H - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0

    def at(i, n, wrap):
        return i % n if wrap else np.clip(i, 0, n - 1)

    c0, c1, r0, r1 = at(x0, W, tx), at(x0 + 1, W, tx), at(y0, H, ty), at(y0 + 1, H, ty)
    return ((a[r0, c0] * (1 - fx) + a[r0, c1] * fx) * (1 - fy) + (a[r1, c0] * (1 - fx) + a[r1, c1] * fx) * fy)


def dense_uv(shapes, per=12):
    """A dense uv grid plus every level's texel centres and edges (where the surfaces bend)."""
    H, W = shapes[0]
    us = set(np.linspace(0, 1, per * W + 1)) | {(i + 0.5) / w for _, w in shapes for i in range(w)}
    vs = set(np.linspace(0, 1, per * H + 1)) | {(i + 0.5) / h for h, _ in shapes for i in range(h)}
    return np.meshgrid(np.array(sorted(us)), np.array(sorted(vs)))


@pytest.mark.parametrize("shape,tile", [((16, 16), True), ((16, 12), False), ((13, 7), (True, False)),
                                        ((1, 11), True), ((9, 1), False), ((6, 10), (False, True))])
@pytest.mark.parametrize("bits", [8, 32])
def test_max_levels_are_never_below_the_fine_surface(shape, tile, bits):
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    h = field(shape, seed=7, sigma=0.4)
    p = level0(h, bits, tile)
    chain = level_chain(p, ("conservative",), mode="max", tile=(tx, ty), max_ratio=1.0,
                        bilinear_safe=True)["conservative"]
    u, v = dense_uv([shape] + level_shapes(shape))
    fine = bilinear(unit(p[..., 0]), u, v, tx, ty)
    for lv in chain:
        dip = fine - bilinear(unit(lv[..., 0]), u, v, tx, ty)
        assert dip.max() <= 1e-12, f"level {lv.shape[:2]} dips {dip.max():g} under the fine surface"


def test_max_without_the_dilation_dips_under_the_fine_surface():
    """The control: a plain 2x2 maximum is not enough (the test above can fail)."""
    h = field((16, 16), seed=7, sigma=0.4)
    r = unit(level0(h, 8)[..., 0])
    plain = r.reshape(8, 2, 8, 2).max(axis=(1, 3))
    u, v = dense_uv([(16, 16), (8, 8)])
    assert (bilinear(r, u, v, True, True) - bilinear(plain, u, v, True, True)).max() > 0.01
    assert (reduce_max(r, True, True) >= plain).all()


def test_max_support_is_the_dilated_pair_on_even_axes():
    assert [sorted(set(row)) for row in max_support(8, True)] == [[0, 1, 2, 7], [1, 2, 3, 4], [3, 4, 5, 6],
                                                                  [0, 5, 6, 7]]
    assert [sorted(set(row)) for row in max_support(8, False)][0] == [0, 1, 2]
    assert max_support(1, True).tolist() == [[0]]


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_levels_come_from_the_stored_heights_not_the_input(dtype):
    """16-bit or float input stored at 8 bits: level 1 averages the stored 8-bit heights."""
    h = field((8, 8))
    given = (h * 65535).round().astype(np.uint16) if dtype == np.uint16 else h
    sm = make_step_map(given, StepMapSettings(bits=8, levels="average"))
    r = sm.pixels[..., 0].astype(np.float64)
    np.testing.assert_array_equal(sm.levels[0][..., 0], np.rint(r.reshape(4, 2, 4, 2).mean(axis=(1, 3))))
    assert [lv.shape for lv in sm.levels] == [(4, 4, 4), (2, 2, 4), (1, 1, 4)]
    assert sm.levels[-1][0, 0, 1] == 255  # one texel: nothing higher, the widest cone


def test_tiling_changes_the_levels_cones():
    h = field((16, 16), seed=5)
    on = make_step_map(h, StepMapSettings(levels="average"))
    off = make_step_map(h, StepMapSettings(levels="average", tile=False))
    np.testing.assert_array_equal(on.levels[0][..., 0], off.levels[0][..., 0])
    assert (on.levels[0][..., 1] != off.levels[0][..., 1]).any()
    assert off.settings.tile == (False, False) and off.settings.levels == "average"


def test_the_average_chain_by_default_none_on_request_and_bad_modes_refused():
    sm = make_step_map(field((8, 8)))
    assert sm.settings.levels == "average" and len(sm.levels) == 3 and sm.settings.to_meta()["levels"] == "average"
    sm = make_step_map(field((8, 8)), StepMapSettings(levels="none"))
    assert sm.settings.levels == "none" and sm.levels == () and "levels" not in sm.settings.to_meta()
    assert StepMapSettings.from_meta({}, 8).levels == "none"  # a map stored without the key has none
    with pytest.raises(ValueError, match="levels must be one of"):
        StepMapSettings(levels="mean")


def test_atlas_layout_puts_level_k_after_the_widths_before_it():
    levels = [np.full((h, w, 4), k, np.uint8) for k, (h, w) in enumerate(level_shapes((13, 20)), 1)]
    image = atlas(levels)
    assert image.shape == (6, 18, 4)
    assert image[0, 0, 0] == 1 and image[0, 10, 0] == 2 and image[0, 15, 0] == 3 and image[0, 17, 0] == 4
    assert image[1, 17, 0] == 0 and image[3, 10, 0] == 0  # uncovered texels are 0
    assert all((a == b).all() for a, b in zip(split_atlas(image, (13, 20)), levels))


@pytest.mark.parametrize("suffix,bits,cones,mode", [(".png", 8, "conservative", "average"),
                                                    (".png", 16, "quadrant", "max"),
                                                    (".tif", 32, "relaxed", "average"),
                                                    (".exr", 32, "conservative", "max")])
def test_save_and_load_round_trip_the_levels(tmp_path, suffix, bits, cones, mode):
    sm = make_step_map(field((13, 10)), StepMapSettings(bits=bits, cones=cones, levels=mode))
    out = tmp_path / f"m{suffix}"
    save_step_map(sm, out)
    assert levels_path(out).is_file() and levels_path(out).name == f"m_levels{suffix}"
    back = load_step_map(out)
    assert back.settings == sm.settings and len(back.levels) == len(sm.levels) == 3
    for a, b in zip(back.levels + back.second_levels, sm.levels + sm.second_levels):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    assert len(back.second_levels) == (3 if cones == "quadrant" else 0)
    if cones == "quadrant":
        assert levels_path(second_path(out)).is_file()
    with pytest.raises(FormatError, match="is the levels of a step map; load m"):
        load_step_map(levels_path(out))
    levels_path(out).unlink()
    with pytest.raises(FormatError, match="levels image m_levels.* is missing"):
        load_step_map(out)


def test_maps_without_levels_load_and_write_as_before(tmp_path):
    sm = make_step_map(field((8, 8)), StepMapSettings(levels="none"))
    save_step_map(sm, tmp_path / "m.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png"]
    assert load_step_map(tmp_path / "m.png").levels == ()
    bad = make_step_map(field((8, 8)), StepMapSettings(levels="average"))
    bad.levels = bad.levels[:1]
    with pytest.raises(ValueError, match="expected levels of shapes"):
        save_step_map(bad, tmp_path / "bad.png")


def test_a_one_texel_map_has_no_levels_and_says_so(tmp_path):
    sm = make_step_map(np.array([[0.5]], np.float32), StepMapSettings(levels="max"))
    assert sm.levels == () and sm.settings.levels == "none"
    save_step_map(sm, tmp_path / "one.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.png"]


def test_progress_hears_the_levels_and_narrow_cones_warn_once_for_the_chain():
    import warnings

    from csm_assets.warning_codes import NarrowCones

    heard = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sm = make_step_map(field((16, 16)), StepMapSettings(levels="average", max_ratio=1e6),
                           progress=lambda done, total: heard.append((done, total)))
    assert heard[-4:] == [(1, 4), (2, 4), (3, 4), (4, 4)] and len(sm.levels) == 4
    chain = [w for w in caught if w.category is NarrowCones and str(w.message).startswith("levels 1-4: ")]
    assert len(chain) == 1, [str(w.message) for w in caught]


def test_a_tga_too_small_for_the_settings_writes_nothing(tmp_path):
    sm = make_step_map(field((8, 8)), StepMapSettings(levels="average", cones="quadrant", source="s" * 60))
    out = tmp_path / ("n" * 80 + ".tga")
    with pytest.raises(ValueError, match="a .tga holds 323 characters"):
        save_step_map(sm, out)
    assert list(tmp_path.iterdir()) == []
