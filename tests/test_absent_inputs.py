"""A file a scene names that is missing when it is converted (a texture deleted, not yet
painted) is recorded in the manifest's ``absent`` list: when it appears, ``check`` says the
scene is stale (``FILE appeared``), ``hook`` regenerates it (a ``--textures copy`` output
copies it again: self-contained), and a commit of the restored texture alone concerns the
scene. Was: the manifest recorded only the files read, so ``check`` stayed fresh and the
outputs kept the old answer. The repository is test_attack_lean's (textures in
``assets/textures/``, the wall in ``props/``)."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest

from attack import assert_clean_run, run_cli
from conftest import SAMPLES
from test_attack_lean import _named, _repo

MISSING = "assets/textures/bricks_color.png"


def _converted_without_colour(tmp_path, kind, textures):
    """The repository, its scene (relative) and output folder, converted by ``hook`` with the
    colour texture missing (a CSM404), outputs fresh."""
    repo, scene = _repo(tmp_path, kind)
    (repo / MISSING).unlink()
    rel = scene.relative_to(repo)
    assert_clean_run(run_cli("hook", rel, "--textures", textures, cwd=repo), 1)
    assert_clean_run(run_cli("check", rel, "--textures", textures, cwd=repo))
    out = scene.parent / f"wall_{scene.suffix[1:]}_csm"
    return repo, rel, out


@pytest.mark.parametrize("kind", ["gltf", "obj", "usda"])
def test_a_restored_texture_makes_the_scene_stale_and_hook_copies_it(tmp_path, kind):
    repo, rel, out = _converted_without_colour(tmp_path, kind, "copy")
    assert MISSING in json.loads((out / "csm-manifest.json").read_text())["scenes"][rel.name]["absent"]
    shutil.copy(SAMPLES / "bricks_color.png", repo / MISSING)
    r = run_cli("check", rel, "--textures", "copy", cwd=repo)
    assert_clean_run(r, 1)
    assert f"{MISSING} appeared" in r.stdout and str(rel) in r.stdout, r.stdout
    assert_clean_run(run_cli("hook", rel, "--textures", "copy", cwd=repo), 1)
    assert_clean_run(run_cli("check", rel, "--textures", "copy", cwd=repo))
    named = _named(out, kind)
    assert named and all((out / n).resolve().parent == out.resolve() and (out / n).is_file() for n in named), named
    assert json.loads((out / "csm-manifest.json").read_text())["scenes"][rel.name]["absent"] == []


def test_committing_the_restored_texture_alone_runs_the_hook_on_the_scene(tmp_path):
    """pre-commit passes only the texture: ``concerned`` finds the scene through ``absent``."""
    repo, rel, out = _converted_without_colour(tmp_path, "gltf", "reference")
    shutil.copy(SAMPLES / "bricks_color.png", repo / MISSING)
    r = run_cli("hook", MISSING, cwd=repo)
    assert_clean_run(r, 1)
    assert_clean_run(run_cli("check", rel, cwd=repo))
    assert json.loads((out / "csm-manifest.json").read_text())["scenes"][rel.name]["absent"] == []


def test_a_manifest_written_before_absent_was_recorded_stays_fresh(tmp_path):
    repo, rel, out = _converted_without_colour(tmp_path, "obj", "reference")
    path = out / "csm-manifest.json"
    m = json.loads(path.read_text())
    assert m["scenes"][rel.name].pop("absent") == [MISSING]
    path.write_text(json.dumps(m))
    assert_clean_run(run_cli("check", rel, cwd=repo))
    shutil.copy(SAMPLES / "bricks_color.png", repo / MISSING)
    assert_clean_run(run_cli("check", rel, cwd=repo))  # nothing recorded: nothing to tell (as before)


LEVEL = """#usda 1.0
(
    defaultPrim = "Level"
)
def Xform "Level" (
    variants = {
        string look = "a"
    }
    prepend variantSets = "look"
)
{
    variantSet "look" = {
        "a" (
            prepend references = @./wall/brick_wall.usda@
        ) {
        }
        "b" (
            prepend references = @./wall/other.usda@
        ) {
        }
    }
}
"""


def _git_repo(folder):
    """``folder`` as a git repository holding the level's wall (wall/brick_wall.usda and its textures)."""
    if shutil.which("git") is None:
        pytest.skip("needs git")
    subprocess.run(["git", "init", "-q"], cwd=folder, check=True)
    (folder / "wall").mkdir()


def test_a_layer_an_unselected_variant_names_is_recorded_and_its_appearing_makes_the_scene_stale(tmp_path):
    """Was: a reference to no file in a variant not selected was dropped unrecorded, so the file
    appearing left the level fresh. Now it is ``absent``: ``check`` of the level, and of the new layer
    alone (as a commit of it passes it), says ``FILE appeared``; ``hook`` given the layer converts
    the level (a git repository: the level is looked for in it)."""
    _git_repo(tmp_path)
    for name in ("brick_wall.usda", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / "wall")
    (tmp_path / "level.usda").write_text(LEVEL)
    assert_clean_run(run_cli("hook", "level.usda", cwd=tmp_path), 1)
    entry = json.loads((tmp_path / "level_usda_csm" / "csm-manifest.json").read_text())["scenes"]["level.usda"]
    assert entry["absent"] == ["wall/other.usda"]
    assert_clean_run(run_cli("check", "level.usda", cwd=tmp_path))
    shutil.copy(SAMPLES / "brick_wall.usda", tmp_path / "wall" / "other.usda")
    for given in ("level.usda", "wall/other.usda"):
        r = run_cli("check", given, cwd=tmp_path)
        assert_clean_run(r, 1)
        assert "stale: level.usda -> level_usda_csm: wall/other.usda appeared" in r.stdout, (given, r.stdout)
    assert_clean_run(run_cli("hook", "wall/other.usda", cwd=tmp_path), 1)
    assert_clean_run(run_cli("check", "wall/other.usda", cwd=tmp_path))


def test_a_layer_committed_alone_checks_the_scene_composing_it(tmp_path):
    """Was: a USD file another scene composes is no scene, and a texture-like lookup skipped scene
    files, so ``check``/``hook`` given an edited layer alone found nothing (``0 of 0``)."""
    _git_repo(tmp_path)
    for name in ("brick_wall.usda", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, tmp_path / "wall")
    (tmp_path / "level.usda").write_text(LEVEL)
    assert_clean_run(run_cli("hook", "level.usda", cwd=tmp_path), 1)
    with open(tmp_path / "wall" / "brick_wall.usda", "a") as f:
        f.write("# edited\n")
    r = run_cli("check", "brick_wall.usda", cwd=tmp_path / "wall")  # from its folder
    assert_clean_run(r, 1)
    assert "input wall/brick_wall.usda changed" in r.stdout, r.stdout
