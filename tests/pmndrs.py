"""Real CC0 normal maps and matcaps shipped in the npm package @pmndrs/assets (base64 WebP
modules), fetched on first use into the tools cache (tests/npm_tools.py)."""

from __future__ import annotations

import base64
import io
import re
import tarfile

import numpy as np
import pytest

from npm_tools import CACHE, npm

PACKAGE = "@pmndrs/assets@1.7.0"  # licence CC0-1.0


def package_dir():
    """The unpacked package folder; pytest.skip when npm cannot bring it."""
    folder = CACHE / "pmndrs-assets-1.7.0"
    if (folder / "package" / "normals").is_dir():
        return folder / "package"
    r = npm(PACKAGE, "pack", "--silent", PACKAGE, cwd=folder)
    tgz = folder / r.stdout.strip().splitlines()[-1] if r.stdout.strip() else None
    if tgz is None or not tgz.is_file():
        pytest.skip(f"npm pack gave no package file for {PACKAGE}")
    with tarfile.open(tgz) as tar:
        tar.extractall(folder, filter="data")
    tgz.unlink()
    return folder / "package"


def images(kind: str):
    """(name, float64 (H, W, 3) pixels in [0, 1]) of the package's ``normals`` or ``matcaps``."""
    from PIL import Image

    for js in sorted((package_dir() / kind).glob("*.webp.js")):
        data = base64.b64decode(re.search(r"base64,([A-Za-z0-9+/=]+)", js.read_text()).group(1))
        yield js.name.split(".")[0], np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), np.float64) / 255


def model(name: str, folder) -> "Path":
    """The package's ``models/<name>.glb`` (bunny, suzi, pmndrs: real CC0 GLBs made by glTF-Transform,
    Draco-compressed) written into ``folder``; returns its path."""
    from pathlib import Path

    js = package_dir() / "models" / f"{name}.glb.js"
    data = base64.b64decode(re.search(r"base64,([A-Za-z0-9+/=]+)", js.read_text()).group(1))
    path = Path(folder) / f"{name}.glb"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path
