"""Against the paper's own preprocessor (../shared/anchors), built with g++ at test time.

Its cones are the exact ones rounded up (+0.5) on non-tiled maps, and wider still when
tiling (its wrap-around skips texels across the corners): ours are never wider.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from csm_assets import step_map

ANCHOR = Path(__file__).resolve().parents[1].parent / "shared" / "anchors" / "dummer_preproc.cpp"


@pytest.fixture(scope="module")
def dummer(tmp_path_factory):
    if not ANCHOR.is_file() or shutil.which("g++") is None:
        pytest.skip("the paper's preprocessor or g++ is absent")
    out = tmp_path_factory.mktemp("dummer")
    exes = {}
    for tile in (True, False):
        exe = out / f"dummer_{tile}"
        subprocess.run(["g++", "-O2", f"-DTILEABLE={str(tile).lower()}", "-o", str(exe), str(ANCHOR)],
                       check=True, capture_output=True)
        exes[tile] = exe
    return exes


def run_dummer(exe, h8: np.ndarray, tmp_path) -> np.ndarray:
    H, W = h8.shape
    (tmp_path / "in.pgm").write_bytes(f"P5 {W} {H} 255\n".encode() + h8.tobytes())
    subprocess.run([str(exe), str(tmp_path / "in.pgm"), str(tmp_path / "out.rgba")], check=True,
                   capture_output=True)
    return np.frombuffer((tmp_path / "out.rgba").read_bytes(), np.uint8).reshape(H, W, 4)


def test_non_tiled_green_is_the_paper_rounded_down(dummer, tmp_path):
    rng = np.random.default_rng(9)
    h8 = (rng.random((40, 56)) ** 4 * 255).astype(np.uint8)
    theirs = run_dummer(dummer[False], h8, tmp_path)[..., 1].astype(int)
    ours = step_map(h8, tile=False)
    np.testing.assert_array_equal(ours[..., 0], h8)
    diff = theirs - ours[..., 1].astype(int)
    assert diff.min() >= 0 and diff.max() <= 1  # floor versus round-to-nearest
    assert (diff == 1).mean() > 0.2


def test_tiled_paper_misses_the_corners(dummer, tmp_path):
    h8 = np.zeros((32, 32), np.uint8)
    h8[0, 0] = 255  # a spike seen only across the corner from the opposite corner
    theirs = run_dummer(dummer[True], h8, tmp_path)[..., 1].astype(int)
    ours = step_map(h8)[..., 1].astype(int)
    assert (ours <= theirs).all()
    assert theirs[31, 31] == 255 and ours[31, 31] == int(np.sqrt(np.hypot(1, 1) / 32) * 255)
