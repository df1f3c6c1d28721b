"""The CLI's own lines reach stderr while another thread writes an image (C libraries' stderr
captured: :mod:`csm_assets.cstderr`). fd 2 is the process's: before, a warning written while
level 0 was being written on its thread went into that write's capture and was lost (CSM304
missing from a CI run of ``stepmap``; 5 of 90 runs under load)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

# the capture held 1.5 s, so every write on a thread overlaps what the main thread says meanwhile
SLOW_CAPTURE = """
import contextlib, sys, time
from csm_assets import cstderr
held = cstderr.captured

@contextlib.contextmanager
def slow():
    with held() as out:
        time.sleep(1.5)
        yield out

cstderr.captured = slow
from csm_assets.cli import main
sys.exit(main(sys.argv[1:]))
"""


def run_slow(*args, cwd=None):
    return subprocess.run([sys.executable, "-c", SLOW_CAPTURE, *map(str, args)], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_a_warning_said_while_level_0_is_written_reaches_stderr(tmp_path):
    """Random 16-bit heights warn CSM304 (no bit depth keeps the budget) once the bits are
    chosen, when level 0 is already being written on its thread."""
    from csm_assets.formats.image import write
    from csm_assets.heightfield import Heightfield

    src = tmp_path / "rough.png"
    write(Heightfield(np.random.default_rng(1).random((256, 256))), src)
    r = run_slow("stepmap", src, "-o", tmp_path / "rough_csm.png")
    assert r.returncode == 0, r.stderr
    assert "csm-assets: warning: CSM304" in r.stderr, r.stderr
    assert (tmp_path / "rough_csm.png").is_file() and (tmp_path / "rough_csm_levels.png").is_file()


def test_own_stderr_keeps_lines_out_of_a_threads_capture(tmp_path):
    """The mechanism alone: a thread holds a capture while the main thread writes a line; with
    :func:`~csm_assets.cstderr.own_stderr` the line reaches the real stderr, without it the
    capture takes it (so the test above measures the fix, not luck)."""
    code = """
import sys, threading, time
from csm_assets import cstderr
if sys.argv[1] == "own":
    cstderr.own_stderr()
inside, done = threading.Event(), threading.Event()
def hold():
    with cstderr.captured():
        inside.set()
        done.wait(10)
t = threading.Thread(target=hold)
t.start()
inside.wait(10)
sys.stderr.write("the main thread's line\\n")
done.set()
t.join()
"""
    own = subprocess.run([sys.executable, "-c", code, "own"], capture_output=True, text=True, timeout=60)
    shared = subprocess.run([sys.executable, "-c", code, "shared"], capture_output=True, text=True, timeout=60)
    assert own.returncode == shared.returncode == 0, (own.stderr, shared.stderr)
    assert "the main thread's line" in own.stderr
    assert "the main thread's line" not in shared.stderr


def test_own_stderr_leaves_a_buffer_alone(monkeypatch):
    """Where sys.stderr is no fd 2 (a test's buffer, the library inside another program's
    redirect) nothing is changed."""
    import io

    from csm_assets import cstderr

    buf = io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    assert cstderr.own_stderr() is False and sys.stderr is buf
