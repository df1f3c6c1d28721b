"""The manifest beside converted outputs: what they were made from, to skip fresh work.

``csm-manifest.json`` in an output folder records the tool version, the settings, the
sha256 of every input file the conversion read (the scene, its buffers, material
libraries and textures) and of every output it wrote. Outputs are fresh when all of
that still holds; checking costs one hash per file, no conversion.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from . import __version__

NAME = "csm-manifest.json"


def file_hash(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _key(scene_path: Path, file: Path) -> str:
    return Path(os.path.relpath(Path(file).resolve(), Path(scene_path).resolve().parent)).as_posix()


def build(scene_path, inputs, outputs, settings: dict) -> dict:
    """The manifest of one conversion (outputs as paths inside the output folder)."""
    return {
        "tool": "csm-assets", "version": __version__, "scene": Path(scene_path).name,
        "settings": settings,
        "inputs": {_key(scene_path, f): file_hash(f) for f in dict.fromkeys(map(Path, inputs))},
        "outputs": {Path(f).name: file_hash(f) for f in outputs},
    }


def staleness(scene_path, out_dir, settings: dict) -> str | None:
    """Why the outputs in ``out_dir`` are stale for this scene and settings, or None if fresh."""
    scene_path, out_dir = Path(scene_path), Path(out_dir)
    try:
        m = json.loads((out_dir / NAME).read_text())
    except FileNotFoundError:
        return "never converted (no manifest)"
    except (OSError, ValueError):
        return "manifest unreadable"
    if m.get("version") != __version__:
        return f"made by csm-assets {m.get('version')}, this is {__version__}"
    if m.get("settings") != json.loads(json.dumps(settings)):
        return "settings changed"
    inputs = m.get("inputs", {})
    if _key(scene_path, scene_path) not in inputs:
        return "manifest is for another scene"
    for rel, digest in inputs.items():
        f = scene_path.resolve().parent / rel
        if not f.is_file():
            return f"input {rel} is gone"
        if file_hash(f) != digest:
            return f"input {rel} changed"
    for name, digest in m.get("outputs", {}).items():
        f = out_dir / name
        if not f.is_file():
            return f"output {name} is missing"
        if file_hash(f) != digest:
            return f"output {name} was modified"
    return None
