"""The Khronos glTF validator (npm package gltf-validator), installed on first use."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

from npm_tools import CACHE, install

SCRIPT = Path(__file__).resolve().parent / "tools" / "gltf_validate.js"


def validator_dir() -> Path:
    """A folder whose node_modules holds gltf-validator; pytest.skip when none can be had."""
    folder = CACHE / "gltf-validator"
    if not (folder / "node_modules" / "gltf-validator").is_dir():
        install("gltf-validator@2.0.0-dev.3.10", folder)
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
