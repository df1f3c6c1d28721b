"""Library calls from exporters (csm_assets.exporters, csm_assets.depth): one material converted
without a scene file gives what ``convert`` writes; depths against a slow reference."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from area_reference import slow_areas
from hypothesis import given, settings
from hypothesis import strategies as st

import csm_assets as csm
from csm_assets.convert.pipeline import ConvertOptions, convert
from csm_assets.errors import FormatError, OptionError
from csm_assets.exporters import convert_material, read_material_extension
from csm_assets.formats import read_step_map

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
EXT = "EXT_materials_cone_step_mapping"


coords = st.floats(-10, 10, allow_nan=False, width=32)


@st.composite
def meshes(draw):
    n = draw(st.integers(3, 7))
    positions = np.array(draw(st.lists(st.tuples(coords, coords, coords), min_size=n, max_size=n)))
    uvs = np.array(draw(st.lists(st.tuples(coords, coords), min_size=n, max_size=n)))
    faces = np.array(draw(st.lists(st.tuples(*[st.integers(0, n - 1)] * 3), min_size=1, max_size=6)))
    return positions, uvs, faces


@settings(max_examples=60, deadline=None)
@given(st.lists(meshes(), min_size=1, max_size=3), st.floats(0.5, 4.0))
def test_world_per_uv_matches_a_slow_reference_and_scales_with_the_mesh(parts, k):
    fast = csm.world_per_uv(parts)
    world, uv = slow_areas(parts)
    if world < 1e-6 or uv < 1e-6:  # (nearly) degenerate: rounding decides; no area is None
        assert fast is None or math.isfinite(fast)
        return
    assert fast == pytest.approx(math.sqrt(world / uv), rel=1e-4)
    scaled = csm.world_per_uv([(p * k, u, f) for p, u, f in parts])
    assert scaled == pytest.approx(k * fast, rel=1e-9)
    assert csm.texture_depth(0.3, parts) == pytest.approx(0.3 / fast, rel=1e-12)


def test_texture_depth_rules():
    quad = (np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float),
            np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), np.array([[0, 1, 2], [0, 2, 3]]))
    assert csm.world_per_uv([quad]) == pytest.approx(2.0)        # 2 world units per uv unit
    assert csm.texture_depth(0.1, [quad]) == pytest.approx(0.05)
    assert csm.texture_depth(-0.1, [quad]) == pytest.approx(0.05)  # the sign is the heights' (inverted)
    assert csm.texture_depth(0.1, [quad], height_scale=3.0) == pytest.approx(0.15)
    flat_uv = (quad[0], np.zeros((4, 2)), quad[2])
    assert csm.world_per_uv([flat_uv]) is None and csm.texture_depth(0.1, [flat_uv]) == pytest.approx(0.1)
    assert csm.world_per_uv([]) is None


@pytest.mark.parametrize("options", [dict(bits=16), dict(bits=8, variant="loop", steps=12, self_shadow=True,
                                                         light_size=0.05),
                                     dict(cones="relaxed", variant="relaxed", tile=False)])
def test_one_material_as_convert_makes_it(tmp_path, options):
    """convert_material on the sample wall's height and depth gives convert's step map and extension
    (convert's with --levels none: an exported material carries one image, no levels, whatever the options say)."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, src / name)
    convert(src / "brick_wall.gltf", tmp_path / "out", **options, levels="none")
    doc = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())
    written = doc["materials"][0]["extensions"][EXT]
    info = written["stepMapTexture"]
    image = doc["images"][doc["textures"][info["index"]]["source"]]
    sampler = doc["samplers"][doc["textures"][info["index"]]["sampler"]]

    made = convert_material(csm.load_heightfield(src / "bricks_height.png"), written["depthScale"],
                            ConvertOptions(**options), tile=(True, True), height_wraps=(10497, 10497),
                            name="bricks_height")
    assert made.gltf_extension(info) == written
    assert made.step_map.settings.levels == "none" and made.step_map.levels == ()  # ConvertOptions' "average"
    assert [sampler["wrapS"], sampler["wrapT"]] == list(made.wraps)
    out_map = tmp_path / "mine.png"
    out_map.write_bytes(made.data)
    assert np.array_equal(read_step_map(out_map), read_step_map(tmp_path / "out" / image["uri"]))
    assert csm.load_step_map(out_map).settings == made.step_map.settings


def test_variant_left_out_picks_as_the_command_line():
    hf = np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8)
    assert convert_material(hf, 0.1, variant=None).variant == "exact"
    relaxed = convert_material(hf, 0.1, variant=None, cones="relaxed")
    assert (relaxed.variant, relaxed.steps, relaxed.step_map.settings.cones) == ("relaxed", 2, "relaxed")


@pytest.mark.parametrize("options, message", [
    (dict(bits=32), "8 or 16-bit"), (dict(steps=200), "steps must be"), (dict(light_size=0.1), "needs self_shadow"),
    (dict(cones="relaxed", variant="exact"), "relaxed variant"), (dict(variant="auto"), "needs max_error")])
def test_options_no_material_can_carry_are_refused(options, message):
    with pytest.raises(OptionError, match=message):
        convert_material(np.zeros((4, 4), np.float32), 0.1, **options)


def test_options_object_is_not_changed():
    opts = ConvertOptions(variant=None, steps=None)
    convert_material(np.zeros((4, 4), np.float32), 0.1, opts)
    assert opts.variant is None and opts.steps is None


def test_extension_read_back_is_checked():
    made = convert_material(np.zeros((4, 4), np.float32), 0.25, variant="pom", steps=9)
    values = read_material_extension(made.gltf_extension({"index": 2, "texCoord": 1}), "s.gltf", "m")
    assert values["texture"] == {"index": 2, "texCoord": 1}
    assert (values["depth_scale"], values["variant"], values["steps"], values["tile"]) == (0.25, "pom", 9, (True, True))
    with pytest.raises(FormatError, match=r"s.gltf.*material 'm'.*texture index"):
        read_material_extension({"depthScale": 0.1}, "s.gltf", "m")
    with pytest.raises(FormatError, match="variant 'nope'"):
        read_material_extension({**made.gltf_extension({"index": 0}), "variant": "nope"}, "s.gltf", "m")


def test_a_step_map_made_before_is_shared():
    hf = np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8)
    first = convert_material(hf, 0.1, bits=16, name="h")
    second = convert_material(first.step_map, 0.3, bits=16, variant="pom", steps=8, name="h")
    assert second.step_map is first.step_map and second.data == first.data
    assert (second.depth_scale, second.variant, second.steps) == (0.3, "pom", 8)
    with pytest.raises(OptionError, match="other settings"):
        convert_material(first.step_map, 0.1, bits=8, name="h")
    with pytest.raises(OptionError, match="other settings"):
        convert_material(first.step_map, 0.1, bits=16, tile=(False, False), name="h")
