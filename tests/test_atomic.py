"""Atomic outputs: all or nothing, old output kept on failure, normal permissions."""

from __future__ import annotations

import os
import stat

import pytest

from csm_assets.atomic import atomic_path
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


def test_missing_directory_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match="missing"):
        with atomic_path(tmp_path / "missing" / "a.png"):
            pass
