"""Atomic outputs: all or nothing, old output kept on failure, normal permissions."""

from __future__ import annotations

import os
import signal
import stat

import pytest

import csm_assets.atomic
from csm_assets.atomic import atomic_path, atomic_paths
from csm_assets.errors import OutputError


def test_replaces_on_success_and_keeps_suffix(tmp_path):
    out = tmp_path / "a.png"
    out.write_text("old")
    with atomic_path(out) as tmp:
        assert tmp.suffix == ".png" and tmp.parent == tmp_path and tmp != out
        tmp.write_text("new")
        assert out.read_text() == "old"
    assert out.read_text() == "new"
    assert os.listdir(tmp_path) == ["a.png"]


def test_failure_keeps_old_output(tmp_path):
    out = tmp_path / "a.png"
    out.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert out.read_text() == "old" and os.listdir(tmp_path) == ["a.png"]


def test_new_file_follows_umask_and_old_mode_is_kept(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "n.png") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "n.png").stat().st_mode) == 0o644
    os.chmod(tmp_path / "n.png", 0o640)
    with atomic_path(tmp_path / "n.png") as tmp:
        tmp.write_text("y")
    assert stat.S_IMODE((tmp_path / "n.png").stat().st_mode) == 0o640


def test_a_link_to_a_device_is_replaced_by_a_file_of_the_umask_s_mode(tmp_path):
    """An output name that is a link to /dev/zero (mode 0666) becomes a regular file with the
    permissions of a new output, not a world-writable one; the device is untouched."""
    out = tmp_path / "o.png"
    out.symlink_to("/dev/zero")
    old = os.umask(0o022)
    try:
        with atomic_path(out) as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    st = out.lstat()
    assert stat.S_ISREG(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o644
    assert stat.S_ISCHR(os.stat("/dev/zero").st_mode)


def test_missing_directory_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match="missing"):
        with atomic_path(tmp_path / "missing" / "a.png"):
            pass


def test_files_that_go_together_are_renamed_together_or_not_at_all(tmp_path):
    """A failure after the first file is written whole leaves both old files and no temporary file."""
    a, b = tmp_path / "m_levels.png", tmp_path / "m.png"
    a.write_text("old levels")
    b.write_text("old map")
    with pytest.raises(OutputError, match="disk full"):
        with atomic_paths([a, b]) as (ta, tb):
            ta.write_text("new levels")
            raise OutputError(b, "disk full")
    assert (a.read_text(), b.read_text()) == ("old levels", "old map")
    assert sorted(os.listdir(tmp_path)) == ["m.png", "m_levels.png"]
    with atomic_paths([a, b]) as (ta, tb):
        ta.write_text("new levels")
        tb.write_text("new map")
    assert (a.read_text(), b.read_text()) == ("new levels", "new map")
    assert sorted(os.listdir(tmp_path)) == ["m.png", "m_levels.png"]


def test_ctrl_c_between_the_renames_waits_for_the_last(tmp_path, monkeypatch):
    """SIGINT delivered right after the first rename: the second file is renamed too, then the
    KeyboardInterrupt comes (never new levels beside an old map)."""
    a, b = tmp_path / "m_levels.png", tmp_path / "m.png"
    real = os.replace

    def replace_then_ctrl_c(src, dst):
        real(src, dst)
        signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(csm_assets.atomic.os, "replace", replace_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        with atomic_paths([a, b]) as (ta, tb):
            ta.write_text("new levels")
            tb.write_text("new map")
    assert (a.read_text(), b.read_text()) == ("new levels", "new map")
    assert sorted(os.listdir(tmp_path)) == ["m.png", "m_levels.png"]
