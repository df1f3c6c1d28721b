"""convert, check and hook on small git repositories laid out as asset repositories are:
textures in a sibling folder, several scenes with their own height settings in one
csm-assets.toml, scenes without relief, a USD asset whose layer is a file of its own; run
from several working directories with relative, absolute and symlinked paths, and through
real pre-commit (a commit that passes after one ``git add``)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from attack import assert_clean_error, assert_clean_run, run_cli, tree_hashes
from conftest import SAMPLES, SHARED_DATA, local_hook_config

ROOT = Path(__file__).resolve().parents[1]
GIT_ENV = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com", GIT_COMMITTER_NAME="t",
               GIT_COMMITTER_EMAIL="t@example.com", GIT_CONFIG_NOSYSTEM="1")

CONFIG = """\
# every scene below this file
bits = 8

[scenes."models/wall.obj"]          # the OBJ names no height texture: the configuration does
height = { bricks = "textures/cobbles.png" }
depth = 0.05

[scenes."models/crate.obj"]         # a real third-party depth map (white is deep)
depth-map = { bricks = "textures/crate_disp.png" }
depth = { bricks = 0.08 }
bits = 16
"""


def git(repo: Path, *args) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=repo, env=GIT_ENV, capture_output=True, text=True, check=True)


def copy(names, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(SAMPLES / name, folder / name)


def plain_obj(folder: Path, stem: str) -> None:
    """The sample OBJ wall with an MTL that names no height (nor bump) texture."""
    copy(["brick_wall.obj", "bricks_color.png"], folder)
    (folder / "brick_wall.obj").rename(folder / f"{stem}.obj")
    text = (folder / f"{stem}.obj").read_text().replace("brick_wall.mtl", f"{stem}.mtl")
    (folder / f"{stem}.obj").write_text(text)
    mtl = (SAMPLES / "brick_wall.mtl").read_text().splitlines()
    (folder / f"{stem}.mtl").write_text("\n".join(ln for ln in mtl if not ln.startswith(("disp", "map_Bump"))) + "\n")


def make_repo(base: Path, *, config: bool = True, commit: bool = True) -> Path:
    """models/wall.gltf (height in ../textures/), models/wall.obj and models/crate.obj (heights
    from the configuration), props/ship.gltf (no relief), usd/asset.usda composing
    usd/parts/wall.usda; a git repository, everything committed (unless not ``commit``)."""
    if shutil.which("git") is None:
        pytest.skip("needs git")
    repo = base / "assets"
    copy(["brick_wall.gltf", "brick_wall.bin", "bricks_color.png"], repo / "models")
    doc = json.loads((repo / "models" / "brick_wall.gltf").read_text())
    doc["images"][1]["uri"] = "../textures/bricks_height.png"
    doc["buffers"][0]["uri"] = "wall.bin"
    (repo / "models" / "wall.gltf").write_text(json.dumps(doc, indent=1))
    (repo / "models" / "brick_wall.gltf").unlink()
    (repo / "models" / "brick_wall.bin").rename(repo / "models" / "wall.bin")
    copy(["bricks_height.png", "cobbles.png"], repo / "textures")
    disp = SHARED_DATA / "toy_box_disp.png"  # LearnOpenGL's (CC BY 4.0); the sample where it is absent
    shutil.copy(disp if disp.is_file() else SAMPLES / "bricks_height.png", repo / "textures" / "crate_disp.png")
    plain_obj(repo / "models", "wall")
    plain_obj(repo / "models", "crate")
    copy(["brick_wall.gltf", "brick_wall.bin", "bricks_color.png"], repo / "props")
    ship = json.loads((repo / "props" / "brick_wall.gltf").read_text())
    ship["materials"][0].pop("extensions")  # no displacement texture: nothing for CSM
    ship["images"].pop()
    ship["textures"].pop()
    (repo / "props" / "ship.gltf").write_text(json.dumps(ship, indent=1))
    (repo / "props" / "brick_wall.gltf").unlink()
    copy(["brick_wall.usda", "bricks_color.png", "bricks_height.png"], repo / "usd" / "parts")
    (repo / "usd" / "parts" / "brick_wall.usda").rename(repo / "usd" / "parts" / "wall.usda")
    (repo / "usd" / "asset.usda").write_text('#usda 1.0\n(\n    defaultPrim = "Asset"\n    upAxis = "Y"\n)\n\n'
                                             'def Xform "Asset" (\n    prepend references = @./parts/wall.usda@\n'
                                             ')\n{\n}\n')
    if config:
        (repo / "csm-assets.toml").write_text(CONFIG)
    git(repo, "init", "-q")
    if commit:
        git(repo, "add", ".")
        git(repo, "commit", "-qm", "assets")
    return repo


@pytest.fixture
def repo(tmp_path):
    return make_repo(tmp_path)


def manifest(out: Path) -> dict:
    return json.loads((out / "csm-manifest.json").read_text())["scenes"]


def statuses(r) -> dict[str, str]:
    return {Path(x["scene"]).name: x["status"] for x in json.loads(r.stdout)["results"]}


# ---- textures in a sibling folder ------------------------------------------------------------

def test_a_texture_in_a_sibling_folder_is_an_ordinary_input(tmp_path):
    """Was: check exit 1 forever ("manifest names an input outside the scene's folder"),
    convert "converted" on every rerun, hook asking for the same files every time."""
    repo = make_repo(tmp_path, config=False)  # the repository's root is the project root
    scene, out = repo / "models" / "wall.gltf", tmp_path / "out"
    assert statuses(run_cli("convert", scene, "-o", out, "--json")) == {"wall.gltf": "converted"}
    entry = manifest(out)["wall.gltf"]
    assert set(entry["inputs"]) == {"models/wall.gltf", "models/wall.bin", "models/bricks_color.png",
                                    "textures/bricks_height.png"}
    assert (out / entry["root"]).resolve() == repo.resolve()
    assert statuses(run_cli("convert", scene, "-o", out, "--json")) == {"wall.gltf": "fresh"}
    assert_clean_run(run_cli("check", scene, "-o", out))
    first = run_cli("hook", "models/wall.gltf", cwd=repo)
    assert_clean_run(first, 1)
    assert (repo / "models" / "wall_gltf_csm" / "bricks_height_csm.png").is_file()
    assert_clean_run(run_cli("hook", "models/wall.gltf", cwd=repo))  # fresh: nothing asked
    assert_clean_run(run_cli("check", "wall.gltf", cwd=repo / "models"))
    from csm_assets.convert import batch

    (job,) = batch.plan([scene])
    assert batch.fresh_result(job).status == "fresh"  # answered in the calling process, no worker
    (repo / "textures" / "bricks_height.png").write_bytes((SAMPLES / "cobbles.png").read_bytes())
    assert batch.fresh_result(job) is None
    r = run_cli("check", scene)
    assert r.returncode == 1 and "input textures/bricks_height.png changed" in r.stdout, r


def test_outside_the_project_root_the_error_names_the_option_and_the_key(tmp_path):
    repo = make_repo(tmp_path)  # the configuration's folder is the root: ../textures from a nested one is outside
    (repo / "models" / "csm-assets.toml").write_text("bits = 8\n")
    r = run_cli("convert", repo / "models" / "wall.gltf", "-o", tmp_path / "out")
    line = assert_clean_error(r, 3, "wall.gltf")
    assert "outside the scene's folder, its project root" in line and "--allow-outside-paths" in line
    assert "allow-outside-paths = true" in line and not (tmp_path / "out").exists()
    (repo / "models" / "csm-assets.toml").write_text("bits = 8\nallow-outside-paths = true\n")
    assert_clean_run(run_cli("convert", repo / "models" / "wall.gltf", "-o", tmp_path / "out"))
    assert_clean_run(run_cli("check", repo / "models" / "wall.gltf", "-o", tmp_path / "out"))
    assert "../textures/bricks_height.png" in manifest(tmp_path / "out")["wall.gltf"]["inputs"]
    # a texture the configuration names itself may live anywhere: recorded from the root, fresh
    (repo / "models" / "csm-assets.toml").write_text('height = { bricks = "../textures/cobbles.png" }\n')
    assert_clean_run(run_cli("hook", "wall.obj", cwd=repo / "models"), 1)
    assert manifest(repo / "models" / "wall_obj_csm")["wall.obj"]["settings"]["heights"] == \
        {"bricks": "../textures/cobbles.png"}
    assert_clean_run(run_cli("hook", "models/wall.obj", cwd=repo))
    assert_clean_run(run_cli("check", repo / "models" / "wall.obj", cwd=tmp_path))


# ---- freshness never depends on the working directory or the spelling -------------------------

def test_paths_relative_absolute_or_symlinked_from_any_folder_give_one_manifest(repo, tmp_path):
    out = tmp_path / "out"
    link = tmp_path / "link"
    link.symlink_to(repo, target_is_directory=True)
    first = run_cli("convert", "models/wall.obj", "-o", out, "--height", "bricks=textures/bricks_height.png",
                    "--json", cwd=repo)
    assert statuses(first) == {"wall.obj": "converted"}, first
    before = tree_hashes(out)
    entry = manifest(out)["wall.obj"]
    assert entry["settings"]["heights"] == {"bricks": "textures/bricks_height.png"}
    assert "textures/bricks_height.png" in entry["inputs"]
    spellings = [  # (cwd, scene, height)
        (repo / "models", "wall.obj", "../textures/bricks_height.png"),
        (tmp_path, repo / "models" / "wall.obj", repo / "textures" / "bricks_height.png"),
        (tmp_path, "link/models/wall.obj", "link/textures/bricks_height.png"),
        (link / "textures", "../models/../models/wall.obj", "bricks_height.png"),
    ]
    for cwd, scene, height in spellings:
        r = run_cli("convert", scene, "-o", out, "--height", f"bricks={height}", "--json", cwd=cwd)
        assert statuses(r) == {"wall.obj": "fresh"}, (cwd, scene, height, r)
        r = run_cli("check", scene, "-o", out, "--height", f"bricks={height}", cwd=cwd)
        assert_clean_run(r)
    assert tree_hashes(out) == before  # not one byte rewritten


# ---- one configuration, several scenes, every command agrees ----------------------------------

def test_the_configuration_gives_each_scene_its_heights_and_all_commands_agree(repo, tmp_path):
    r = run_cli("hook", "models/wall.gltf", "models/wall.obj", "models/crate.obj", cwd=repo)
    assert_clean_run(r, 1)
    beside = {s: manifest(repo / "models" / f"{s.replace('.', '_')}_csm")[s] for s in
              ("wall.gltf", "wall.obj", "crate.obj")}
    assert beside["wall.obj"]["settings"]["heights"] == {"bricks": "textures/cobbles.png"}
    assert beside["wall.obj"]["settings"]["depth"] == 0.05 and beside["wall.obj"]["picks"]["bricks"]["bits"] == 8
    assert beside["crate.obj"]["settings"]["heights"] == {"bricks": "textures/crate_disp.png (depth map)"}
    assert beside["crate.obj"]["settings"]["depths"] == {"bricks": 0.08}
    assert beside["crate.obj"]["picks"]["bricks"]["bits"] == 16
    assert beside["wall.gltf"]["settings"]["heights"] == {}
    for cwd, path in ((repo, "models"), (repo / "models", "."), (tmp_path, repo / "models")):
        r = run_cli("check", path, cwd=cwd)
        assert_clean_run(r)
        assert "3 of 3 scene(s) up to date" in r.stderr, r
    r = run_cli("check", ".", cwd=repo)  # asset.usda was not converted; the ship needs nothing
    assert_clean_run(r, 1)
    assert "3 of 5 scene(s) up to date, 1 skipped (no relief)" in r.stderr, r
    assert r.stdout.splitlines() == ["stale: usd/asset.usda -> usd/asset_usda_csm: never converted (no manifest)",
                                     "skipped (no relief): props/ship.gltf"], r.stdout  # each named
    out = tmp_path / "out"  # convert with no flag: the same settings per scene as the hook had
    r = run_cli("convert", "models", "-o", out, "--json", cwd=repo)
    assert statuses(r) == {"wall.gltf": "converted", "wall.obj": "converted", "crate.obj": "converted"}, r
    for s, e in beside.items():  # but the textures: referenced beside the scene, copied into -o (lean outputs)
        assert e["settings"].pop("textures") == "reference"
        assert manifest(out / f"{s.replace('.', '_')}")[s]["settings"] == e["settings"], s
    r = run_cli("check", "models/wall.obj", "--bits", "16", cwd=repo)  # a flag given wins over the file
    assert r.returncode == 1 and "settings changed" in r.stdout


# ---- only what a scene requires -------------------------------------------------------------

def test_a_scene_without_relief_writes_nothing(repo, tmp_path):
    before = tree_hashes(repo / "props")
    r = run_cli("hook", "props/ship.gltf", cwd=repo)
    assert_clean_run(r)  # nothing written: nothing to add, exit 0
    assert "1 skipped (no relief)" in r.stdout
    r = run_cli("convert", "props", "-o", tmp_path / "out", cwd=repo)
    assert_clean_run(r)
    assert "skipped (no relief) props/ship.gltf" in r.stdout
    r = run_cli("check", "props", cwd=repo)
    assert_clean_run(r)
    assert "0 of 1 scene(s) up to date, 1 skipped (no relief)" in r.stderr
    assert tree_hashes(repo / "props") == before and not (tmp_path / "out").exists()
    r = run_cli("convert", "props/ship.gltf", "-o", tmp_path / "one", "--json", cwd=repo)  # named: as before
    assert statuses(r) == {"ship.gltf": "unchanged"} and (tmp_path / "one" / "ship.gltf").is_file()


def test_a_usd_layer_another_scene_composes_is_not_a_scene(repo, tmp_path):
    r = run_cli("convert", "usd", "-o", tmp_path / "out", "--json", cwd=repo)
    assert statuses(r) == {"asset.usda": "converted"}, r
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["asset_usda"]
    r = run_cli("hook", "usd/asset.usda", "usd/parts/wall.usda", cwd=repo)  # as pre-commit passes them
    assert_clean_run(r, 1)
    assert (repo / "usd" / "asset_usda_csm").is_dir() and not (repo / "usd" / "parts" / "wall_usda_csm").exists()
    assert_clean_run(run_cli("check", "usd/asset.usda", "usd/parts/wall.usda", cwd=repo))
    assert_clean_run(run_cli("check", "usd", cwd=repo))


def test_a_usd_layer_is_part_of_its_scene_in_any_run(repo, tmp_path):
    """pre-commit splits a long file list between processes: the layer may come alone. It is
    still part of the scene composing it, from any folder (was: 'stale: ... never converted')."""
    assert_clean_run(run_cli("hook", "usd/asset.usda", cwd=repo), 1)
    for cwd, layer in ((repo, "usd/parts/wall.usda"), (repo / "usd" / "parts", "wall.usda")):
        assert_clean_run(run_cli("check", layer, cwd=cwd))
        assert_clean_run(run_cli("hook", layer, cwd=cwd))
        assert not (repo / "usd" / "parts" / "wall_usda_csm").exists()
    r = run_cli("convert", "usd/parts/wall.usda", "-o", tmp_path / "out", cwd=repo)  # convert: the same answer
    assert r.returncode == 2 and "usd/parts/wall.usda is a layer of" in r.stderr and "asset.usda" in r.stderr, r


# ---- real pre-commit -------------------------------------------------------------------------

def test_a_commit_passes_after_one_git_add(tmp_path):
    """Real pre-commit as a git hook (the system hook of .pre-commit-hooks.yaml, the installed
    csm-assets on PATH): the first commit writes the outputs and fails, ``git add`` them,
    the second passes; nothing for the ship without relief nor for the USD layer."""
    pytest.importorskip("pre_commit")
    repo = make_repo(tmp_path, commit=False)
    bin_dir = Path(sys.executable).parent
    if not (bin_dir / "csm-assets").is_file():
        pytest.skip("csm-assets is not installed beside this python")
    env = dict(GIT_ENV, PRE_COMMIT_HOME=str(tmp_path / "cache"), PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    (repo / ".pre-commit-config.yaml").write_text(local_hook_config("csm-assets-system"))
    subprocess.run([sys.executable, "-m", "pre_commit", "install"], cwd=repo, env=env, check=True,
                   capture_output=True)
    subprocess.run(["git", "add", "."], cwd=repo, env=env, check=True)  # every scene is in the first commit

    def commit():
        return subprocess.run(["git", "commit", "-qm", "csm"], cwd=repo, env=env, capture_output=True, text=True,
                              timeout=600)

    first = commit()
    assert first.returncode == 1, first.stdout + first.stderr
    assert "add them to the commit" in first.stdout + first.stderr
    written = sorted(p.relative_to(repo).as_posix() for p in repo.rglob("*_csm") if p.is_dir())
    assert written == ["models/crate_obj_csm", "models/wall_gltf_csm", "models/wall_obj_csm", "usd/asset_usda_csm"]
    subprocess.run(["git", "add", "."], cwd=repo, env=env, check=True)
    second = commit()
    assert second.returncode == 0, second.stdout + second.stderr
    assert git(repo, "status", "--porcelain").stdout == ""
    assert_clean_run(run_cli("check", repo, cwd=tmp_path))
