"""Attacks on the levels images a converted scene names (glTF stepMapLevelsTexture and
stepMap2LevelsTexture, USD inputs stepMapLevels and stepMap2Levels, MTL csm_map_levels and
csm_map2_levels): a FIFO, a link to /dev/zero, a folder, a truncated PNG, the wrong size, channel
count or type, a header claiming 100000x100000 (and one claiming 16000x16000, which the image
library would open: refused from the header, nothing decoded), a missing file. ``verify``: exit 3
with one line naming the image and what was expected. ``view``: it starts, and one warning line
names the image and what was expected (the page draws that step map's level 0 alone). The FIFO
cases run as subprocesses with timeouts far above their second."""

from __future__ import annotations

import io
import os
import select
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from attack import assert_clean_error, run_cli, run_cli_here

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
FORMATS = ("gltf", "obj", "usda")
IMAGES = {"first": "bricks_height_csm_levels.png", "second": "bricks_height_csm_q_levels.png"}
EXPECTED = "expected 127x64 RGBA uint8 (levels 1..n of its 128x128 step map side by side)"
# kind -> what the one error line says besides the file's name (None: EXPECTED alone)
KINDS = {"fifo": "is a FIFO, not a file", "devzero": "outside the scene's folder", "folder": "is a folder, not a file",
         "truncated": "truncated or corrupt image", "missing": None, "absurd": "100000x100000",
         "big header": "is 16000x16000, 4 channel(s) uint8", "size": "is 127x32, 4 channel(s) uint8",
         "rgb": "is 127x64, 3 channel(s) uint8", "grey": "is 127x64, 1 channel(s) uint8",
         "16-bit": "is 127x64, 4 channel(s) uint16"}


def png_header(width: int, height: int) -> bytes:
    """A PNG whose header declares an RGBA ``width`` x ``height`` image and whose data is 100 bytes."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 100)) + chunk(b"IEND", b""))


def attack(kind: str, file: Path) -> None:
    """Replace the levels image ``file`` by what ``kind`` names."""
    good = file.read_bytes()
    file.unlink()
    pixels = np.asarray(Image.open(io.BytesIO(good)))
    made = {"size": pixels[:32], "rgb": pixels[..., :3], "grey": pixels[..., 0],
            "16-bit": pixels.astype(np.uint16) * 257}
    if kind == "fifo":
        os.mkfifo(file)
    elif kind == "devzero":
        file.symlink_to("/dev/zero")
    elif kind == "folder":
        file.mkdir()
    elif kind == "truncated":
        file.write_bytes(good[:len(good) // 2])
    elif kind in ("absurd", "big header"):
        file.write_bytes(png_header(*(100000, 100000) if kind == "absurd" else (16000, 16000)))
    elif kind == "16-bit":  # RGBA, 16 bits a channel: OpenImageIO writes what PIL cannot
        import OpenImageIO as oiio

        out = oiio.ImageOutput.create(str(file))
        out.open(str(file), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 4, "uint16"))
        out.write_image(np.ascontiguousarray(made[kind]))
        out.close()
    elif kind in made:
        Image.fromarray(np.ascontiguousarray(made[kind])).save(file)
    else:
        assert kind == "missing"


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """{format: the folder of the sample wall converted with quadrant cones (two images, two chains)}."""
    base = tmp_path_factory.mktemp("levels")
    for name in ("brick_wall.gltf", "brick_wall.bin", "brick_wall.obj", "brick_wall.mtl", "brick_wall.usda",
                 "bricks_color.png", "bricks_height.png", "bricks_normal.png"):
        shutil.copy(SAMPLES / name, base / name)
    out = {}
    for fmt in FORMATS:
        r = run_cli("convert", base / f"brick_wall.{fmt}", "-o", base / fmt, "-q", "--cones", "quadrant", timeout=600)
        assert r.returncode == 0, r.stderr
        assert all((base / fmt / image).is_file() for image in IMAGES.values()), sorted((base / fmt).iterdir())
        out[fmt] = base / fmt
    return out


def attacked(converted, tmp_path, fmt: str, which: str, kind: str) -> tuple[Path, Path]:
    """(the scene, its attacked levels image) in a copy of the converted ``fmt`` folder."""
    if fmt == "usda":
        pytest.importorskip("pxr", reason="USD (usd-core) is not installed")
    folder = tmp_path / fmt
    shutil.copytree(converted[fmt], folder)
    attack(kind, folder / IMAGES[which])
    return folder / f"brick_wall.{fmt}", folder / IMAGES[which]


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("which", list(IMAGES))
@pytest.mark.parametrize("fmt", FORMATS)
def test_verify_refuses_a_bad_levels_image_in_one_line(converted, tmp_path, fmt, which, kind):
    """Was: the USD stepMapLevels or stepMap2Levels a FIFO blocked verify for ever (killed after 60 s),
    a folder was 'cannot open the step map' naming the scene; a glTF's or MTL's was refused by the
    image reader without saying it was a levels image or what it should be."""
    scene, image = attacked(converted, tmp_path, fmt, which, kind)
    args = ("verify", scene, "--views", "45/30", "--no-cameras")
    slow = kind in ("fifo", "devzero")  # what could block or never end: a real process, a timeout
    r = run_cli(*args, timeout=120) if slow else run_cli_here(*args)
    error = assert_clean_error(r, 3, image.name)
    if kind == "devzero":  # the reader refuses a link out of the project before anything opens it
        assert KINDS[kind] in error, error
        return
    if kind == "missing" and fmt == "usda":
        assert f"'./{image.name}' does not resolve" in error, error
        return
    if kind in ("fifo", "folder") and fmt == "usda":  # refused by the USD reader, before verify's check
        key = "stepMapLevels" if which == "first" else "stepMap2Levels"
        assert KINDS[kind] in error and f"the CSM shader's {key}" in error and "expected an image file" in error, error
        return
    assert EXPECTED in error and (KINDS[kind] or "no such file") in error, error


def test_view_warns_of_each_bad_levels_image_and_serves(converted, tmp_path):
    """view (glTF) of every attack: the load path warns in one line naming the image and what was
    expected (CSM505), or CSM502 for what is no file (was 'is missing' for a FIFO and a folder);
    a size, channel count, type or truncation the terminal said nothing of (the page drew level 0
    alone, its reason in the browser's console only)."""
    from csm_assets.view import load_scene
    from csm_assets.warning_codes import line

    for which in IMAGES:
        for kind in KINDS:
            scene, image = attacked(converted, tmp_path / which / kind.replace(" ", "_"), "gltf", which, kind)
            if kind == "devzero":
                with pytest.raises(Exception, match="outside the scene's folder"):
                    load_scene(scene)
                continue
            lines = [line(w) for w in load_scene(scene).warnings]
            named = [text for text in lines if image.name in text]
            assert len(named) == 1, (which, kind, lines)
            if kind in ("fifo", "folder", "missing"):
                assert "CSM502" in named[0] and (KINDS[kind] or "is missing") in named[0], named[0]
            else:
                assert "CSM505" in named[0] and EXPECTED in named[0] and KINDS[kind] in named[0], named[0]
                assert named[0].rstrip().endswith("the page draws that step map's level 0 alone"), named[0]


def test_view_of_a_scene_whose_levels_image_is_a_fifo_starts_at_once(converted, tmp_path):
    """The real command: it prints its warning and its URL within seconds (the FIFO is never opened)."""
    scene, image = attacked(converted, tmp_path, "gltf", "first", "fifo")
    p = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(scene), "--no-browser"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([p.stdout], [], [], 120)  # far above its second: a hang fails here
        first = p.stdout.readline() if ready else ""
    finally:
        p.terminate()
        _, err = p.communicate(timeout=120)
    assert "viewing brick_wall.gltf at http://127.0.0.1:" in first, (first, err)
    assert f"{image.name} is a FIFO, not a file" in err and "Traceback" not in err, err
