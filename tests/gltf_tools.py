"""Real glTF compressors for fixtures, installed on first use from npm like the validator:
gltfpack (meshoptimizer's: quantization, ``-cc`` meshopt compression) and gltf-pipeline
(Cesium's: ``-d`` Draco compression). Tests skip cleanly when a tool cannot be had."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from npm_tools import CACHE, install

VERSIONS = {"gltfpack": "gltfpack@1.3.0", "gltf-pipeline": "gltf-pipeline@4.3.1"}


def tool(name: str) -> Path:
    """The executable of npm package ``name`` (gltfpack or gltf-pipeline)."""
    folder = CACHE / name
    exe = folder / "node_modules" / ".bin" / name
    if not exe.is_file():
        install(VERSIONS[name], folder)
    if not exe.is_file():
        pytest.skip(f"npm installed {VERSIONS[name]} without its {name} executable")
    return exe


def run(name: str, *args) -> None:
    r = subprocess.run([str(tool(name)), *map(str, args)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def gltfpack(src: Path, dst: Path, *flags) -> Path:
    run("gltfpack", *flags, "-i", src, "-o", dst)
    return dst


def draco(src: Path, dst: Path) -> Path:
    """``gltf-pipeline -d``, keeping the textures only an extension it does not know uses."""
    run("gltf-pipeline", "-d", "--keepUnusedElements", "-i", src, "-o", dst)
    return dst
