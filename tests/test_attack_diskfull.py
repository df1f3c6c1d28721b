"""Attack: the disk fills up while outputs are written. Runs on a small tmpfs mounted in the
test (root only; skipped where mounting is not permitted). Every run ends in exit 0 with
complete, fresh outputs, or exit 4 with one error line and the old outputs left as they were:
never a truncated file published."""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli, run_cli_here, tree_hashes
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from PIL import Image

from csm_assets.formats import read_step_map
from csm_assets.stepmap import levels_path

USD_WALL = ("brick_wall.usda", "bricks_color.png", "bricks_height.png")


@pytest.fixture
def small_fs(tmp_path):
    """A 400 KiB tmpfs at ``tmp_path / 'fs'``; skips where it cannot be mounted."""
    fs = tmp_path / "fs"
    fs.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(fs)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode(errors='replace').strip()}")
    try:
        yield fs
    finally:
        subprocess.run(["umount", "-l", str(fs)], capture_output=True)


def _free(fs) -> int:
    st = os.statvfs(fs)
    return st.f_bavail * st.f_frsize


def _leave(fs, free: int) -> None:
    """Fill ``fs`` so that about ``free`` bytes stay free."""
    filler = fs / "filler"
    filler.unlink(missing_ok=True)
    with open(filler, "wb") as f:
        f.write(b"\0" * max(_free(fs) - free, 0))


def _leftovers(folder) -> list[str]:
    return [p.name for p in folder.rglob("*") if ".tmp" in p.name or p.name.startswith(".csm-stage-")]


@pytest.mark.parametrize("ext", [".png", ".tif", ".exr", ".tga"])
def test_stepmap_on_a_full_disk_keeps_the_old_output(small_fs, tmp_path, ext):
    src = tmp_path / "noise.png"
    Image.fromarray((np.random.default_rng(0).random((128, 128)) * 65535).astype(np.uint16)).save(src)
    assert_clean_run(run_cli_here("stepmap", src, "-o", tmp_path / f"ref{ext}"))
    size = (tmp_path / f"ref{ext}").stat().st_size  # noise does not compress
    out = small_fs / f"map{ext}"
    out.write_bytes(b"the old output")
    levels_path(out).write_bytes(b"the old levels")  # the pair: never new levels beside the old map
    _leave(small_fs, size // 2)
    with Attack(src):
        r = run_cli("stepmap", src, "-o", out)
    assert_clean_error(r, 4, out.name)
    assert out.read_bytes() == b"the old output" and levels_path(out).read_bytes() == b"the old levels"
    assert not _leftovers(small_fs)
    (small_fs / "filler").unlink()
    assert_clean_run(run_cli_here("stepmap", src, "-o", out))  # with room again, it is written whole
    assert np.array_equal(read_step_map(out), read_step_map(tmp_path / f"ref{ext}"))


@pytest.mark.parametrize("scene,files", [("brick_wall.gltf", GLTF_WALL), ("brick_wall.glb", GLTF_WALL),
                                         ("brick_wall.obj", OBJ_WALL), ("brick_wall.usda", USD_WALL)])
def test_convert_on_a_filling_disk_is_all_or_nothing(small_fs, tmp_path, scene, files):
    """At every fill level across the size of the outputs (so the disk runs out in the step
    map, the textures, the buffers, the MTL, the USD layer or the manifest), a conversion
    either succeeds whole or fails with exit 4 and leaves the previous outputs as they were.
    The first conversion runs as a process, the sweep's in this one (run_cli_here)."""
    src = copy_samples(tmp_path / "in", files)
    out = small_fs / "out"
    assert_clean_run(run_cli("convert", src / scene, "-o", out, "--depth", "0.05", "-q"))
    old = tree_hashes(out)
    need = 2 * sum(p.stat().st_size for p in out.rglob("*") if p.is_file()) + (16 << 10)  # staged extras
    results = set()
    with Attack(src):
        for free in sorted({0, 4096, *range(8192, need + 8192, max(need // 6, 4096))}):
            _leave(small_fs, free)
            r = run_cli_here("convert", src / scene, "-o", out, "--depth", "0.1", "-q")
            if r.returncode == 0:
                assert_clean_run(r)
                assert_clean_run(run_cli_here("check", src / scene, "-o", out, "--depth", "0.1", "-q"))
                shutil.rmtree(out)  # back to the old outputs for the next level
                (small_fs / "filler").unlink()
                assert_clean_run(run_cli_here("convert", src / scene, "-o", out, "--depth", "0.05", "-q"))
            else:
                assert_clean_error(r, 4)
                assert tree_hashes(out) == old, f"outputs changed at {free} bytes free"
            assert not _leftovers(out)
            results.add(r.returncode)
    assert results == {0, 4}, results  # the sweep reached both ends
