"""Attacks on the search for USD composers (every USD file of a layer's repository is read to
tell which layers are parts of another scene): special files named like USD layers."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from attack import assert_clean_run, run_cli

pytest.importorskip("pxr", reason="USD (usd-core) is not installed")
SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def test_a_fifo_named_like_a_usd_layer_elsewhere_in_the_repository_does_not_block(tmp_path):
    """Was: ``check wall/brick_wall.usda`` hung (killed after 60 s) reading ``other/junk.usda``,
    a FIFO, as a possible composer of the wall."""
    if shutil.which("git") is None:
        pytest.skip("needs git")
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    (tmp_path / "wall").mkdir()
    for name in ("brick_wall.usda", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / "wall" / name)
    (tmp_path / "other").mkdir()
    os.mkfifo(tmp_path / "other" / "junk.usda")
    r = run_cli("check", "wall/brick_wall.usda", cwd=tmp_path, timeout=300)  # a second when it does not block
    assert_clean_run(r, 1)
    assert "stale: wall/brick_wall.usda" in r.stdout, r.stdout
    assert_clean_run(run_cli("hook", "wall/brick_wall.usda", cwd=tmp_path, timeout=300), 1)
    assert_clean_run(run_cli("check", ".", cwd=tmp_path, timeout=300))


def test_layers_that_compose_each_other_are_both_scenes(tmp_path):
    """Was: a.usda (the wall) sublayering b.usda, which sublayers a.usda: each counted as a part
    of the other, so neither was converted and ``check .`` said '0 of 0 scene(s) up to date'."""
    for name in ("bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    wall = (SAMPLES / "brick_wall.usda").read_text()
    (tmp_path / "a.usda").write_text(wall.replace("#usda 1.0\n(", "#usda 1.0\n(\n    subLayers = [@./b.usda@]", 1))
    (tmp_path / "b.usda").write_text("#usda 1.0\n(\n    subLayers = [@./a.usda@]\n)\n")
    r = run_cli("check", ".", cwd=tmp_path, timeout=300)
    assert_clean_run(r, 1)
    assert "stale: a.usda" in r.stdout and "stale: b.usda" in r.stdout, r.stdout
    r = run_cli("hook", ".", cwd=tmp_path, timeout=300)
    assert_clean_run(r, 1)
    assert "CSM401" in r.stderr and "cycles" in r.stderr, r.stderr  # USD's own warning is shown
    assert (tmp_path / "a_usda_csm" / "csm-manifest.json").is_file()
    assert_clean_run(run_cli("check", ".", cwd=tmp_path, timeout=300))
