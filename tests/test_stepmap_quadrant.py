"""Step maps of quadrant cones: the packed layout (two images), the stored settings, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from attack import assert_clean_error, assert_clean_run, run_cli
from csm_assets import (StepMapSettings, load_step_map, make_step_map, quadrant_cone_ratios, read_step_map_meta,
                        save_step_map, step_map, unpack_step_map)
from csm_assets.cones.quadrant import quadrant_exact
from csm_assets.errors import FormatError
from csm_assets.packing import neighbourhood_min, pack_quadrant_maps
from csm_assets.stepmap import second_path


def field(n=20, m=14, seed=3):
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(seed).random((n, m)), 1.2, mode="wrap")
    return (h - h.min()) / (h.max() - h.min())


def cones_of(packed8):
    """float64 (4, H, W) ratios the shader reads from the two images ((H, W, 8))."""
    first = unpack_step_map(packed8[..., :4])
    second = unpack_step_map(packed8[..., 4:])
    g = [packed8[..., k] for k in (1, 2, 3, 5)]
    top = 1.0 if packed8.dtype == np.float32 else float(np.iinfo(packed8.dtype).max)
    return np.stack([(np.asarray(c, np.float64) / top) ** 2 for c in g]), first, second


@pytest.mark.parametrize("bits", [8, 16, 32])
@pytest.mark.parametrize("tile", [True, (False, True)])
def test_layout_holds_four_cones_never_wider_and_the_slopes(bits, tile):
    h = field()
    p = step_map(h, bits=bits, tile=tile, cones="quadrant")
    assert p.shape == h.shape + (8,) and p.dtype == {8: np.uint8, 16: np.uint16, 32: np.float32}[bits]
    cones, first, second = cones_of(p)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    exact = quadrant_exact(h, tx, ty, 1.0)
    assert (cones <= exact).all(), "a stored quadrant cone is wider than exact"
    step = 1.0 if bits == 32 else 1.0 / np.iinfo(p.dtype).max
    assert (np.sqrt(cones) >= np.sqrt(exact) - step - 1e-7).all()  # rounded down by under one step
    cons = step_map(h, bits=bits, tile=tile)  # the conservative map: same height and slopes
    np.testing.assert_array_equal(p[..., 0], cons[..., 0])
    np.testing.assert_array_equal(p[..., 4], cons[..., 0])
    np.testing.assert_array_equal(p[..., 6:], cons[..., 2:])
    # the narrowest quadrant is the conservative cone, code for code
    np.testing.assert_array_equal(p[..., [1, 2, 3, 5]].min(axis=-1), cons[..., 1])


@pytest.mark.parametrize("bits", [8, 32])
def test_bilinear_safe_pass_runs_per_cone_channel(bits):
    h = field()
    raw = step_map(h, bits=bits, cones="quadrant")
    safe = step_map(h, bits=bits, cones="quadrant", bilinear_safe=True)
    for k in (1, 2, 3, 5):
        np.testing.assert_array_equal(safe[..., k], neighbourhood_min(raw[..., k], True, True).astype(raw.dtype))
    np.testing.assert_array_equal(safe[..., [0, 4, 6, 7]], raw[..., [0, 4, 6, 7]])


def test_pack_quadrant_maps_matches_quadrant_cone_ratios_in_float():
    h = field(9, 11)
    p = pack_quadrant_maps(h, quadrant_exact(h, True, True, 2.0), 2.0, True, True, bits=32)
    got = np.stack([p[..., k].astype(np.float64) ** 2 * 2.0 for k in (1, 2, 3, 5)])
    np.testing.assert_allclose(got, quadrant_cone_ratios(h, max_ratio=2.0), rtol=1e-6)


def test_extremes_one_by_one_and_flat():
    for h in (np.array([[0.4]]), np.zeros((3, 5))):
        p = step_map(h, cones="quadrant")
        assert (p[..., [1, 2, 3, 5]] == 255).all()


@pytest.mark.parametrize("suffix, bits", [(".png", 8), (".png", 16), (".tif", 32), (".exr", 32)])
def test_save_and_load_round_trip_two_images(tmp_path, suffix, bits):
    h = field()
    sm = make_step_map(h, StepMapSettings(cones="quadrant", bits=bits, tile=(True, False)))
    assert sm.second is not None and sm.second.shape == sm.pixels.shape
    out = tmp_path / f"m{suffix}"
    save_step_map(sm, out)
    assert second_path(out) == tmp_path / f"m_q{suffix}" and second_path(out).is_file()
    meta = read_step_map_meta(out)
    assert meta["cones"] == "quadrant" and meta["second"] == f"m_q{suffix}"
    back = load_step_map(out)
    np.testing.assert_array_equal(back.pixels, sm.pixels)
    np.testing.assert_array_equal(back.second, sm.second)
    assert back.settings == sm.settings.replace(source="")
    with pytest.raises(FormatError, match="second image of a quadrant"):
        load_step_map(second_path(out))
    second_path(out).unlink()
    with pytest.raises(FormatError, match="missing"):
        load_step_map(out)


def test_conservative_maps_have_no_second_image(tmp_path):
    sm = make_step_map(field(6, 6))
    assert sm.second is None
    save_step_map(sm, tmp_path / "c.png")
    assert not second_path(tmp_path / "c.png").exists() and load_step_map(tmp_path / "c.png").second is None


def test_stepmap_cli_writes_both_images(tmp_path):
    d = (field() * 255).astype(np.uint8)
    Image.fromarray(d).save(tmp_path / "h.png")
    assert_clean_run(run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "q.png", "--cones", "quadrant"))
    sm = load_step_map(tmp_path / "q.png")
    want = step_map(d, cones="quadrant", bilinear_safe=True)  # the CLI default
    np.testing.assert_array_equal(np.concatenate([sm.pixels, sm.second], -1), want)
    assert sm.settings.cones == "quadrant"
    # the second image must not overwrite the input either
    Image.fromarray(d).save(tmp_path / "x_q.png")
    assert_clean_error(run_cli("stepmap", tmp_path / "x_q.png", "-o", tmp_path / "x.png", "--cones", "quadrant"), 2)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("cones", ["quadrant", "relaxed"])
def test_verify_draws_a_map_with_its_own_variant_only(tmp_path, cones, capsys):
    """verify on a step map of quadrant (both images) or relaxed cones draws the variant that
    draws it, also for --variant all; another variant is refused (exit 2) before any drawing,
    and so is the quadrant variant on a conservative map. The library's verify_file agrees.
    (It drew exact on the first image before: the +u+v cones, wrong for three quarters of the
    rays, failed by 10 texels on the toy box.)"""
    from conftest import skip_without_gl

    from csm_assets.cli import main
    from csm_assets.verify.maps import verify_file

    skip_without_gl()
    d = (field(32, 32) * 255).astype(np.uint8)
    Image.fromarray(d).save(tmp_path / "h.png")
    assert main(["stepmap", str(tmp_path / "h.png"), "-o", str(tmp_path / "m.png"), "--cones", cones, "-q"]) == 0
    assert main(["stepmap", str(tmp_path / "h.png"), "-o", str(tmp_path / "c.png"), "-q"]) == 0
    capsys.readouterr()
    base = ["verify", str(tmp_path / "m.png"), "--size", "32", "--views", "90", "20/290", "--json"]
    for extra in ([], ["--variant", "all"], ["--variant", cones]):
        assert main([*base, *extra]) == 0
        report = json.loads(capsys.readouterr().out)
        assert [v["variant"] for v in report["variants"]] == [cones]
    assert main([*base, "--variant", "exact"]) == 2
    assert f"drawn by the {cones} variant only, not exact" in capsys.readouterr().err
    assert main(["verify", str(tmp_path / "c.png"), "--size", "32", "--variant", "quadrant"]) == 2
    assert "quadrant maps (two images)" in capsys.readouterr().err
    rep = verify_file(tmp_path / "m.png", size=32, views=((20.0, 290.0),))
    assert [v.variant for v in rep.variants] == [cones] and rep.passed
    with pytest.raises(ValueError, match="only"):
        verify_file(tmp_path / "m.png", size=32, variants=("exact",))
    if cones == "quadrant":  # self-shadows read the light ray's quadrant from both images
        assert main([*base, "--shadows", "--light-elevation", "40", "--light-azimuth", "30"]) == 0
        assert json.loads(capsys.readouterr().out)["shadows"]["variant"] == "quadrant"
