"""The Khronos glTF validator (npm package gltf-validator), installed on first use."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

CACHE = Path(os.environ.get("CSM_TOOLS_CACHE", Path.home() / ".cache" / "csm-assets-tools"))
SCRIPT = Path(__file__).resolve().parent / "tools" / "gltf_validate.js"


def validator_dir() -> Path:
    """A folder whose node_modules holds gltf-validator; pytest.skip when none can be had."""
    folder = CACHE / "gltf-validator"
    if (folder / "node_modules" / "gltf-validator").is_dir():
        return folder
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.skip("node/npm absent: cannot run the Khronos glTF validator")
    folder.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["npm", "install", "--silent", "--no-audit", "--no-fund", "--prefix", str(folder),
                        "gltf-validator@2.0.0-dev.3.10"], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        pytest.skip(f"npm could not install gltf-validator: {r.stderr.strip()[:200]}")
    return folder


def validate(path) -> dict:
    """The validator's report for ``path`` (a dict with ``issues.numErrors`` etc.)."""
    folder = validator_dir()
    env = dict(os.environ, NODE_PATH=str(folder / "node_modules"))
    r = subprocess.run(["node", str(SCRIPT), str(path)], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def errors(report: dict) -> list[str]:
    return [f"{m['code']} {m.get('pointer', '')}: {m['message']}"
            for m in report["issues"]["messages"] if m["severity"] == 0]
