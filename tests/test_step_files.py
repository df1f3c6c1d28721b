"""A step map's files are saved as a set (:mod:`csm_assets.step_files`): the image, a quadrant map's
second image and their levels are all written into temporary files first, then renamed together, so
a failure at any point leaves every old file as it was (never new levels beside an old map)."""

from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import csm_assets.formats.image as image
from csm_assets.bench.maps import terrain
from csm_assets.errors import OutputError
from csm_assets.step_files import StepMapSaver, step_map_files
from csm_assets.stepmap import DEFAULTS, load_step_map, make_step_map, save_step_map

NAMES = ["m_q_levels.png", "m_levels.png", "m_q.png", "m.png"]  # the order they are renamed in


@pytest.fixture(scope="module")
def quadrant_map():
    return make_step_map(terrain(48) / 255.0, DEFAULTS.replace(cones="quadrant", bits=8, levels="average"))


def _old_files(folder) -> dict:
    for name in NAMES:
        (folder / name).write_bytes(f"old {name}".encode())
    return {name: (folder / name).read_bytes() for name in NAMES}


def test_the_files_are_renamed_levels_first_the_map_last(quadrant_map, tmp_path):
    files = step_map_files(tmp_path / "m.png", quadrant_map.settings, quadrant_map.shape)
    assert [p.name for p, _ in files] == NAMES
    assert files[-1][1]["second"] == "m_q.png" and files[-1][1]["levels_image"] == "m_levels.png"


@pytest.mark.parametrize("failing", NAMES)
def test_a_failure_after_a_file_is_written_leaves_every_old_file(quadrant_map, tmp_path, monkeypatch, failing):
    """The failure comes once ``failing`` is written whole (as a read-back that finds the disk full
    would): no file of the set is replaced, no temporary file is left, the error names the map."""
    old = _old_files(tmp_path)
    real = image._write_pixels

    def write_then_fail(pixels, path, description="", into=None, stop=None):
        real(pixels, path, description, into, stop)
        if path.name == failing:
            raise OutputError(path, "injected: no space left on the device")

    monkeypatch.setattr(image, "_write_pixels", write_then_fail)
    with pytest.raises(OutputError, match="injected") as e:
        save_step_map(quadrant_map, tmp_path / "m.png")
    assert str(e.value).startswith(f"{tmp_path / failing}: injected")
    assert failing == "m.png" or str(e.value).endswith("(m.png, which names it, is not written)")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == old
    monkeypatch.undo()
    save_step_map(quadrant_map, tmp_path / "m.png")  # then the whole set, loaded as it was made
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(NAMES)
    back = load_step_map(tmp_path / "m.png")
    np.testing.assert_array_equal(back.second, quadrant_map.second)
    for got, want in zip(back.levels + back.second_levels, quadrant_map.levels + quadrant_map.second_levels):
        np.testing.assert_array_equal(got, want)


def test_ctrl_c_while_level_0_is_written_stops_the_writers_and_leaves_the_old_files(quadrant_map, tmp_path):
    old = _old_files(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        with StepMapSaver(tmp_path / "m.png") as saver:
            saver.start(quadrant_map)  # level 0 on threads, as while the level chain is made
            raise KeyboardInterrupt
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == old


def test_levels_of_the_wrong_shapes_publish_nothing(quadrant_map, tmp_path):
    old = _old_files(tmp_path)
    with pytest.raises(ValueError, match="expected levels of shapes"):
        with StepMapSaver(tmp_path / "m.png") as saver:
            saver.start(quadrant_map)
            saver.finish(quadrant_map.__class__(quadrant_map.pixels, quadrant_map.settings, quadrant_map.second,
                                                levels=quadrant_map.levels[1:]))
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == old


def test_ctrl_c_in_the_level_chain_of_stepmap_leaves_the_old_pair(tmp_path):
    """SIGINT to ``csm-assets stepmap`` once the level chain shows progress (level 0 is being
    written beside it, on a terminal as a person runs it): exit 130, one line, the old map and
    levels as they were, no temporary file."""
    src, out = tmp_path / "t.png", tmp_path / "out.png"
    image._write_pixels(terrain(1024)[:, :, None], src)
    old = {out: b"old map", out.with_name("out_levels.png"): b"old levels"}
    for path, data in old.items():
        path.write_bytes(data)
    master, slave = pty.openpty()
    p = subprocess.Popen([sys.executable, "-m", "csm_assets", "stepmap", str(src), "-o", str(out)],
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave, close_fds=True)
    os.close(slave)
    seen, deadline = b"", time.monotonic() + 300
    try:
        while b"/10 rows" not in seen:  # the chain's progress: levels 1..10 of a 1024^2 map
            assert p.poll() is None and time.monotonic() < deadline, seen[-500:]
            if select.select([master], [], [], 1)[0]:
                seen += _read(master)
        p.send_signal(signal.SIGINT)
        while time.monotonic() < deadline:  # until the child closes the terminal
            if select.select([master], [], [], 1)[0]:
                if not (data := _read(master)):
                    break
                seen += data
    finally:
        os.close(master)
        if p.poll() is None and time.monotonic() >= deadline:
            p.kill()
    assert p.wait(timeout=60) == 130, seen
    assert b"csm-assets: interrupted" in seen and b"Traceback" not in seen
    assert {path: path.read_bytes() for path in tmp_path.iterdir() if path != src} == old


def _read(fd) -> bytes:
    try:
        return os.read(fd, 65536)
    except OSError:  # EIO: the child closed the terminal
        return b""
