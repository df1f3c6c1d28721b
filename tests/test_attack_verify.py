"""Attacks on verify: no OpenGL, sizes GL cannot draw, absurd step counts, foreign RGBA maps."""

from __future__ import annotations

import os

import numpy as np
import pytest
from attack import Attack, assert_clean_error, run_cli
from conftest import random_field, skip_without_gl
from PIL import Image

from csm_assets import Heightfield, save_heightfield


@pytest.fixture
def height_png(tmp_path):
    path = tmp_path / "h.png"
    save_heightfield(Heightfield(random_field(32, 8)), path)
    return path


def no_egl_env(tmp_path):
    """EGL finds no vendor (glvnd's vendor files hidden): no context can be made."""
    empty = tmp_path / "no-egl-vendors"
    empty.mkdir(exist_ok=True)
    return {**os.environ, "__EGL_VENDOR_LIBRARY_DIRS": str(empty), "__EGL_VENDOR_LIBRARY_FILENAMES": ""}


def test_without_egl_verify_exits_5_with_one_line(tmp_path, height_png):
    with Attack(height_png):
        r = run_cli("verify", height_png, "--size", "16", env=no_egl_env(tmp_path))
    line = assert_clean_error(r, 5)
    assert "EGL" in line and "apt-get install libegl1 libgl1-mesa-dri libegl-mesa0" in line


def test_without_egl_a_max_error_batch_fails_the_scene_not_the_batch(tmp_path):
    from curved_scenes import write_obj

    src = write_obj(tmp_path / "src")
    with Attack(tmp_path / "src"):
        r = run_cli("convert", src, "-o", tmp_path / "out", "--max-error", "1", env=no_egl_env(tmp_path))
    line = assert_clean_error(r, 5, src.name)
    assert "apt-get install" in line
    assert not (tmp_path / "out" / src.name).exists()


@pytest.mark.parametrize("args, code", [
    (("--steps", "1000000000"), 2), (("--steps", "0"), 2), (("--size", "100000"), 2), (("--size", "4"), 2),
    (("--max-iterations", "0"), 2), (("--max-error", "nan"), 2), (("--views", "95"), 2),
])
def test_absurd_arguments_are_usage_errors(height_png, args, code):
    with Attack(height_png):
        r = run_cli("verify", height_png, *args)
    assert_clean_error(r, code)


def test_size_beyond_what_gl_draws_is_refused_before_allocating():
    skip_without_gl()
    from csm_assets.render.renderer import Renderer

    with pytest.raises(ValueError, match="larger than this OpenGL"):
        Renderer((1 << 20, 8))


def test_rgba_map_without_settings_is_not_read_as_heights(tmp_path):
    rgba = (np.random.default_rng(1).random((16, 16, 4)) * 255).astype(np.uint8)
    path = tmp_path / "foreign.png"
    Image.fromarray(rgba, "RGBA").save(path)
    with Attack(path):
        r = run_cli("verify", path, "--size", "16")
    line = assert_clean_error(r, 3, "foreign.png")
    assert "--step-map" in line and "--height-map" in line


@pytest.fixture(scope="module")
def converted_gltf(tmp_path_factory):
    from curved_scenes import write_gltf

    from csm_assets.convert.pipeline import convert

    base = tmp_path_factory.mktemp("scene")
    src = write_gltf(base / "src")
    convert(src, base / "out")
    return base / "out" / src.name


@pytest.mark.parametrize("field, value, said", [
    ("depthScale", "deep", "depthScale must be a number"), ("depthScale", -1, "depthScale must be a finite number >= 0"),
    ("maxRatio", 0, "maxRatio must be a finite number > 0"),
    ("variant", "steep", "variant 'steep'"), ("steps", 10 ** 9, "steps 1000000000"), ("minStep", 5, "minStep 5"),
    ("stepMapTexture", {"index": 99}, "stepMapTexture/index"), ("stepMapTexture", 3, "stepMapTexture"),
    ("tile", "yes", "tile must be two booleans"),
])
def test_malformed_csm_extension_is_exit_3_naming_the_scene(converted_gltf, tmp_path, field, value, said):
    import json

    doc = json.loads(converted_gltf.read_text())
    doc["materials"][1]["extensions"]["EXT_materials_cone_step_mapping"][field] = value
    bad = converted_gltf.parent / f"bad_{field}.gltf"
    bad.write_text(json.dumps(doc))
    with Attack(bad):
        r = run_cli("verify", bad, "--size", "16", "--views", "90")
    line = assert_clean_error(r, 3, bad.name)
    assert said in line and ("ridges" in line or "/materials/1/" in line)  # the material, by name or pointer


def test_missing_step_map_is_exit_3_naming_it(converted_gltf, tmp_path):
    import shutil

    folder = tmp_path / "copy"
    shutil.copytree(converted_gltf.parent, folder)
    (folder / "ridges_height_csm.png").unlink()
    r = run_cli("verify", folder / converted_gltf.name, "--size", "16", "--views", "90")
    assert_clean_error(r, 3, "ridges_height_csm.png")
