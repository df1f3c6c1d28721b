"""A lock is never granted on a removed output folder (issue 34): convert A creates the folder
and fails late (``--error-on`` after its step maps), removing it; convert B, waiting on A's
lock, then makes the folder again and writes its outputs. Two real processes, A paused at a
hook point while B is seen waiting in ``/proc/locks``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from attack import assert_clean_run, run_cli
from conftest import GLTF_WALL, copy_samples
from hook_points import paused

CLI = [sys.executable, "-m", "csm_assets"]


def _late_failing_scene(folder: Path) -> Path:
    """The glTF wall without normals: CSM201 comes after its step map, so ``--error-on CSM201``
    fails late."""
    src = copy_samples(folder, GLTF_WALL)
    doc = json.loads((src / "brick_wall.gltf").read_text())
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            prim["attributes"].pop("NORMAL", None)
            prim["attributes"].pop("TANGENT", None)
    (src / "flat.gltf").write_text(json.dumps(doc))
    return src / "flat.gltf"


def _waiting_on_a_lock(pid: int, timeout: float = 120) -> None:
    """Return once process ``pid`` is blocked on a lock (a ``->`` line of ``/proc/locks``)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if any(line.split()[1:2] == ["->"] and str(pid) in line.split()
               for line in Path("/proc/locks").read_text().splitlines()):
            return
        time.sleep(0.05)
    raise AssertionError(f"process {pid} never waited on the folder's lock")


@pytest.mark.skipif(not Path("/proc/locks").is_file(), reason="needs Linux's /proc/locks")
def test_a_convert_waiting_on_a_folder_another_removed_makes_it_again(tmp_path):
    a_scene = _late_failing_scene(tmp_path / "a")
    b_scene = copy_samples(tmp_path / "b", GLTF_WALL) / "brick_wall.gltf"
    out = tmp_path / "out"
    a = paused("convert", a_scene, "-o", out, "-q", "--error-on", "CSM201", env=os.environ)
    try:
        assert a.stdout.readline() == "paused\n", a.stderr.read()
        assert out.is_dir()  # A made it and holds its lock
        b = subprocess.Popen([*CLI, "convert", str(b_scene), "-o", str(out), "-q"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        _waiting_on_a_lock(b.pid)
        a.stdin.write("\n")
        a.stdin.flush()
        assert a.wait(120) == 3, a.stderr.read()  # A failed late and removed the folder it made
        b_out, b_err = b.communicate(timeout=300)
    finally:
        for p in (a, *([b] if "b" in locals() else [])):
            if p.poll() is None:
                p.kill()
    assert b.returncode == 0, b_err
    assert "Traceback" not in b_err
    assert sorted(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == ["brick_wall.gltf"]
    assert (out / "bricks_height_csm.png").is_file() and (out / "brick_wall.gltf").is_file()
    assert_clean_run(run_cli("check", b_scene, "-o", out, "-q"))


def test_converts_racing_one_that_fails_late_all_write_their_outputs(tmp_path):
    """Without a hook point: A fails late while B and C start at once into the folder A makes;
    whatever the order, B and C write their outputs and exit 0 (3 rounds)."""
    a_scene = _late_failing_scene(tmp_path / "a")
    b_scene = copy_samples(tmp_path / "b", GLTF_WALL) / "brick_wall.gltf"
    c_scene = copy_samples(tmp_path / "c", GLTF_WALL) / "brick_wall.glb"
    for round_ in range(3):
        out = tmp_path / f"out{round_}"
        runs = [subprocess.Popen([*CLI, "convert", str(s), "-o", str(out), "-q", *extra], stderr=subprocess.PIPE,
                                 text=True)
                for s, extra in ((a_scene, ["--error-on", "CSM201"]), (b_scene, []), (c_scene, []))]
        codes = [p.wait(300) for p in runs]
        errors = [p.stderr.read() for p in runs]
        assert codes == [3, 0, 0], errors
        assert sorted(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == ["brick_wall.glb",
                                                                                           "brick_wall.gltf"]
