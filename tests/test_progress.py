"""Progress on a terminal, through a real pseudo-terminal (python's ``pty``): the CLI's stderr is a
tty, as when a person runs it. A single-scene ``convert`` shows its stages (reading, step maps,
tangents, writing; pick and confirm with --max-error) on one line redrawn in place, then the bar;
``hook`` and ``check`` too; nothing with -q, and nothing in pipes."""

from __future__ import annotations

import os
import pty
import select
import subprocess
import sys
import tempfile
import time

import pytest

from attack import assert_clean_run, run_cli
from conftest import copy_samples, skip_without_gl

GLTF_WALL = ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png", "bricks_normal.png")


def on_terminal(*args, cwd=None, timeout: float = 240) -> tuple[int, str, str]:
    """Run ``csm-assets ARGS`` with stderr on a pty and stdout to a file: (exit code, what the
    terminal received, stdout)."""
    master, slave = pty.openpty()
    with tempfile.TemporaryFile() as out:
        p = subprocess.Popen([sys.executable, "-m", "csm_assets", *map(str, args)], stdin=subprocess.DEVNULL,
                             stdout=out, stderr=slave, cwd=cwd, close_fds=True)
        os.close(slave)
        got, deadline = [], time.monotonic() + timeout
        while True:
            ready, _, _ = select.select([master], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                p.kill()
                raise AssertionError(f"no end after {timeout} s: {b''.join(got)[-500:]!r}")
            try:
                data = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not data:
                break
            got.append(data)
        os.close(master)
        code = p.wait(timeout=30)
        out.seek(0)
        return code, b"".join(got).decode("utf-8", "replace"), out.read().decode()


def _in_order(text: str, *parts: str) -> None:
    at = [text.find(p) for p in parts]
    assert -1 not in at and at == sorted(at), (parts, at, text[-2000:])


@pytest.fixture
def wall(tmp_path):
    return copy_samples(tmp_path / "in", GLTF_WALL) / "brick_wall.gltf"


def test_single_scene_convert_shows_its_stages_on_a_terminal(wall, tmp_path):
    code, term, out = on_terminal("convert", wall, "-o", tmp_path / "out")
    assert code == 0, term
    _in_order(term, "\rbrick_wall.gltf: reading", "\rbrick_wall.gltf: step maps", "% (",
              "\rbrick_wall.gltf: tangents", "\rbrick_wall.gltf: writing", "] 1/1 converted brick_wall.gltf")
    assert "\x1b[K" in term and " s\x1b[K" in term  # redrawn in place, with its clock
    assert "\r" not in out and out.startswith("1 scene(s): 1 converted")  # stdout: the summary only
    assert "Traceback" not in term


def test_no_progress_with_quiet_or_json(wall, tmp_path):
    code, term, out = on_terminal("convert", wall, "-o", tmp_path / "out", "-q")
    assert code == 0 and term == "" and out == ""
    code, term, out = on_terminal("convert", wall, "-o", tmp_path / "out2", "--json")
    assert code == 0 and term == "" and out.startswith("{")


def test_no_progress_in_pipes(wall, tmp_path):
    r = run_cli("convert", wall, "-o", tmp_path / "out")
    assert_clean_run(r)
    assert r.stderr == "" and "\r" not in r.stdout and "reading" not in r.stdout


def test_hook_and_check_show_progress_on_a_terminal(wall, tmp_path):
    code, term, _ = on_terminal("hook", wall)
    assert code == 1, term  # wrote: add them to the commit
    _in_order(term, "brick_wall.gltf: reading", "brick_wall.gltf: writing", "] 1/1 converted brick_wall.gltf")
    code, term, _ = on_terminal("check", wall)
    assert code == 0 and "\rchecking" in term and "1 of 1 scene(s) up to date" in term, term
    code, term, _ = on_terminal("check", wall, "-q")
    assert code == 0 and term == ""


@pytest.mark.slow
def test_max_error_shows_pick_and_confirm(wall, tmp_path):
    skip_without_gl()
    code, term, _ = on_terminal("convert", wall, "-o", tmp_path / "out", "--max-error", "2")
    assert code == 0, term
    _in_order(term, "brick_wall.gltf: reading", "brick_wall.gltf: step maps", "brick_wall.gltf: pick",
              "brick_wall.gltf: tangents", "brick_wall.gltf: confirm", "brick_wall.gltf: writing")


def test_verify_and_bench_trade_show_progress_on_a_terminal(wall, tmp_path):
    skip_without_gl()
    assert on_terminal("convert", wall, "-o", tmp_path / "out", "-q")[0] == 0
    code, term, out = on_terminal("verify", tmp_path / "out" / "brick_wall.gltf", "--size", "32")
    assert code == 0, term
    _in_order(term, "\rbrick_wall.gltf: reading", "\rbrick_wall.gltf: drawing ")
    assert "PASS" in out and "\r" not in out
    code, term, out = on_terminal("bench", "trade", wall.parent / "bricks_height.png", "--size", "16",
                                  "--views", "60")
    assert code == 0, term
    _in_order(term, "\rbricks_height.png: reading", "\rbricks_height.png: measuring exact")
    assert "\r" not in out
