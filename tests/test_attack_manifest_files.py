"""A ``csm-manifest.json`` that is no regular file (issue 34): a FIFO hung ``check`` and
``hook``, a link to ``/dev/zero`` ate memory and blamed the texel limit. Now the manifest is
opened as a regular file of at most ``manifest.MAX_BYTES``, never through a link leading out of
its folder: anything else is a corrupt manifest, as one of the wrong shape is (``check``: stale
with the reason, exit 1; ``convert``/``hook``: exit 4 naming it, nothing overwritten). A scene
file that is a FIFO or a link to a device is refused before a reader opens it (exit 3). Each run
has a timeout far above its bound."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, copy_samples
from csm_assets.convert import manifest

TIMEOUT = 120  # each run takes seconds; a hang would never end


def _fifo(path: Path) -> None:
    os.mkfifo(path)


def _dev_zero(path: Path) -> None:
    path.symlink_to("/dev/zero")


def _huge(path: Path) -> None:
    with open(path, "wb") as f:  # sparse: no disk, no time
        f.truncate(manifest.MAX_BYTES + 1)


def _link_outside(path: Path) -> None:
    elsewhere = path.parent.parent / "elsewhere.json"
    elsewhere.write_text(json.dumps({"version": "0.1.0", "scenes": {}}))
    path.symlink_to(elsewhere)


def _folder(path: Path) -> None:
    path.mkdir()


CASES = {"fifo": (_fifo, "is a FIFO"), "dev-zero": (_dev_zero, "is a link leading outside its output folder"),
         "huge": (_huge, f"is a file of {manifest.MAX_BYTES + 1} bytes"),
         "link-outside": (_link_outside, "is a link leading outside its output folder"),
         "folder": (_folder, "is a folder")}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_manifest_that_is_no_regular_file_is_a_corrupt_manifest(tmp_path, case):
    make, says = CASES[case]
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    scene = src / "brick_wall.gltf"
    beside = src / "brick_wall_gltf_csm"
    beside.mkdir()
    make(beside / manifest.NAME)
    with Attack(*(src / n for n in GLTF_WALL)):
        r = run_cli("check", scene, timeout=TIMEOUT)
        assert r.returncode == 1 and "Traceback" not in r.stderr, r
        assert f"stale: {scene} -> {beside}: {says}" in r.stdout, r.stdout
        for command in (["hook", scene], ["convert", scene, "-o", beside]):
            r = run_cli(*command, timeout=TIMEOUT)
            line = assert_clean_error(r, 4, manifest.NAME)
            assert says in line and "remove it or choose another output folder" in line, line
            assert "TEXELS" not in line
    assert sorted(p.name for p in beside.iterdir()) == [manifest.NAME]  # nothing written beside it


def test_a_link_to_a_manifest_inside_its_folder_is_read(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    scene = src / "brick_wall.gltf"
    beside = src / "brick_wall_gltf_csm"
    assert_clean_run(run_cli("hook", scene, "-q"), 1)
    (beside / manifest.NAME).rename(beside / "kept.json")
    (beside / manifest.NAME).symlink_to("kept.json")
    assert_clean_run(run_cli("check", scene, "-q", timeout=TIMEOUT))
    assert_clean_run(run_cli("convert", scene, "-o", beside, "-q", "--force", timeout=TIMEOUT))
    assert not (beside / manifest.NAME).is_symlink()  # published as a file of its own, as every output is
    assert_clean_run(run_cli("check", scene, "-q", timeout=TIMEOUT))


def test_a_folder_whose_manifest_is_a_fifo_is_an_output_folder(tmp_path):
    """Its files are outputs, never scenes (the manifest is looked at, not opened)."""
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    beside = src / "brick_wall_gltf_csm"
    copy_samples(beside, ["brick_wall.gltf", "brick_wall.bin"])
    os.mkfifo(beside / manifest.NAME)
    r = run_cli("check", src, timeout=TIMEOUT)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r
    assert r.stdout.count("stale: ") == 2, r.stdout  # brick_wall.gltf and .glb beside it, not the copy inside
    assert f"{beside / 'brick_wall.gltf'} ->" not in r.stdout


@pytest.mark.parametrize("make,kind", [(_fifo, "a FIFO"), (_dev_zero, "a character device")])
def test_a_scene_that_is_no_regular_file_is_refused_without_reading_it(tmp_path, make, kind):
    scene = tmp_path / "wall.obj"
    make(scene)
    for command in (["hook", scene], ["convert", scene, "-o", tmp_path / "out"], ["check", scene]):
        line = assert_clean_error(run_cli(*command, timeout=TIMEOUT), 3, "wall.obj")  # check says it as they do
        assert f"is {kind}, not a scene file" in line, line
