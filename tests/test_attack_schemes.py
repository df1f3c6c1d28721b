"""One scheme rule for every reference a scene makes (csm_assets.references): URLs in any case
and any ``scheme:`` form, Windows drives and UNC paths are refused by the glTF, OBJ and USD
readers alike, and ``view`` never makes the page request another host. A scene opened
through a link from another folder is refused with a message saying so."""

from __future__ import annotations

import json
import socket

import pytest
from pxr import Sdf, Usd

from attack import Attack, assert_clean_error, run_cli
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from csm_assets.errors import FormatError
from csm_assets.formats import gltf, obj, usd
from csm_assets.references import is_data_uri, refusal, scheme
from usd_stages import edit, wall_folder

URLS = ["HTTP://127.0.0.1:9/x.png", "https:host/x.png", "hTtPs://host/x.png", "File:///etc/passwd",
        "ftp:x.png", "data:image/png;base64,AAAA", " http://host/x.png", "ht\ttp://host/x.png",
        "\nhttps://host/x.png", "javascript:alert(1)", "blob:http://host/1"]
PATHS = ["C:\\textures\\x.png", "C:/textures/x.png", "c:x.png", "\\\\host\\share\\x.png", "//host/x.png",
         "\\x.png", "/etc/passwd", "/\\host/x.png"]
FINE = ["x.png", "sub\\map.png", "sub/map.png", "./a:b.png", "a b.png", "..\\x.png", "%48TTP://x", "x.png?y"]


@pytest.mark.parametrize("ref", URLS)
def test_urls_in_any_case_and_form_are_refused(ref):
    assert refusal(ref) and refusal(ref).startswith("a URL")


@pytest.mark.parametrize("ref", PATHS)
def test_absolute_drive_and_unc_paths_are_refused(ref):
    why = refusal(ref)
    assert why and ("absolute" in why or "UNC" in why), why


@pytest.mark.parametrize("ref", FINE)
def test_relative_names_pass(ref):
    assert refusal(ref) is None and scheme(ref) is None


def test_data_uris_in_any_case():
    assert is_data_uri("DATA:application/octet-stream;base64,AA") and is_data_uri("Data:,x")
    assert not is_data_uri("data.png") and not is_data_uri(None) and not is_data_uri("./data:x")


def _gltf_with(folder, uri, where="image"):
    path = folder / "brick_wall.gltf"
    doc = json.loads(path.read_text())
    if where == "image":
        doc["images"][1]["uri"] = uri
    else:
        doc["buffers"][0]["uri"] = uri
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("uri", ["HTTP://127.0.0.1:9/x.png", "https:host/x.png", "C:\\x.png", "\\\\host\\share\\x.png"])
@pytest.mark.parametrize("where", ["image", "buffer"])
def test_gltf_reader_refuses(tmp_path, uri, where):
    path = _gltf_with(copy_samples(tmp_path, GLTF_WALL), uri, where)
    with pytest.raises(FormatError, match="absolute paths and URLs are refused"):
        gltf.read(path)


def test_gltf_reader_reads_an_upper_case_data_uri(tmp_path):
    folder = copy_samples(tmp_path, GLTF_WALL)
    import base64

    data = base64.b64encode((folder / "brick_wall.bin").read_bytes()).decode()
    path = _gltf_with(folder, f"DATA:application/octet-stream;BASE64,{data}", "buffer")
    (folder / "brick_wall.bin").unlink()
    assert gltf.read(path).meshes


@pytest.mark.parametrize("line", ["map_Kd HTTP://127.0.0.1:9/x.png", "disp -mm 0 0.03 https:host/h.png",
                                  "map_Bump C:\\x.png", "disp \\\\host\\share\\h.png"])
def test_obj_reader_refuses(tmp_path, line):
    folder = copy_samples(tmp_path, OBJ_WALL)
    mtl = folder / "brick_wall.mtl"
    keep = [x for x in mtl.read_text().splitlines() if not x.startswith(line.split()[0] + " ")]
    mtl.write_text("\n".join(keep + [line]) + "\n")
    with pytest.raises(FormatError, match="absolute paths and URLs are refused"):
        obj.read(folder / "brick_wall.obj")


def test_obj_mtllib_url_is_refused(tmp_path):
    folder = copy_samples(tmp_path, OBJ_WALL)
    path = folder / "brick_wall.obj"
    path.write_text(path.read_text().replace("mtllib brick_wall.mtl", "mtllib HTTPS:host/x.mtl"))
    with pytest.raises(FormatError, match="absolute paths and URLs are refused"):
        obj.read(path)


@pytest.mark.parametrize("asset", ["HTTP://127.0.0.1:9/x.png", "https:host/x.png", "C:/x.png"])
def test_usd_texture_asset_is_refused(tmp_path, asset):
    path = wall_folder(tmp_path) / "brick_wall.usda"
    text = path.read_text()
    assert "@./bricks_height.png@" in text
    path.write_text(text.replace("@./bricks_height.png@", f"@{asset}@"))
    with pytest.raises(FormatError, match="absolute paths and URLs are refused"):
        usd.read(path)


@pytest.mark.parametrize("asset", ["Https:host/x.usda", "HTTP://127.0.0.1:9/x.usda"])
def test_usd_sublayer_url_is_refused(tmp_path, asset):
    path = wall_folder(tmp_path) / "brick_wall.usda"
    edit(path, lambda stage: stage.GetRootLayer().subLayerPaths.append(asset))
    with pytest.raises(FormatError, match="absolute paths and URLs are refused"):
        usd.read(path)


@pytest.mark.parametrize("command", ["view", "convert", "verify"])
def test_no_request_to_another_host(tmp_path, command):
    """A mixed-case URL in a scene: view, convert and verify stop with exit 3 before anything
    asks the named host (a listening socket here) for the file."""
    with socket.socket() as beacon:
        beacon.bind(("127.0.0.1", 0))
        beacon.listen(4)
        beacon.settimeout(0.5)
        port = beacon.getsockname()[1]
        path = _gltf_with(copy_samples(tmp_path / "s", GLTF_WALL), f"HTTP://127.0.0.1:{port}/x.png")
        extra = {"view": ["--no-browser"], "convert": ["-o", tmp_path / "out"], "verify": []}[command]
        with Attack(path.parent):
            line = assert_clean_error(run_cli(command, path, *extra, timeout=120), 3, path.name)
        assert "URLs are refused" in line and "HTTP://" in line, line
        with pytest.raises(socket.timeout):
            beacon.accept()


@pytest.mark.parametrize("command", ["view", "convert"])
def test_scene_opened_through_a_link_says_so(tmp_path, command):
    folder = copy_samples(tmp_path / "real", GLTF_WALL)
    other = tmp_path / "other"
    other.mkdir()
    (other / "wall.gltf").symlink_to(folder / "brick_wall.gltf")
    extra = ["--no-browser"] if command == "view" else ["-o", tmp_path / "out"]
    line = assert_clean_error(run_cli(command, other / "wall.gltf", *extra, timeout=120), 3, "wall.gltf")
    assert "the scene path is a link to" in line and str(folder / "brick_wall.gltf") in line, line


def test_usd_stage_with_an_upper_case_url_layer_is_not_opened(tmp_path):
    """The USD walk refuses before usd-core resolves anything (no layer of that name opened)."""
    path = wall_folder(tmp_path) / "brick_wall.usda"
    edit(path, lambda stage: stage.GetRootLayer().subLayerPaths.append("FILE:///etc/hostname"))
    with pytest.raises(FormatError, match=r"a URL \(file:\)"):
        usd.read(path)
    assert Sdf.Layer.Find("/etc/hostname") is None and Usd.Stage  # nothing composed
