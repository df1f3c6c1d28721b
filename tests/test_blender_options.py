"""The Blender add-on's export options without Blender (no bpy): keywords to properties to
ConvertOptions, refused as convert refuses them, and every option documented in the guide."""

from __future__ import annotations

from pathlib import Path

import pytest

from csm_assets.blender.options import BY_NAME, OPTIONS, check_options, convert_options, keyword_to_property
from csm_assets.convert.pipeline import ConvertOptions
from csm_assets.errors import OptionError

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guides" / "blender.md"


def test_defaults_are_converts():
    opts = convert_options({})
    assert (opts.bits, opts.variant, opts.steps, opts.max_error, opts.tile) == (None, None, 0, None, None)
    d = ConvertOptions()
    assert (opts.cones, opts.self_shadow, opts.light_size, opts.max_ratio, opts.bilinear_safe) == \
        (d.cones, d.self_shadow, d.light_size, d.max_ratio, d.bilinear_safe)
    assert check_options({}).variant == "exact"


def test_keywords_become_the_options_convert_takes():
    values = {k: keyword_to_property(k, v) for k, v in dict(
        bits=16, variant="pom", steps=24, max_error=None, cones="conservative", self_shadow=True,
        light_size=0.05, tile=False, max_ratio=0.5, bilinear_safe=False).items()}
    assert values["bits"] == "16" and values["tile"] == "NO_TILE" and values["max_error"] == 0.0
    opts = convert_options(values)
    assert (opts.bits, opts.variant, opts.steps, opts.self_shadow, opts.tile, opts.bilinear_safe) == \
        (16, "pom", 24, True, False, False)
    assert keyword_to_property("variant", None) == "AUTO" and keyword_to_property("tile", True) == "TILE"
    assert check_options({"max_error": 0.5}).variant == "auto"
    assert check_options({"cones": "relaxed"}).variant == "relaxed"


def test_float_properties_come_back_as_typed():
    import numpy as np

    stored = float(np.float32(0.05))  # what a Blender FloatProperty holds
    assert stored != 0.05 and convert_options({"light_size": stored}).light_size == 0.05


@pytest.mark.parametrize("name, value, error", [
    ("bits", 32, OptionError), ("steps", 500, OptionError), ("steps", 2.5, OptionError),
    ("variant", "best", OptionError), ("self_shadow", 1, OptionError), ("max_ratio", 0, OptionError),
    ("light_size", float("nan"), OptionError), ("nope", 1, TypeError)])
def test_bad_keywords_are_refused(name, value, error):
    with pytest.raises(error):
        keyword_to_property(name, value)


@pytest.mark.parametrize("values, message", [
    ({"light_size": 0.1}, "needs self_shadow"), ({"cones": "relaxed", "variant": "loop"}, "relaxed variant"),
    ({"variant": "auto"}, "needs max_error")])
def test_combinations_no_material_can_carry_are_refused(values, message):
    with pytest.raises(OptionError, match=message):
        check_options(values)


def test_the_guide_lists_every_option():
    text = GUIDE.read_text(encoding="utf-8")
    for option in OPTIONS:
        assert f"| {option.label} | `{option.name}` |" in text, option.name
    assert set(BY_NAME) == {o.name for o in OPTIONS}
    assert "csm-assets blender install" in text


def test_install_names_a_missing_blender():
    from attack import run_cli

    r = run_cli("blender", "install", "--blender", "/nonexistent/blender")
    assert r.returncode == 2 and "/nonexistent/blender: no such Blender executable" in r.stderr, r.stderr
