"""The command line as users run it: a real subprocess, real files, exit codes."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import numpy as np
import pytest
from PIL import Image

from csm_assets import read_step_map, read_step_map_meta, step_map
from csm_assets.cli import main


def run(*args):
    """``python -m csm_assets ARGS`` with the interpreter (and so the install) under test."""
    return subprocess.run([sys.executable, "-m", "csm_assets", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


@pytest.fixture
def depth_png(tmp_path):
    d = np.random.default_rng(2).integers(0, 256, (24, 20), dtype=np.uint8)
    Image.fromarray(d).save(tmp_path / "depth.png")
    return tmp_path / "depth.png", d


def test_stepmap_writes_the_library_result(depth_png, tmp_path):
    src, d = depth_png
    before = src.read_bytes()
    r = run("stepmap", src, "-o", tmp_path / "out.png", "--invert", "--max-ratio", "0.5")
    assert r.returncode == 0, r.stderr
    assert r.stderr == "" and r.stdout == ""  # quiet in scripts
    np.testing.assert_array_equal(read_step_map(tmp_path / "out.png"),
                                  step_map(255 - d, max_ratio=0.5, bilinear_safe=True))  # convert's default
    assert read_step_map_meta(tmp_path / "out.png")["max_ratio"] == 0.5
    assert src.read_bytes() == before
    r = run("stepmap", src, "-o", tmp_path / "paper.png", "--invert", "--max-ratio", "0.5", "--no-bilinear-safe")
    assert r.returncode == 0, r.stderr
    np.testing.assert_array_equal(read_step_map(tmp_path / "paper.png"), step_map(255 - d, max_ratio=0.5))
    assert read_step_map_meta(tmp_path / "paper.png")["bilinear_safe"] is False


@pytest.mark.parametrize("args, dtype", [(["--bits", "16", "--no-tile"], np.uint16), ([], np.float32)])
def test_bits_and_tiling_follow_the_flags(depth_png, tmp_path, args, dtype):
    src, d = depth_png
    out = tmp_path / ("o.tif" if args else "o.exr")  # EXR defaults to float
    assert main(["stepmap", str(src), "-o", str(out), *args]) == 0
    got = read_step_map(out)
    assert got.dtype == dtype
    np.testing.assert_array_equal(got, step_map(d, tile=not args, bits={np.uint16: 16}.get(dtype, 32),
                                                bilinear_safe=True))
    assert read_step_map_meta(out)["tile"] == [not args, not args]


def test_channel_flag(tmp_path):
    rgb = np.zeros((5, 5, 3), np.uint8)
    rgb[..., 2] = np.arange(25).reshape(5, 5) * 10
    Image.fromarray(rgb).save(tmp_path / "c.png")
    assert main(["stepmap", str(tmp_path / "c.png"), "-o", str(tmp_path / "o.png"), "--channel", "B"]) == 0
    np.testing.assert_array_equal(read_step_map(tmp_path / "o.png")[..., 0], rgb[..., 2])


@pytest.mark.parametrize("args, code, text", [
    (["stepmap", "{src}", "-o", "{src}"], 2, "is the input"),
    (["stepmap", "{src}"], 2, "-o/--output"),
    (["stepmap", "{src}", "-o", "{tmp}/o.png", "--bits", "12"], 2, "invalid choice"),
    (["stepmap", "{src}", "-o", "{tmp}/o.png", "--max-ratio", "-1"], 2, "> 0"),
    (["stepmap", "{src}", "-o", "{tmp}/o.jpg"], 2, "o.jpg"),
    (["stepmap", "{src}", "-o", "{tmp}/o.png", "--bits", "32"], 2, "float32"),
    (["stepmap", "{tmp}/none.png", "-o", "{tmp}/o.png"], 3, "none.png: no such file"),
    (["stepmap", "{tmp}/bad.png", "-o", "{tmp}/o.png"], 3, "bad.png"),
    (["stepmap", "{src}", "-o", "{tmp}/no/dir/o.png"], 4, "o.png"),
    (["frobnicate"], 2, "invalid choice"),
])
def test_errors_are_one_line_with_documented_codes(depth_png, tmp_path, args, code, text):
    src, _ = depth_png
    (tmp_path / "bad.png").write_bytes(b"\x89PNG broken")
    r = run(*[a.format(src=src, tmp=tmp_path) for a in args])
    assert r.returncode == code
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("csm-assets: ") and text in lines[0], r.stderr
    assert not (tmp_path / "o.png").exists()


def test_same_file_through_another_name_is_refused(depth_png, tmp_path):
    src, _ = depth_png
    os.link(src, tmp_path / "alias.png")
    assert run("stepmap", src, "-o", tmp_path / "alias.png").returncode == 2


def test_help_documents_every_flag():
    r = run("stepmap", "--help")
    assert r.returncode == 0
    for flag in ["--invert", "--no-tile", "--bits", "--max-ratio", "--channel", "-o"]:
        assert flag in r.stdout
    assert "exit codes" in run("--help").stdout.lower()


def test_progress_shows_on_a_terminal(depth_png, tmp_path):
    src, _ = depth_png
    leader, follower = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "stepmap", str(src), "-o",
                             str(tmp_path / "o.png")], stderr=follower, stdout=subprocess.DEVNULL)
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=120) == 0
    text = b"".join(chunks).decode()
    assert "100%" in text and "wrote" in text
