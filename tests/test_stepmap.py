"""The StepMap value: make, save, load (one open), the defaults every command shares, and
the same input through stepmap, convert and verify giving the same map."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import csm_assets as csm
from attack import assert_clean_error, run_cli
from csm_assets.cli import main
from csm_assets.formats import image
from csm_assets.stepmap import DEFAULTS

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def test_min_step_is_derived_from_bilinear_safe_in_one_place():
    assert csm.StepMapSettings().min_step == 0.25 and DEFAULTS.bilinear_safe
    assert csm.StepMapSettings(bilinear_safe=False).min_step == 1.0
    assert csm.StepMapSettings(tile=False).tile == (False, False)


@pytest.mark.parametrize("bits, ext", [(8, ".png"), (16, ".png"), (32, ".exr")])
def test_make_save_load_round_trip_with_one_open(tmp_path, monkeypatch, bits, ext):
    hf = csm.load_heightfield(SAMPLES / "cobbles.png")
    settings = DEFAULTS.replace(bits=bits, tile=(True, False), max_ratio=0.5, source="cobbles.png", levels="none")
    sm = csm.make_step_map(hf, settings)  # the map alone: its levels image is one more open (test_levels.py)
    assert sm.pixels.shape == (*hf.shape, 4) and sm.settings.bits == bits
    np.testing.assert_array_equal(sm.pixels, csm.step_map(hf.exact_heights(), tile=(True, False), max_ratio=0.5,
                                                          bits=bits, bilinear_safe=True))
    path = tmp_path / f"m{ext}"
    csm.save_step_map(sm, path)
    opens = []
    real = image._open
    monkeypatch.setattr(image, "_open", lambda p: opens.append(p) or real(p))
    back = csm.load_step_map(path)
    assert len(opens) == 1
    assert back.settings == sm.settings
    np.testing.assert_array_equal(back.pixels, sm.pixels)


def test_a_map_without_settings_needs_them_given(tmp_path):
    path = tmp_path / "foreign.png"
    csm.write_step_map(csm.step_map(np.zeros((4, 4))), path)  # no settings stored
    with pytest.raises(csm.FormatError, match="no csm-assets step map settings"):
        csm.load_step_map(path)
    sm = csm.load_step_map(path, external=DEFAULTS.replace(max_ratio=2.0, bilinear_safe=False))
    assert sm.settings.cone == "external" and sm.settings.max_ratio == 2.0 and sm.min_step == 1.0
    assert csm.load_step_map(SAMPLES / "cobbles.png", optional=True) is None  # heights, not a step map


def test_raw_altitudes_keep_their_scale_in_the_settings():
    hf = csm.Heightfield(np.array([[10.0, 30.0], [20.0, 50.0]], np.float32), None, {})
    sm = csm.make_step_map(hf)
    assert (sm.settings.height_scale, sm.settings.height_offset) == (40.0, 10.0)


def test_stepmap_convert_and_verify_make_the_same_map(tmp_path, monkeypatch):
    """The sample wall's height texture through the three commands with their defaults."""
    src = tmp_path / "bricks_height.png"
    shutil.copy(SAMPLES / "bricks_height.png", src)
    assert main(["stepmap", str(src), "-o", str(tmp_path / "s.png"), "-q"]) == 0
    by_stepmap = csm.load_step_map(tmp_path / "s.png")

    assert main(["convert", str(SAMPLES / "brick_wall.gltf"), "-o", str(tmp_path / "c"), "-q"]) == 0
    by_convert = csm.load_step_map(tmp_path / "c" / "bricks_height_csm.png")

    seen = {}

    def capture(packed, **kwargs):
        seen.update(kwargs, packed=packed)
        raise KeyboardInterrupt  # stop before rendering: the map is what is compared

    monkeypatch.setattr("csm_assets.cli.verify.verify_step_map", capture)  # the map verify made, as it hands it on
    assert main(["verify", str(src)]) == 130

    np.testing.assert_array_equal(by_stepmap.pixels, by_convert.pixels)
    np.testing.assert_array_equal(seen["packed"], by_convert.pixels)
    assert by_stepmap.settings.replace(source="x") == by_convert.settings.replace(source="x")
    assert seen["min_step"] == by_convert.min_step == 0.25
    assert seen["max_ratio"] == by_convert.settings.max_ratio


def test_render_size_and_steps_defaults_agree(tmp_path):
    import inspect

    from csm_assets.bench import trade
    from csm_assets.verify import maps as verify
    from csm_assets.cli import build_parser

    assert inspect.signature(verify.verify_step_map).parameters["size"].default == verify.RENDER_SIZE
    assert inspect.signature(trade.measure_trade).parameters["size"].default == verify.RENDER_SIZE
    p = build_parser()
    from csm_assets.cli import verify as verify_cli
    assert p.parse_args(["verify", "x.png"]).size is None  # verify's own default, or --distance's
    assert verify_cli.SIZE == verify.RENDER_SIZE
    assert p.parse_args(["bench", "trade", "x.png"]).size == verify.RENDER_SIZE
    assert inspect.signature(verify.verify_step_map).parameters["steps"].default is None  # verify.map_steps
    assert verify.map_steps("loop") == verify.default_steps("loop") == verify.STEPS
    assert verify.default_steps("exact") == 0 and verify.map_steps("exact") == verify.STEPS  # a label only
    from csm_assets.cli.scenes import resolver

    c = p.parse_args(["convert", "x.gltf", "-o", "o"])  # flags not given: None, the settings decide
    assert (c.bits, c.max_ratio, c.bilinear_safe) == (None, None, None)
    o = resolver(c).options(tmp_path / "x.gltf")  # a scene without a configuration: the defaults
    assert (o.bits, o.max_ratio, o.bilinear_safe) == (None, DEFAULTS.max_ratio, DEFAULTS.bilinear_safe)
    assert p.parse_args(["stepmap", "x.png", "-o", "o.png"]).bits is None  # verify.bits chooses
    s = p.parse_args(["stepmap", "x.png", "-o", "o.png"])
    assert (s.max_ratio, s.bilinear_safe) == (DEFAULTS.max_ratio, DEFAULTS.bilinear_safe)
    assert p.parse_args(["stepmap", "x.png", "-o", "o.png", "--no-bilinear-safe"]).bilinear_safe is False


def test_a_bit_depth_the_scene_cannot_hold_is_an_options_error(tmp_path):
    out = tmp_path / "out"
    r = run_cli("convert", str(SAMPLES / "brick_wall.gltf"), "-o", str(out), "--bits", "32")
    assert_clean_error(r, 2, "brick_wall.gltf")
    assert not any(out.glob("*.png"))
