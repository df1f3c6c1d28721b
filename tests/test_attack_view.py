"""Attacks on ``csm-assets view``: bad scenes and options fail before serving, with
convert's exit codes and one error line; nothing is written."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from attack import Attack, assert_clean_error, run_cli
from conftest import GLTF_WALL, SAMPLES, copy_samples


def test_missing_scene(tmp_path):
    assert_clean_error(run_cli("view", tmp_path / "nothere.gltf", "--no-browser"), 3, "nothere.gltf")


@pytest.mark.parametrize("name", ["brick_wall.obj", "brick_wall.usda"])
def test_other_formats_are_refused(tmp_path, name):
    folder = copy_samples(tmp_path, [name])
    with Attack(folder):
        line = assert_clean_error(run_cli("view", folder / name, "--no-browser"), 3, name)
    assert "glTF" in line


@pytest.mark.parametrize("content", [b"", b"{not json", b'{"asset": {}}', b"glTF\x02\x00\x00\x00\xff\xff\xff\xff",
                                     b'{"asset": {"version": "2.0"}, "buffers": [{"byteLength": 8, "uri": "gone.bin"}]}'])
def test_malformed_scene(tmp_path, content):
    path = tmp_path / ("s.glb" if content.startswith(b"glTF") else "s.gltf")
    path.write_bytes(content)
    with Attack(tmp_path):
        assert_clean_error(run_cli("view", path, "--no-browser"), 3, path.name)


def test_folder_is_not_a_scene(tmp_path):
    (tmp_path / "d.gltf").mkdir()
    assert_clean_error(run_cli("view", tmp_path / "d.gltf", "--no-browser"), 3, "d.gltf")


@pytest.mark.parametrize("port", ["-1", "65536", "http"])
def test_bad_port(tmp_path, port):
    folder = copy_samples(tmp_path, GLTF_WALL)
    assert_clean_error(run_cli("view", folder / "brick_wall.gltf", "--port", port, "--no-browser"), 2, "--port")


def test_port_taken(tmp_path):
    folder = copy_samples(tmp_path, GLTF_WALL)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        line = assert_clean_error(run_cli("view", folder / "brick_wall.gltf", "--port", port, "--no-browser"),
                                  2, f"--port {port}")
    assert "cannot listen" in line


def test_no_files_written(tmp_path):
    """A refused scene leaves its folder as it was (no cache, no outputs)."""
    folder = copy_samples(tmp_path, ["brick_wall.obj", "brick_wall.mtl"])
    before = sorted(p.name for p in Path(folder).iterdir())
    run_cli("view", folder / "brick_wall.obj", "--no-browser")
    assert sorted(p.name for p in Path(folder).iterdir()) == before
    assert SAMPLES.is_dir()


def test_files_outside_the_folder_are_refused(tmp_path):
    """As convert does: a scene naming ../outside.png is refused (exit 3), nothing is served."""
    import json

    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    doc = json.loads((folder / "brick_wall.gltf").read_text())
    doc["images"][0]["uri"] = "../outside.png"
    (tmp_path / "outside.png").write_bytes((folder / "bricks_color.png").read_bytes())
    (folder / "brick_wall.gltf").write_text(json.dumps(doc))
    with Attack(tmp_path):
        line = assert_clean_error(run_cli("view", folder / "brick_wall.gltf", "--no-browser"), 3, "brick_wall.gltf")
    assert "outside" in line


def test_malformed_step_map_placement(tmp_path):
    """A converted scene whose stepMapTexture's KHR_texture_transform is not numbers: exit 3
    naming its JSON pointer, for view and verify alike (they place the relief by it)."""
    import json

    folder = copy_samples(tmp_path / "src", GLTF_WALL)
    assert run_cli("convert", folder / "brick_wall.gltf", "-o", tmp_path / "out", "-q").returncode == 0
    scene = tmp_path / "out" / "brick_wall.gltf"
    doc = json.loads(scene.read_text())
    info = doc["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"]
    info["extensions"] = {"KHR_texture_transform": {"scale": "big"}}
    scene.write_text(json.dumps(doc))
    with Attack(tmp_path):
        for args in (["view", scene, "--no-browser"], ["verify", scene]):
            line = assert_clean_error(run_cli(*args), 3, "brick_wall.gltf")
            assert "stepMapTexture/extensions/KHR_texture_transform" in line, line
