"""Files a scene names that are there but are no regular file (a FIFO, a link to a device):
refused from their ``stat`` with one line naming them, never opened (a FIFO blocks a read for
ever, ``/dev/zero`` never ends). Subprocess timeouts far above a conversion's second."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from attack import assert_clean_error, run_cli

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def test_a_gltf_buffer_that_is_a_fifo_is_refused_not_read(tmp_path):
    """Was: convert, check and hook of brick_wall.gltf whose brick_wall.bin is a FIFO blocked
    for ever (killed after 30 s) in the buffer's read."""
    for name in ("brick_wall.gltf", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    os.mkfifo(tmp_path / "brick_wall.bin")
    for command in (("convert", "brick_wall.gltf", "-o", "out"), ("hook", "brick_wall.gltf")):
        error = assert_clean_error(run_cli(*command, cwd=tmp_path, timeout=300), 3, "brick_wall.gltf")
        assert "buffer 0 (brick_wall.bin) is a FIFO" in error, error
    r = run_cli("check", "brick_wall.gltf", cwd=tmp_path, timeout=300)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr  # never converted: stale
    assert not (tmp_path / "out").exists() and not (tmp_path / "brick_wall_gltf_csm").exists()


def test_a_usd_layer_that_is_a_fifo_is_refused_not_opened(tmp_path):
    """Was: convert of a.usda whose sublayer (or reference) f.usda is a FIFO blocked for ever
    (killed after 30 s) in USD's open of the layer."""
    import pytest

    pytest.importorskip("pxr", reason="USD (usd-core) is not installed")
    for name in ("bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    wall = (SAMPLES / "brick_wall.usda").read_text()
    (tmp_path / "sub.usda").write_text(wall.replace("#usda 1.0\n(", "#usda 1.0\n(\n    subLayers = [@./f.usda@]", 1))
    (tmp_path / "ref.usda").write_text(wall + '\ndef Xform "Extra" (\n    prepend references = @./f.usda@\n)\n{\n}\n')
    os.mkfifo(tmp_path / "f.usda")
    for scene, kind in (("sub.usda", "subLayer"), ("ref.usda", "reference")):
        for command in (("convert", scene, "-o", "out"), ("hook", scene)):
            error = assert_clean_error(run_cli(*command, cwd=tmp_path, timeout=300), 3, scene)
            assert f"{kind} './f.usda'" in error and "is a FIFO, not a layer file" in error, error


def test_a_height_texture_that_is_a_fifo_is_named_for_what_it_is(tmp_path):
    """Was: 'no such file' (--height, stepmap) and 'is missing' (CSM101) for a FIFO that is there."""
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    os.mkfifo(tmp_path / "h.png")
    error = assert_clean_error(run_cli("convert", "brick_wall.gltf", "-o", "o", "--height", "bricks=h.png",
                                       cwd=tmp_path, timeout=300), 3, "h.png")
    assert "is a FIFO, not a file (named by --height bricks=h.png)" in error, error
    error = assert_clean_error(run_cli("stepmap", "h.png", "-o", "s.png", cwd=tmp_path, timeout=300), 3, "h.png")
    assert "is a FIFO, not a file" in error, error
    os.mkfifo(tmp_path / "bricks_height.png")  # the scene's own height texture
    r = run_cli("convert", "brick_wall.gltf", "-o", "o", cwd=tmp_path, timeout=300)
    assert r.returncode == 0 and "CSM101" in r.stderr, r.stderr
    assert "(bricks_height.png is a FIFO, not a file)" in r.stderr, r.stderr


def test_check_of_a_fifo_named_as_a_scene_is_exit_3_as_convert_and_hook_say(tmp_path):
    """Was: 'stale: never converted' (exit 1) where convert and hook said 'is a FIFO' (exit 3)."""
    fifo = tmp_path / "wall.gltf"
    os.mkfifo(fifo)
    for command in (["check", fifo], ["hook", fifo], ["convert", fifo, "-o", tmp_path / "out"]):
        r = run_cli(*command, timeout=120)
        assert r.returncode == 3 and "is a FIFO, not a scene file" in r.stderr, (command, r.stderr)
