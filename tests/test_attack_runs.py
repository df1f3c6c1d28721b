"""Attacks on runs: reports, --strict, --jobs, kill -9 of a batch and Ctrl-C of a long
stepmap, through the real CLI (tests/attack.py's contract). Output folders and clashes:
tests/test_attack_outputs.py."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import OBJ_WALL, SAMPLES, copy_samples
from PIL import Image


def _heights(path: Path, seed: int, shape=(32, 32)) -> np.ndarray:
    h = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    Image.fromarray(h).save(path)
    return h


# ---- reports and --strict ----------------------------------------------------------------------

def _warning_scene(tmp_path) -> Path:
    """The OBJ wall whose MTL names a missing color texture besides its heights (one warning)."""
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    mtl = src / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("disp -mm 0 0.03 bricks_height.png", "disp -mm 0 0.03 gone.png"))
    return src / "brick_wall.obj"


def test_strict_turns_warnings_into_exit_3_and_writes_nothing(tmp_path):
    scene = _warning_scene(tmp_path)
    out = tmp_path / "out"
    with Attack(scene.parent):
        r = run_cli("convert", scene, "-o", out, "--strict")
    line = assert_clean_error(r, 3, "brick_wall.obj")
    assert "--strict" in line and any("gone.png" in w for w in r.stderr.splitlines())
    assert not out.exists()
    assert len(assert_clean_run(run_cli("convert", scene, "-o", out))) == 1  # one warning, exit 0
    r = run_cli("convert", scene, "-o", out, "--strict")  # fresh outputs keep their warnings
    assert_clean_error(r, 3, "brick_wall.obj")
    r = run_cli("hook", scene, "--strict")
    assert_clean_error(r, 3, "brick_wall.obj")


def test_scene_without_height_textures_is_reported_unchanged(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    mtl = src / "brick_wall.mtl"
    mtl.write_text("\n".join(line for line in mtl.read_text().splitlines()
                             if not line.startswith(("disp", "map_Bump"))) + "\n")
    r = run_cli("convert", src / "brick_wall.obj", "-o", tmp_path / "out", "--json")
    assert_clean_run(r)
    report = json.loads(r.stdout)
    assert report["results"][0]["status"] == "unchanged"
    assert "0 converted, 1 unchanged" in report["summary"]


def test_off_a_terminal_convert_prints_the_scene_line_and_the_summary(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    r = run_cli("convert", src / "brick_wall.obj", "-o", tmp_path / "out")
    assert_clean_run(r)
    assert r.stderr == ""  # stderr: warnings and errors only
    lines = r.stdout.splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("[1/1] converted ") and "brick_wall.obj" in lines[0]
    assert lines[1].startswith("1 scene(s): 1 converted, 0 unchanged, 0 fresh, 0 failed")
    r = run_cli("convert", src / "brick_wall.obj", "-o", tmp_path / "out", "-q")
    assert r.stdout == r.stderr == ""


# ---- options, kills, interrupts ----------------------------------------------------------------

@pytest.mark.parametrize("jobs", ["0", "-1", "two"])
@pytest.mark.parametrize("command", ["convert", "hook"])
def test_jobs_must_be_a_whole_number_of_at_least_one(tmp_path, jobs, command):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    args = [command, src / "brick_wall.obj", f"--jobs={jobs}"] + (["-o", tmp_path / "out"] if command == "convert" else [])
    with Attack(src):
        assert_clean_error(run_cli(*args), 2, "--jobs")
    assert not (tmp_path / "out").exists()


def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_kill_9_of_a_batch_leaves_no_workers_running(tmp_path):
    src = tmp_path / "in"
    for i in range(6):  # enough work that the workers are busy when the batch dies
        folder = src / f"s{i}"
        copy_samples(folder, OBJ_WALL)
        _heights(folder / "bricks_height.png", i, (384, 384))
    p = subprocess.Popen([sys.executable, "-m", "csm_assets", "convert", str(src), "-o", str(tmp_path / "out"),
                          "--jobs", "2", "-q"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    deadline = time.time() + 60
    staging = []  # a worker converting (not still starting up: that can take seconds on a busy machine)
    while time.time() < deadline and (len(workers) < 2 or not staging):
        time.sleep(0.2)
        workers = [k for k in _children(p.pid) if "spawn_main" in Path(f"/proc/{k}/cmdline").read_text()]
        staging = list((tmp_path / "out").rglob(".csm-stage-*")) if (tmp_path / "out").is_dir() else []
    assert p.poll() is None and len(workers) >= 2 and staging, "the batch ended before its workers could be seen"
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    time.sleep(3)
    left = [w for w in workers if _alive(w)]
    for w in left:
        os.kill(w, signal.SIGKILL)
    assert not left, f"workers {left} outlived the killed batch"
    # the next run cleans up and finishes the job
    r = run_cli("convert", src, "-o", tmp_path / "out", "--jobs", "2")
    assert_clean_run(r)
    assert not list((tmp_path / "out").rglob(".csm-stage-*"))


def test_ctrl_c_during_a_big_stepmap_is_honoured_at_once(tmp_path):
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(2).random((2048, 2048)), 8, mode="wrap")
    h = (h - h.min()) / (h.max() - h.min())
    src = tmp_path / "smooth.png"
    Image.fromarray((h * 65535).astype(np.uint16)).save(src)
    out = tmp_path / "out.png"
    out.write_bytes(b"old output")
    assert_clean_run(run_cli("stepmap", SAMPLES / "cobbles.png", "-o", tmp_path / "warm.png"))  # compiled
    with Attack(src):
        p = subprocess.Popen([sys.executable, "-m", "csm_assets", "stepmap", str(src), "-o", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(3.5)  # reading and the start of the cone kernel (about 10 s on this map)
        assert p.poll() is None
        sent = time.perf_counter()
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        waited = time.perf_counter() - sent
    assert p.returncode == 130, err
    assert "Traceback" not in err and err.startswith("csm-assets: interrupted")
    assert waited < 3, f"took {waited:.1f} s to stop"
    assert out.read_bytes() == b"old output" and sorted(q.name for q in tmp_path.iterdir()) == [
        "out.png", "smooth.png", "warm.png", "warm_levels.png"]  # no out_levels.png either
