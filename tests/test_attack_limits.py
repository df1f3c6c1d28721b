"""Attacks on memory: decompression bombs and oversized files refused before allocating.

Each CLI case runs the real command in a subprocess and measures its peak memory, so a
limit that is checked after the allocation fails here.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from attack import Attack, CliRun, assert_clean_error, run_cli
from bombs import gif_bomb, png_bomb, tiff_bomb
from PIL import Image

from csm_assets.errors import FormatError
from csm_assets.formats import load_heightfield

TEXELS = "CSM_ASSETS_MAX_TEXELS"


def _peak_mb(*args, env=None) -> tuple[int, str, float]:
    """Exit code, stderr and peak resident memory (MB) of ``csm-assets ARGS``."""
    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "sys.stderr.write(r.stderr); "
            "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    r = subprocess.run([sys.executable, "-c", code, sys.executable, "-m", "csm_assets", *map(str, args)],
                       capture_output=True, text=True, env=env, timeout=300)
    rc, kb = r.stdout.split()
    return int(rc), r.stderr, int(kb) / 1024


@pytest.fixture(scope="session")
def bomb_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("bombs")
    png_bomb(d / "bomb.png")
    tiff_bomb(d / "bomb.tif")
    gif_bomb(d / "bomb.gif")
    return d


@pytest.mark.parametrize("name", ["bomb.png", "bomb.tif", "bomb.gif"])
def test_decompression_bombs_refused_before_decoding(bomb_dir, tmp_path, name):
    src = bomb_dir / name
    assert src.stat().st_size < 1 << 20
    with Attack(src):
        rc, err, peak = _peak_mb("stepmap", src, "-o", tmp_path / "out.png")
    line = assert_clean_error(CliRun(rc, "", err), 3, name)
    assert "30000x30000" in line and TEXELS in line
    assert peak < 400, f"{peak:.0f} MB: the image was decoded before the check"
    assert not (tmp_path / "out.png").exists()


def test_bomb_in_a_scene_is_an_input_error(bomb_dir, tmp_path):
    """The same check guards a scene's height texture (convert reads it the same way)."""
    import shutil

    from conftest import OBJ_WALL, copy_samples

    scene = copy_samples(tmp_path / "in", OBJ_WALL)
    shutil.copy(bomb_dir / "bomb.png", scene / "bricks_height.png")
    with Attack(scene):
        r = run_cli("convert", scene / "brick_wall.obj", "-o", tmp_path / "out")
    # a texture that cannot be read leaves its material without CSM, with a warning
    assert "Traceback" not in r.stderr
    assert any("bricks_height.png" in line and "over the limit" in line for line in r.stderr.splitlines()), r.stderr


def test_the_limit_is_configurable(tmp_path, monkeypatch):
    p = tmp_path / "h.png"
    Image.fromarray(np.zeros((40, 50), np.uint8)).save(p)
    monkeypatch.setenv(TEXELS, "1999")
    with pytest.raises(FormatError, match=r"h.png: a 50x40-pixel image declares 2,000 texels, over the limit of 1,999"):
        load_heightfield(p)
    monkeypatch.setenv(TEXELS, "2000")
    assert load_heightfield(p).data.shape == (40, 50)


@pytest.mark.parametrize("value", ["abc", "-5", "1.5"])
def test_a_bad_limit_in_the_environment_is_a_usage_error(tmp_path, value):
    p = tmp_path / "h.png"
    Image.fromarray(np.zeros((4, 4), np.uint8)).save(p)
    r = run_cli("stepmap", p, "-o", tmp_path / "o.png", env={**os.environ, TEXELS: value})
    assert_clean_error(r, 2, TEXELS)


def _depth_text(path, rows: int, cols: int):
    row = " ".join(["0.5"] * cols) + "\n"
    with open(path, "w") as f:
        f.write("# Depth Map for Rayshade output file\n")
        for _ in range(rows):
            f.write(row)
    return path


def test_big_depth_text_is_read_lean(tmp_path):
    """A 8 MB z-buffer text: a few bytes of memory per character, no object per value
    (the old reader took 6 GB for 32 MB)."""
    p = _depth_text(tmp_path / "z.txt", 1450, 1450)
    size = p.stat().st_size
    tracemalloc.start()
    try:
        hf = load_heightfield(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert hf.data.shape == (1450, 1450) and float(hf.data[0, 0]) == 0.5
    assert peak < 16 * size, f"peak {peak / 2**20:.0f} MB for a {size / 2**20:.0f} MB file"


def test_32mb_depth_text_over_the_limit(tmp_path):
    p = _depth_text(tmp_path / "z.txt", 2900, 2900)
    assert p.stat().st_size > 32 << 20
    env = {**os.environ, TEXELS: "1000000"}
    with Attack(p):
        rc, err, peak = _peak_mb("stepmap", p, "-o", tmp_path / "o.png", env=env)
    line = assert_clean_error(CliRun(rc, "", err), 3, "z.txt")
    assert "8410000 values" in line and "limit of 1,000,000" in line
    assert peak < 600, f"{peak:.0f} MB"


def test_declared_resolution_over_the_limit(tmp_path):
    p = tmp_path / "r.txt"
    p.write_text("# Resolution for this rendering is 100000x100000\n1 2\n")
    with pytest.raises(FormatError, match="resolution 100000x100000 declares"):
        load_heightfield(p)
