"""Maps one texel thin and 65536 long (1xN and Nx1, issue 34): the bit choice never keeps a
depth that stores cones wider than exact (CSM301: at 8 bits, a cone one column of 1/65536 wide
under a full-height step is narrower than one step) when 16 bits store them exactly; and verify
refuses a map wider or taller than the GL limit (GL_MAX_TEXTURE_SIZE, queried from its context)
with one error line naming the file and the limit, exit 3, before any upload."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, copy_samples, skip_without_gl
from csm_assets.formats.image import write
from csm_assets.heightfield import Heightfield
from csm_assets.stepmap import StepMapSettings, make_step_map
from csm_assets.verify.bits import chooser
from csm_assets.warning_codes import NarrowCones

LONG = 65536


def rough(shape, seed=7) -> np.ndarray:
    """Random 8-bit heights: neighbours a whole height apart, the narrowest cones there are."""
    return np.random.default_rng(seed).integers(0, 256, shape).astype(np.uint8)


@pytest.mark.parametrize("shape", [(1, LONG), (LONG, 1)])
def test_the_bit_choice_stores_every_cone_exactly_on_a_long_map(shape):
    heights = rough(shape).astype(np.float32) / 255
    with warnings.catch_warnings():
        warnings.simplefilter("error", NarrowCones)  # nothing stored wider than exact at the bits chosen
        sm = make_step_map(heights, StepMapSettings(), choose=chooser(0.1))
    assert sm.settings.bits == sm.choice.bits == 16 and sm.pixels.dtype == np.uint16
    assert "CSM301" in sm.choice.reason and "16 bits store them exactly" in sm.choice.reason
    with pytest.warns(NarrowCones):  # the case itself: at 8 bits some cones are one step, wider than exact
        make_step_map(heights, StepMapSettings(bits=8))
    # a map whose cones all fit 8 bits keeps 8: the rule costs nothing there
    smooth = np.round(255 * (0.5 + 0.5 * np.sin(np.linspace(0, 40, LONG))))[None, :].astype(np.float32) / 255
    assert make_step_map(smooth, StepMapSettings(), choose=chooser(0.1)).settings.bits == 8


@pytest.mark.parametrize("shape", [(1, LONG), (LONG, 1)])
def test_verify_refuses_a_map_over_the_gl_limit_naming_it(shape, tmp_path):
    skip_without_gl()
    src = tmp_path / "long.png"
    write(Heightfield(rough(shape).astype(np.float32) / 255), src)  # a 16-bit PNG of 8-bit levels
    r = run_cli("stepmap", src, "-o", tmp_path / "long_csm.png", "--json")
    lines = assert_clean_run(r)
    assert not [x for x in lines if "CSM301" in x], lines  # (CSM304: no bits make this relief pass)
    assert json.loads(r.stdout)["bits"]["bits"] == 16
    for target in (tmp_path / "long_csm.png", src):  # a step map, and a height map verify makes one of
        r = run_cli("verify", target)
        line = assert_clean_error(r, 3, target.name)
        w, h = shape[1], shape[0]
        assert f"a {w}x{h} step map is larger than this OpenGL" in line and "GL_MAX_TEXTURE_SIZE" in line, line
        assert "texels a side" in line
        assert "GL_INVALID_VALUE" not in r.stderr and not r.stdout


def test_a_scene_with_a_map_over_the_gl_limit_converts_and_verify_refuses_it(tmp_path):
    skip_without_gl()
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    write(Heightfield(rough((1, LONG)).astype(np.float32) / 255), src / "long.png")
    out = tmp_path / "out"
    assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", out, "--height", f"bricks={src / 'long.png'}"))
    line = assert_clean_error(run_cli("verify", out / "brick_wall.gltf"), 3, "long_csm.png")
    assert "GL_MAX_TEXTURE_SIZE" in line
    # --max-error picks by drawing the map: refused alike, the scene not written
    r = run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "picked", "--height", f"bricks={src / 'long.png'}",
                "--max-error", "1")
    assert r.returncode == 3 and "long_csm.png" in r.stderr and "GL_MAX_TEXTURE_SIZE" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "picked" / "brick_wall.gltf").exists()
