"""Attacks on orphan removal (``hook``) and orphan reports (``check``) with odd manifests:
an output folder two scenes share (``convert -o`` of each), entries whose files are gone."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from attack import assert_clean_run, run_cli

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def shared_folder(tmp_path: Path) -> Path:
    """wall.gltf and wall2.gltf converted one after the other into out/ (one manifest)."""
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    shutil.copy(tmp_path / "brick_wall.gltf", tmp_path / "wall2.gltf")
    for scene in ("brick_wall.gltf", "wall2.gltf"):
        assert_clean_run(run_cli("convert", scene, "-o", "out", cwd=tmp_path))
    return tmp_path / "out"


def test_hook_that_removes_an_orphan_entry_whose_files_are_gone_exits_1(tmp_path):
    """Was: the scene and its own outputs deleted by hand, ``hook .`` rewrote the manifest
    (the entry removed) and exited 0, so the change went uncommitted."""
    out = shared_folder(tmp_path)
    for gone in (tmp_path / "wall2.gltf", out / "wall2.gltf", out / "wall2_csm.bin"):
        gone.unlink()
    assert_clean_run(run_cli("check", "out", cwd=tmp_path), 1)
    before = (out / "csm-manifest.json").read_bytes()
    r = run_cli("hook", "out", cwd=tmp_path)  # the output folder only: nothing converted
    assert_clean_run(r, 1)
    assert "wall2.gltf" in r.stderr and "stage the removal" in r.stderr, r.stderr
    after = (out / "csm-manifest.json").read_bytes()
    assert after != before and list(json.loads(after)["scenes"]) == ["brick_wall.gltf"]
    assert_clean_run(run_cli("check", "out", cwd=tmp_path))
    assert_clean_run(run_cli("hook", "out", cwd=tmp_path))  # nothing left to remove: 0


def test_check_json_names_a_scene_a_broken_configuration_entry_fails(tmp_path):
    """Was: ``check --json`` left out the scene whose configuration entry names a texture
    that is gone (exit 2, an error on stderr): the report listed only the others."""
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png", "brick_wall.obj",
                 "brick_wall.mtl", "bricks_normal.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    (tmp_path / "csm-assets.toml").write_text('[scenes."*.gltf"]\nheight = { bricks = "gone.png" }\n')
    r = run_cli("check", "--json", ".", cwd=tmp_path)
    assert r.returncode == 2 and "csm-assets.toml:2" in r.stderr and "gone.png" in r.stderr, r.stderr
    rows = {row["scene"]: row for row in json.loads(r.stdout)["scenes"]}
    assert set(rows) == {"brick_wall.gltf", "brick_wall.obj"}, rows
    assert rows["brick_wall.gltf"]["state"] == "error" and "gone.png" in rows["brick_wall.gltf"]["reason"]
    assert rows["brick_wall.obj"]["state"] == "stale"
    r = run_cli("check", ".", cwd=tmp_path)  # the summary counts it (was: '0 of 1 scene(s) up to date')
    assert r.returncode == 2 and "0 of 2 scene(s) up to date, 1 failed (configuration)" in r.stderr, r.stderr


def test_hook_removes_an_orphan_only_under_the_folders_lock(tmp_path):
    """Was: ``hook`` rewrote the manifest and removed files without the output folder's lock,
    so a conversion into that folder meanwhile could lose its entry or a file it shares."""
    import fcntl
    import os
    import subprocess
    import sys
    import time

    out = shared_folder(tmp_path)
    (tmp_path / "wall2.gltf").unlink()
    before = (out / "csm-manifest.json").read_bytes()
    fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # as a conversion into out/ holds it
    try:
        hook = subprocess.Popen([sys.executable, "-m", "csm_assets", "hook", "out"], cwd=tmp_path,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(8)  # far above the removal's milliseconds (and the interpreter's start)
        assert hook.poll() is None and (out / "csm-manifest.json").read_bytes() == before
        assert (out / "wall2.gltf").is_file()
    finally:
        os.close(fd)
    _, err = hook.communicate(timeout=300)
    assert hook.returncode == 1 and "removed" in err, err
    assert list(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == ["brick_wall.gltf"]
    assert not (out / "wall2.gltf").exists() and (out / "brick_wall.gltf").is_file()


def test_an_orphan_entry_naming_the_manifest_among_its_outputs_keeps_it(tmp_path):
    """Was: an entry listing ``csm-manifest.json`` as an output (an edited manifest) made ``hook``
    delete the manifest that still held the other scene's entry; the folder then read as scenes."""
    out = shared_folder(tmp_path)
    m = json.loads((out / "csm-manifest.json").read_text())
    m["scenes"]["wall2.gltf"]["outputs"]["csm-manifest.json"] = "0" * 64
    (out / "csm-manifest.json").write_text(json.dumps(m))
    (tmp_path / "wall2.gltf").unlink()
    assert_clean_run(run_cli("hook", "out", cwd=tmp_path), 1)
    assert list(json.loads((out / "csm-manifest.json").read_text())["scenes"]) == ["brick_wall.gltf"]
    assert_clean_run(run_cli("check", "brick_wall.gltf", "-o", "out", cwd=tmp_path))


def test_a_scene_renamed_in_its_folder_leaves_no_orphan_when_only_the_new_name_is_given(tmp_path):
    """Was: after ``git mv rock.obj boulder.obj`` pre-commit passes only boulder.obj; ``hook
    boulder.obj`` wrote boulder_obj_csm/ and exited 0 after it was staged, leaving rock_obj_csm/
    committed, which ``check .`` then reported orphaned (exit 1)."""
    for name in ("brick_wall.obj", "brick_wall.mtl", "bricks_color.png", "bricks_height.png", "bricks_normal.png"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    assert_clean_run(run_cli("hook", "brick_wall.obj", cwd=tmp_path), 1)
    (tmp_path / "brick_wall.obj").rename(tmp_path / "boulder.obj")
    assert_clean_run(run_cli("check", "boulder.obj", cwd=tmp_path), 1)  # missing outputs, and the orphan
    r = run_cli("hook", "boulder.obj", cwd=tmp_path)
    assert_clean_run(r, 1)
    assert "brick_wall_obj_csm" in r.stderr and "stage the removal" in r.stderr, r.stderr
    assert not (tmp_path / "brick_wall_obj_csm").exists()
    assert_clean_run(run_cli("check", ".", cwd=tmp_path))
    assert_clean_run(run_cli("hook", "boulder.obj", cwd=tmp_path))
