"""csm_assets.exporters.confirm_material: an exporter's ``max_error`` pick confirmed on the
material's own meshes as ``convert --max-error`` confirms it on the scene (the sample wall,
converted by convert, read back as verify reads it)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import csm_assets as csm
from csm_assets.convert.pick import MARGIN
from csm_assets.convert.pipeline import ConvertOptions, convert
from csm_assets.exporters import confirm_material, convert_material
from csm_assets.verify.scene import load_primitives, read_converted, verify_primitives

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
EXT = "EXT_materials_cone_step_mapping"
BUDGET = 0.05  # texels: on the wall, the quick pick's exact fails at verify's views; convert writes relaxed 1


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    """(converted path, its extension, its meshes and cameras, the heights, the options) at BUDGET."""
    from conftest import skip_without_gl

    skip_without_gl()
    tmp = tmp_path_factory.mktemp("confirm")
    src = tmp / "src"
    src.mkdir()
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, src / name)
    opts = ConvertOptions(max_error=BUDGET, bits=8, variant=None)
    convert(src / "brick_wall.gltf", tmp / "out", **vars(opts))
    path = tmp / "out" / "brick_wall.gltf"
    ext = json.loads(path.read_text())["materials"][0]["extensions"][EXT]
    scene, _, cameras, _ = read_converted(path)
    return path, ext, scene.meshes, cameras, csm.load_heightfield(src / "bricks_height.png"), opts


def test_the_confirmed_pick_is_the_one_convert_writes(wall):
    path, ext, meshes, cameras, heights, opts = wall
    made = convert_material(heights, ext["depthScale"], opts, name="bricks_height")
    assert (made.variant, made.steps) != (ext["variant"], ext["steps"])  # the quick pick alone differs here
    confirmed = confirm_material(made, meshes, opts, heightfield=heights, name="wall", cameras=cameras)
    assert (confirmed.variant, confirmed.steps) == (ext["variant"], ext["steps"])
    assert confirmed.step_map is made.step_map and confirmed.data == made.data and confirmed.warnings == []
    prims, cams = load_primitives(path)  # the pick passes verify on the file, at the tighter budget
    assert verify_primitives(prims, cameras=cams, max_error=MARGIN * BUDGET).passed


def test_an_8_bit_map_that_cannot_meet_the_budget_is_made_again_at_16_bits(wall, tmp_path):
    _, ext, meshes, _, heights, _ = wall
    opts = ConvertOptions(max_error=0.02, bits=8, variant=None)
    made = convert_material(heights, ext["depthScale"], opts, name="bricks_height")
    confirmed = confirm_material(made, meshes, opts, heightfield=heights, name="wall")
    (warning,) = confirmed.warnings
    assert warning.startswith("CSM303 an 8-bit step map cannot meet --max-error 0.02")
    assert confirmed.step_map.settings.bits == 16 and made.step_map.settings.bits == 8
    (tmp_path / "m.png").write_bytes(confirmed.data)
    again = csm.make_step_map(heights, confirmed.step_map.settings)
    assert np.array_equal(csm.read_step_map(tmp_path / "m.png"), again.pixels)
    kept = confirm_material(made, meshes, opts, name="wall")  # no heights to make it again from
    (warning,) = kept.warnings
    assert warning.startswith("CSM302 no setting meets --max-error 0.02")
    assert kept.step_map is made.step_map and (kept.variant, kept.steps) == (made.variant, made.steps)


@pytest.mark.parametrize("options", [dict(bits=8), dict(bits=8, max_error=BUDGET, variant="pom", steps=8)])
def test_nothing_picked_is_returned_as_is(wall, options):
    _, ext, meshes, _, heights, _ = wall
    made = convert_material(heights, ext["depthScale"], **options)
    assert confirm_material(made, meshes, **options) is made
