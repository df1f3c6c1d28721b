"""npm packages the tests use (the Khronos validator, gltfpack, gltf-pipeline, @pmndrs/assets),
fetched on first use into one cache folder. A package npm cannot bring is tried once per test
session: its tests then skip at once instead of each waiting for npm again."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

CACHE = Path(os.environ.get("CSM_TOOLS_CACHE", Path.home() / ".cache" / "csm-assets-tools"))
_failed: dict[str, str] = {}  # package -> why npm could not bring it


def npm(package: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run ``npm <args>`` in ``cwd`` (created) to bring ``package``; pytest.skip when node or
    npm is absent or npm fails (remembered for the session)."""
    if package in _failed:
        pytest.skip(_failed[package])
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.skip(f"node/npm absent: cannot bring {package}")
    cwd.mkdir(parents=True, exist_ok=True)
    try:
        r = subprocess.run(["npm", *args], capture_output=True, text=True, timeout=300, cwd=cwd)
        why = None if r.returncode == 0 else r.stderr.strip()[:200]
    except subprocess.TimeoutExpired:
        why = "npm took over 300 s"
    if why is not None:
        _failed[package] = f"npm could not bring {package}: {why}"
        pytest.skip(_failed[package])
    return r


def install(package: str, folder: Path) -> None:
    """``npm install package`` into ``folder``'s node_modules."""
    # run from the cache's parent: npm takes a bare name that matches a folder for that folder
    npm(package, "install", "--silent", "--no-audit", "--no-fund", "--prefix", str(folder), package,
        cwd=CACHE.parent)
