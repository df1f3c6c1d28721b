"""Real CC0 normal maps and matcaps shipped in the npm package @pmndrs/assets (base64 WebP
modules), installed on first use into the tools cache, as tests/khronos.py does."""

from __future__ import annotations

import base64
import io
import re
import shutil
import subprocess
import tarfile

import numpy as np
import pytest

from khronos import CACHE

PACKAGE = "@pmndrs/assets@1.7.0"  # licence CC0-1.0


def package_dir():
    """The unpacked package folder; pytest.skip when npm cannot bring it."""
    folder = CACHE / "pmndrs-assets-1.7.0"
    if (folder / "package" / "normals").is_dir():
        return folder / "package"
    if shutil.which("npm") is None:
        pytest.skip("npm absent: cannot fetch @pmndrs/assets")
    folder.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["npm", "pack", "--silent", PACKAGE], capture_output=True, text=True, timeout=300,
                       cwd=folder)
    tgz = folder / r.stdout.strip().splitlines()[-1] if r.returncode == 0 and r.stdout.strip() else None
    if tgz is None or not tgz.is_file():
        pytest.skip(f"npm could not fetch {PACKAGE}: {r.stderr.strip()[:200]}")
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
