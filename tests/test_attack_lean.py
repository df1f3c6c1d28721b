"""Lean outputs attacked as an asset repository's user would: a texture the scene names is
deleted, then comes back. The output names it where the scene names it (a CSM404 says it is
missing), never a file of its own folder that nobody writes, so it resolves again once the
texture is restored."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import urllib.parse
from pathlib import Path

import pytest

from attack import assert_clean_run, run_cli
from conftest import SAMPLES


def _repo(tmp_path: Path, kind: str) -> tuple[Path, Path]:
    """A git repository with the brick textures in ``assets/textures/`` and the sample wall in
    ``props/`` naming them there; returns (repository, scene)."""
    repo = tmp_path / "repo"
    tex = repo / "assets" / "textures"
    tex.mkdir(parents=True)
    (repo / "props").mkdir()
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    for name in ("bricks_color.png", "bricks_height.png", "bricks_normal.png"):
        shutil.copy(SAMPLES / name, tex / name)
    if kind == "gltf":
        doc = json.loads((SAMPLES / "brick_wall.gltf").read_text())
        for image in doc["images"]:
            image["uri"] = "../assets/textures/" + image["uri"]
        shutil.copy(SAMPLES / "brick_wall.bin", repo / "props" / "brick_wall.bin")
        scene = repo / "props" / "wall.gltf"
        scene.write_text(json.dumps(doc))
    elif kind in ("usda", "level"):  # the wall alone, or a level in levels/ referencing it
        usd = (SAMPLES / "brick_wall.usda").read_text().replace("@./bricks_", "@../assets/textures/bricks_")
        scene = repo / "props" / "wall.usda"
        scene.write_text(usd)
        if kind == "level":
            (repo / "levels").mkdir()
            scene = repo / "levels" / "wall.usda"  # the output folder's name as for the others
            scene.write_text('#usda 1.0\n(\n    defaultPrim = "Level"\n)\ndef Xform "Level" (\n'
                             '    references = @../props/wall.usda@\n)\n{\n}\n')
    else:
        shutil.copy(SAMPLES / "brick_wall.obj", repo / "props" / "wall.obj")
        mtl = (SAMPLES / "brick_wall.mtl").read_text().replace("bricks_", "../assets/textures/bricks_")
        (repo / "props" / "brick_wall.mtl").write_text(mtl)
        scene = repo / "props" / "wall.obj"
    return repo, scene


def _named(out: Path, kind: str) -> list[str]:
    """The colour texture references of the output in ``out``, as written."""
    if kind in ("usda", "level"):
        usd = (out / "wall.usda").read_text()
        return [p for p in re.findall(r"@([^@]*)@", usd) if "bricks_color" in p]
    if kind == "gltf":
        doc = json.loads((out / "wall.gltf").read_text())
        return [urllib.parse.unquote(i["uri"]) for i in doc["images"] if "bricks_color" in i["uri"]]
    return [line.split()[-1] for line in (out / "brick_wall.mtl").read_text().splitlines()
            if line.startswith("map_Kd")]


@pytest.mark.parametrize("kind", ["gltf", "obj", "usda", "level"])
@pytest.mark.parametrize("textures", ["reference", "copy"])
def test_a_deleted_texture_is_named_where_the_scene_names_it(tmp_path, kind, textures):
    """Was: with bricks_color.png deleted, the glTF output named ``bricks_color.png`` in its own
    folder (written by nobody) and the MTL kept ``../assets/...``, right beside the scene but
    wrong from the output folder, without a warning; after ``git checkout`` of the texture,
    ``check`` said up to date while the outputs still named no file. A USD level flattened
    the missing texture's path to an absolute one (``verify`` refuses it, exit 3), a lone USD
    layer kept the path right only beside the scene."""
    repo, scene = _repo(tmp_path, kind)
    color = repo / "assets" / "textures" / "bricks_color.png"
    color.unlink()
    out = scene.parent / f"wall_{scene.suffix[1:]}_csm"
    warnings = assert_clean_run(run_cli("convert", scene, "-o", out, "--textures", textures))
    assert any("CSM404" in w and "bricks_color" in w for w in warnings), warnings
    named = _named(out, kind)
    assert named and all((out / n).resolve() == color and not Path(n).is_absolute() for n in named), named
    shutil.copy(SAMPLES / "bricks_color.png", color)  # the texture is back: the output's reference resolves
    assert all((out / n).is_file() for n in named)
