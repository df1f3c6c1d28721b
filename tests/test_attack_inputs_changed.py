"""A height texture replaced while it is being converted (issue 34): the manifest never records
the hash of bytes other than those converted. The replacement happens at a fixed point of the
conversion (after the step map was made from the old texels, before publishing), from a
progress callback in this process or from a hook point in the real CLI's process."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, copy_samples
from csm_assets.convert.pipeline import convert
from csm_assets.convert.inputs import InputChanged, Snapshot
from hook_points import replacing


def _other_heights(texture: Path, into: Path, step: int = 3) -> Path:
    """A height texture of the same size as ``texture`` with other texels (every ``step``-th
    row inverted), at ``into``."""
    img = np.asarray(Image.open(texture)).copy()
    img[::step] = 255 - img[::step]
    Image.fromarray(img).save(into)
    return into


def _manifest(out: Path) -> dict:
    return json.loads((out / "csm-manifest.json").read_text())["scenes"]


def test_a_texture_replaced_during_convert_publishes_nothing(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    texture = src / "bricks_height.png"
    new = _other_heights(texture, tmp_path / "new.png")
    out = tmp_path / "out"

    def progress(stage, done, total):
        if stage == "writing" and new.exists():  # the step map was made from the old texels
            os.replace(new, texture)

    with pytest.raises(InputChanged, match="bricks_height.png: changed while it was being converted"):
        convert(src / "brick_wall.gltf", out, progress=progress)
    assert not out.exists()  # nothing published, the folder it made removed
    assert run_cli("check", src / "brick_wall.gltf", "-o", out).returncode == 1
    assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", out, "-q"))
    assert_clean_run(run_cli("check", src / "brick_wall.gltf", "-o", out, "-q"))


def test_hook_with_a_texture_replaced_mid_run_leaves_check_stale_until_a_clean_run(tmp_path):
    """The issue's case through the real hook: its first run made outputs from texture v1; v2 is
    saved; a hook run converting v2 sees v3 saved after its step map was made. That run fails
    (exit 3 naming the texture), leaves v1's outputs, and check calls them stale; the next hook
    run writes outputs equal to a clean conversion of v3."""
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    scene, texture = src / "brick_wall.gltf", src / "bricks_height.png"
    beside = src / "brick_wall_gltf_csm"
    assert_clean_run(run_cli("hook", scene, "-q"), 1)
    v1_outputs = {p.name: p.read_bytes() for p in beside.iterdir()}
    _other_heights(texture, texture)  # v2
    v3 = _other_heights(texture, tmp_path / "v3.png", step=5)
    r = replacing(texture, v3, "hook", scene, "-q", env=os.environ)
    line = assert_clean_error(r, 3, "bricks_height.png")
    assert "changed while it was being converted" in line and "nothing was written" in line
    assert {p.name: p.read_bytes() for p in beside.iterdir()} == v1_outputs  # old outputs intact
    check = run_cli("check", scene)
    assert check.returncode == 1 and "input bricks_height.png changed" in check.stdout, check
    assert_clean_run(run_cli("hook", scene, "-q"), 1)
    assert_clean_run(run_cli("check", scene, "-q"))
    clean = tmp_path / "clean"
    assert_clean_run(run_cli("convert", scene, "-o", clean, "-q"))
    assert (beside / "bricks_height_csm.png").read_bytes() == (clean / "bricks_height_csm.png").read_bytes()
    assert _manifest(beside)["brick_wall.gltf"]["inputs"] == _manifest(clean)["brick_wall.gltf"]["inputs"]


def test_the_second_look_refuses_a_removed_input_and_keeps_the_first_hashes(tmp_path):
    f = tmp_path / "t.png"
    f.write_bytes(b"one")
    seen = Snapshot()
    seen.take([f, tmp_path / "missing.png"])  # a missing file is the reader's to report
    assert seen.confirm([f]) == {f: hashlib.sha256(b"one").hexdigest()}
    os.replace(tmp_path / "t.png", tmp_path / "moved.png")
    with pytest.raises(InputChanged, match="t.png: was removed while it was being converted"):
        seen.confirm([f])


def test_a_texture_replaced_before_its_texels_are_loaded_poisons_no_cache(tmp_path, monkeypatch):
    """The step map cache is keyed by the texture's hash taken before its texels are loaded: a
    texture replaced in between must not leave the new texels' map under the old key."""
    from csm_assets.convert import maps
    from csm_assets.convert.options import ConvertOptions

    src = copy_samples(tmp_path / "in", GLTF_WALL)
    texture = src / "bricks_height.png"
    v1 = texture.read_bytes()
    new = _other_heights(texture, tmp_path / "new.png")
    cache = tmp_path / "cache"
    real = maps.load_heightfield

    def replaced_first(*args, **kwargs):
        if new.exists():
            os.replace(new, texture)
        return real(*args, **kwargs)

    monkeypatch.setattr(maps, "load_heightfield", replaced_first)
    with pytest.raises(InputChanged):
        convert(src / "brick_wall.gltf", tmp_path / "out", ConvertOptions(cache_dir=cache))
    texture.write_bytes(v1)  # back to the first texels: the cache must not answer with the others' map
    convert(src / "brick_wall.gltf", tmp_path / "cached", ConvertOptions(cache_dir=cache))
    convert(src / "brick_wall.gltf", tmp_path / "clean")
    assert (tmp_path / "cached" / "bricks_height_csm.png").read_bytes() == \
        (tmp_path / "clean" / "bricks_height_csm.png").read_bytes()
