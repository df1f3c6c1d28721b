"""What the converter's attack run still found, each through the real CLI: a finite but huge
scale that overflowed into ``Infinity``, a uri forging a log line, a GIF bomb within the
texel limit under a memory limit, an unreachable ``--scheduler``, Ctrl-C reaching the pool's
workers, and two converts into one folder (the manifest's lock, two real processes)."""

from __future__ import annotations

import fcntl
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from attack import Attack, CliRun, assert_clean_error, assert_clean_run, run_cli
from bombs import gif_bomb, png_bomb
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from csm_assets import limits
from csm_assets.errors import FormatError
from csm_assets.printable import printable

CLI = [sys.executable, "-m", "csm_assets"]


def _tiny_obj_wall(folder: Path, scale: str) -> Path:
    """The OBJ wall shrunk to 2 mm, its displacement scale ``scale``."""
    copy_samples(folder, OBJ_WALL)
    obj = folder / "brick_wall.obj"
    lines = []
    for line in obj.read_text().splitlines():
        if line.startswith("v "):
            line = "v " + " ".join(str(float(x) * 0.002) for x in line.split()[1:])
        lines.append(line)
    obj.write_text("\n".join(lines) + "\n")
    mtl = folder / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("disp -mm 0 0.03", f"disp -mm 0 {scale}"))
    return obj


def test_a_huge_scale_on_a_tiny_mesh_is_refused_not_infinity(tmp_path):
    obj = _tiny_obj_wall(tmp_path / "in", "1e308")
    out = tmp_path / "out"
    with Attack(obj.parent):
        line = assert_clean_error(run_cli("convert", obj, "-o", out), 3, "brick_wall.obj")
    assert "material 'bricks'" in line and "1e+308" in line and "--depth" in line, line
    written = [p.read_text(errors="replace").lower() for p in out.rglob("*") if p.suffix in (".mtl", ".json")]
    assert not any("inf" in t.replace("info", "") for t in written)


def test_the_writers_refuse_a_non_finite_number():
    from csm_assets.formats.csm_params import written
    from csm_assets.scene import CsmSettings

    class Csm:
        depth_scale, max_ratio, tile, height_scale, height_offset = math.inf, 1.0, (True, True), 1.0, 0.0
        variant, steps, min_step, self_shadow, light_size = "exact", 0, 1.0, False, 0.0

    assert CsmSettings  # the real settings carry these attributes
    with pytest.raises(ValueError, match="depthScale inf is not a finite number"):
        written(Csm())


def test_a_uri_cannot_forge_a_log_line(tmp_path):
    """A height texture uri holding a newline and an error-shaped text, and an escape
    sequence: one warning line, escaped; no forged error line."""
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    path = folder / "brick_wall.gltf"
    doc = json.loads(path.read_text())
    doc["images"][1]["uri"] = "my gone.png\ncsm-assets: error: forged\x1b[2J\u2028x.png"
    path.write_text(json.dumps(doc))
    r = run_cli("convert", path, "-o", tmp_path / "out")
    warnings = assert_clean_run(r)
    assert not [x for x in r.stderr.splitlines() if x.startswith("csm-assets: error")], r.stderr
    (line,) = [w for w in warnings if "gone.png" in w]
    assert "my gone.png\\ncsm-assets: error: forged\\x1b[2J\\u2028x.png" in line, line
    assert "\x1b" not in r.stderr and "\u2028" not in r.stderr


def test_printable_escapes_controls_only():
    assert printable("a\nb\r\tc\x00\x7f\x9b\u202e ü 漢") == "a\\nb\\r\\tc\\x00\\x7f\\x9b\\u202e ü 漢"


def _limited(*args, address_space: int) -> tuple[CliRun, float]:
    """The CLI under ``ulimit -v address_space`` (through a wrapper process, so the peak is
    its own): its run and its peak memory in MB."""
    code = ("import resource, subprocess, sys; lim = int(sys.argv[1]); "
            "r = subprocess.run(sys.argv[2:], capture_output=True, text=True, "
            "preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (lim, lim))); "
            "sys.stderr.write(r.stderr); print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    r = subprocess.run([sys.executable, "-c", code, str(address_space), *CLI, *map(str, args)],
                       capture_output=True, text=True, timeout=120)
    rc, kb = r.stdout.split()
    return CliRun(int(rc), "", r.stderr), int(kb) / 1024


@pytest.mark.parametrize("bomb", [gif_bomb, png_bomb])
def test_a_bomb_within_the_texel_limit_says_what_memory_it_needs(tmp_path, bomb):
    """13000x13000 (under the texel limit) under a 3 GiB address space: refused from its
    header, before decoding, with the memory it needs, what bounds it and the limit to lower."""
    src = bomb(tmp_path / f"bomb{'.gif' if bomb is gif_bomb else '.png'}", 13000)
    r, peak = _limited("stepmap", src, "-o", tmp_path / "out.png", address_space=3 << 30)
    line = assert_clean_error(r, 3, src.name)
    assert "13000x13000" in line and "GiB of memory" in line and "ulimit -v" in line, line
    assert "lower CSM_ASSETS_MAX_TEXELS" in line and "MemoryError" not in line, line
    assert peak < 500, f"{peak:.0f} MB: decoded before the check"
    assert not (tmp_path / "out.png").exists()


def test_check_memory_counts_the_step_map_not_the_file(monkeypatch):
    monkeypatch.setattr(limits, "available_memory", lambda: (10 * limits.BYTES_PER_TEXEL, "memory available"))
    limits.check_memory("x.png", 10, "a 5x2-pixel image")
    with pytest.raises(FormatError, match=r"x.png: a 11x1-pixel image \(11 texels\) needs about .* GiB of memory "
                                          r".* memory available leaves .*lower CSM_ASSETS_MAX_TEXELS .* to 10 or less"):
        limits.check_memory("x.png", 11, "a 11x1-pixel image")


def test_an_unreachable_scheduler_is_named(tmp_path):
    folder = copy_samples(tmp_path / "in", GLTF_WALL)
    t0 = time.monotonic()
    r = run_cli("convert", folder / "brick_wall.gltf", "-o", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:1")
    line = assert_clean_error(r, 2)
    assert line.startswith("csm-assets: error: --scheduler tcp://127.0.0.1:1: cannot reach"), line
    assert time.monotonic() - t0 < 25  # no 30 s of retries against a refused port


def _batch(tmp_path, n: int) -> Path:
    src = tmp_path / "in"
    for i in range(n):
        copy_samples(src / f"s{i}", OBJ_WALL)
    return src


def _group_alive(pgid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def _workers(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmd = (stat.parent / "cmdline").read_text()
        except OSError:
            continue
        if int(fields[1]) == pid and "spawn_main" in cmd:
            kids.append(int(stat.parent.name))
    return kids


def test_ctrl_c_of_a_batch_is_one_message_from_the_main_process(tmp_path):
    """SIGINT to the whole process group (a terminal's Ctrl-C) while the workers convert:
    exit 130, one line, no worker traceback, every process of the group gone."""
    src = _batch(tmp_path, 5)
    p = subprocess.Popen([*CLI, "convert", str(src), "-o", str(tmp_path / "out"), "--jobs", "2"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert p.stdout.readline().startswith("[1/5] "), "no scene finished"
        os.killpg(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130, err
    assert err == "csm-assets: interrupted; outputs were left as they were\n", err
    deadline = time.monotonic() + 10
    while _group_alive(p.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _group_alive(p.pid)
    assert not list((tmp_path / "out").rglob(".csm-stage-*"))


STOP_IN_A_CALLBACK = """
import ctypes, os, signal, time
from csm_assets.convert import workers
workers.worker_start(os.getppid())
@ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
def compare(a, b):  # Python called back from C, as numba's compiler calls llvmlite's object cache
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.05)  # the handler runs here, inside the callback
    return 0
items = (ctypes.c_int * 2)()
ctypes.CDLL(None).qsort(items, 2, ctypes.sizeof(ctypes.c_int), compare)
time.sleep(5)
print("ran on")
"""


def test_a_stop_inside_a_c_callback_still_stops_the_worker_quietly():
    """SIGTERM (the pool's stop after Ctrl-C) taken while Python runs inside a C callback: the
    SystemExit cannot unwind there, so the worker sends itself the signal again and stops at the
    next line outside it, exit 130 without a word. (On a fresh clone numba compiles in the
    workers, and the first Ctrl-C printed "Exception ignored ... SystemExit: 130" and a traceback.)"""
    p = subprocess.run([sys.executable, "-c", STOP_IN_A_CALLBACK], capture_output=True, text=True, timeout=60)
    assert (p.returncode, p.stdout, p.stderr) == (130, "", "")


def test_workers_ignore_sigint(tmp_path):
    """SIGINT sent to the pool's workers alone does nothing: the batch finishes, all converted."""
    src = _batch(tmp_path, 4)
    p = subprocess.Popen([*CLI, "convert", str(src), "-o", str(tmp_path / "out"), "--jobs", "2"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while len(workers) < 2 and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.1)
        workers = _workers(p.pid)
    for w in workers:
        os.kill(w, signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert workers, "no workers seen"
    assert p.returncode == 0 and "Traceback" not in err, err
    assert out.count(" converted ") == 4, out


def test_two_converts_into_one_folder_keep_both_entries(tmp_path):
    """Two processes converting different scenes into one folder at once: the manifest keeps
    both (the folder is locked around its read-modify-write); while a third process holds the
    lock, a convert waits for it."""
    a = copy_samples(tmp_path / "a", GLTF_WALL) / "brick_wall.gltf"
    b = copy_samples(tmp_path / "b", OBJ_WALL) / "brick_wall.obj"
    out = tmp_path / "out"
    procs = [subprocess.Popen([*CLI, "convert", str(s), "-o", str(out), "-q"], stderr=subprocess.PIPE, text=True)
             for s in (a, b)]
    for p in procs:
        assert p.wait(120) == 0, p.stderr.read()
    assert sorted(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == ["brick_wall.gltf",
                                                                                       "brick_wall.obj"]
    fd = os.open(out, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        p = subprocess.Popen([*CLI, "convert", str(a), "-o", str(out), "-q", "--force"], stderr=subprocess.PIPE,
                             text=True)
        time.sleep(4)
        assert p.poll() is None, "convert did not wait for the folder's lock"
    finally:
        os.close(fd)
    assert p.wait(120) == 0, p.stderr.read()
    assert len(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == 2
