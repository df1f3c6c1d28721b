"""Lean outputs (issue 35): outputs beside a scene name the scene's own textures where they are
(``--textures reference``, the default there) instead of copying them; ``-o`` folders are
self-contained copies by default. Every command downstream (verify, check, hook and its orphan
removal, view, the Khronos validator, real pre-commit) keeps working, and nothing that removes
outputs ever removes a referenced texture."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from attack import assert_clean_run, run_cli
from conftest import SAMPLES, SHARED_DATA, local_hook_config
from csm_assets.formats import gltf_container as gc

SCENES = {"gltf": ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"],
          "glb": ["brick_wall.glb", "bricks_color.png", "bricks_height.png"],
          "obj": ["brick_wall.obj", "brick_wall.mtl", "bricks_color.png", "bricks_height.png", "bricks_normal.png"],
          "usda": ["brick_wall.usda", "bricks_color.png", "bricks_height.png"]}
TEXTURES = ("bricks_color.png", "bricks_height.png", "bricks_normal.png")


def git(repo: Path, *args) -> None:
    if shutil.which("git") is None:
        pytest.skip("needs git")
    env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@example.com", "GIT_COMMITTER_NAME": "t",
           "GIT_COMMITTER_EMAIL": "t@example.com", "GIT_CONFIG_NOSYSTEM": "1", "HOME": str(repo)}
    subprocess.run(["git", *args], cwd=repo, env=env, check=True, capture_output=True)


def external_glb(folder: Path) -> None:
    """The sample GLB with its images as files beside it (uris), as some exporters write them."""
    doc = gc.load(SAMPLES / "brick_wall.glb")
    for image in doc.json["images"]:
        del image["bufferView"], image["mimeType"]
        image["uri"] = f"{image['name']}.png"
    (folder / "brick_wall.glb").write_bytes(gc.glb_bytes(doc))


def repo_with(tmp_path: Path, kind: str) -> Path:
    """A git repository holding one sample scene (and its textures)."""
    repo = tmp_path / f"repo_{kind}"
    repo.mkdir()
    for name in SCENES[kind]:
        if name != "brick_wall.glb":
            shutil.copy(SAMPLES / name, repo / name)
    if kind == "glb":
        external_glb(repo)
    git(repo, "init", "-q")
    return repo


def digests(folder: Path) -> dict[str, str]:
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in folder.iterdir() if f.is_file()}


def size(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def verified(scene: Path) -> None:
    r = run_cli("verify", scene)
    assert r.returncode == 0 and "PASS" in r.stdout, r.stdout + r.stderr


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_beside_outputs_reference_the_scene_textures(tmp_path, kind):
    """hook (outputs beside the scene): no output is a copy of a source texture, the folder is
    smaller than a copying conversion's, the scene names ``../<texture>``, verify passes, check agrees."""
    repo = repo_with(tmp_path, kind)
    scene = next(repo.glob(f"brick_wall.{kind}"))
    assert_clean_run(run_cli("hook", scene.name, cwd=repo), 1)
    out = repo / f"brick_wall_{kind}_csm"
    sources = {hashlib.sha256((repo / n).read_bytes()).hexdigest() for n in TEXTURES if (repo / n).is_file()}
    assert not sources & set(digests(out).values()), sorted(digests(out))
    entry = json.loads((out / "csm-manifest.json").read_text())["scenes"][scene.name]
    assert entry["settings"]["textures"] == "reference"
    assert not set(entry["outputs"]) & set(TEXTURES)
    assert {"bricks_color.png", "bricks_height.png"} <= set(entry["inputs"])
    assert b"../bricks_color.png" in (out / ("brick_wall.mtl" if kind == "obj" else scene.name)).read_bytes()
    verified(out / scene.name)
    assert_clean_run(run_cli("check", ".", cwd=repo))
    copied = tmp_path / "copied"
    assert_clean_run(run_cli("convert", scene, "-o", copied, "--textures", "copy"))
    assert sources <= set(digests(copied).values())
    assert size(out) < size(copied) - (repo / "bricks_color.png").stat().st_size


def test_glb_embedded_images_stay_embedded(tmp_path):
    repo = tmp_path / "repo"
    repo.mkdir()
    shutil.copy(SAMPLES / "brick_wall.glb", repo / "brick_wall.glb")
    git(repo, "init", "-q")
    assert_clean_run(run_cli("hook", "brick_wall.glb", cwd=repo), 1)
    out = repo / "brick_wall_glb_csm"
    assert sorted(f.name for f in out.iterdir()) == ["brick_wall.glb", "csm-manifest.json"]
    doc = gc.load(out / "brick_wall.glb")
    assert all("uri" not in im for im in doc.json["images"])


@pytest.mark.parametrize("kind", ["gltf", "obj", "usda"])
def test_an_o_folder_is_self_contained(tmp_path, kind):
    """convert -o copies (the default there): the folder renders after its sources are gone."""
    repo = repo_with(tmp_path, kind)
    out = tmp_path / "ship"
    assert_clean_run(run_cli("convert", repo / f"brick_wall.{kind}", "-o", out))
    shutil.rmtree(repo)
    assert (out / "bricks_color.png").is_file()
    assert b"../" not in (out / f"brick_wall.{kind}").read_bytes()
    verified(out / f"brick_wall.{kind}")


def test_reference_into_an_o_folder_of_the_project(tmp_path):
    """--textures reference -o: names ../models/... from the output folder; check agrees when given
    the same choice (or the configuration's), and says the settings changed otherwise."""
    repo = repo_with(tmp_path, "gltf")
    models = repo / "models"
    models.mkdir()
    for name in SCENES["gltf"]:
        (repo / name).rename(models / name)
    out = repo / "build" / "wall"
    assert_clean_run(run_cli("convert", models / "brick_wall.gltf", "-o", out, "--textures", "reference"))
    uris = [im["uri"] for im in json.loads((out / "brick_wall.gltf").read_text())["images"]]
    assert uris == ["../../models/bricks_color.png", "../../models/bricks_height.png", "bricks_height_csm.png",
                    "bricks_height_csm_levels.png"]  # the map and its levels: made here, beside the scene
    verified(out / "brick_wall.gltf")
    assert_clean_run(run_cli("check", models / "brick_wall.gltf", "-o", out, "--textures", "reference"))
    r = run_cli("check", models / "brick_wall.gltf", "-o", out)
    assert r.returncode == 1 and "settings changed" in r.stdout, r.stdout
    (repo / "csm-assets.toml").write_text('textures = "reference"\n')
    assert_clean_run(run_cli("check", models / "brick_wall.gltf", "-o", out))


def test_escaped_uris_and_names_outside_the_project_are_copied(tmp_path):
    """A texture in a folder with a space is named by an escaped uri; outside any project (no
    configuration, no repository) an output folder cannot reach its scene's folder, so it copies."""
    repo = repo_with(tmp_path, "gltf")
    (repo / "my textures").mkdir()
    (repo / "bricks_color.png").rename(repo / "my textures" / "bricks color.png")
    doc = json.loads((repo / "brick_wall.gltf").read_text())
    doc["images"][0]["uri"] = "my%20textures/bricks%20color.png"
    (repo / "brick_wall.gltf").write_text(json.dumps(doc))
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=repo), 1)
    out = repo / "brick_wall_gltf_csm"
    assert json.loads((out / "brick_wall.gltf").read_text())["images"][0]["uri"] == \
        "../my%20textures/bricks%20color.png"
    verified(out / "brick_wall.gltf")
    bare = tmp_path / "bare"
    bare.mkdir()
    for name in SCENES["gltf"]:
        shutil.copy(SAMPLES / name, bare / name)
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=bare), 1)
    assert (bare / "brick_wall_gltf_csm" / "bricks_color.png").is_file()


def test_a_texture_in_another_output_folder_is_copied(tmp_path):
    repo = repo_with(tmp_path, "gltf")
    (repo / "other_gltf_csm").mkdir()
    (repo / "other_gltf_csm" / "csm-manifest.json").write_text('{"tool": "csm-assets", "format": 2, "scenes": {}}')
    shutil.copy(repo / "bricks_color.png", repo / "other_gltf_csm" / "shared.png")
    doc = json.loads((repo / "brick_wall.gltf").read_text())
    doc["images"][0]["uri"] = "other_gltf_csm/shared.png"
    (repo / "brick_wall.gltf").write_text(json.dumps(doc))
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=repo), 1)
    uris = [im["uri"] for im in json.loads((repo / "brick_wall_gltf_csm" / "brick_wall.gltf").read_text())["images"]]
    assert uris[:2] == ["shared.png", "../bricks_height.png"]


def test_a_changed_texture_is_stale_and_orphan_removal_never_removes_one(tmp_path):
    """A referenced texture is an input: changed, the scene is stale and hook regenerates it;
    renaming or moving the scene (the old outputs are orphans) and removing its relief remove
    outputs, never the textures the outputs named."""
    repo = repo_with(tmp_path, "obj")
    git(repo, "add", ".")
    git(repo, "commit", "-qm", "assets")
    assert_clean_run(run_cli("hook", "brick_wall.obj", cwd=repo), 1)
    (repo / "bricks_normal.png").write_bytes((SAMPLES / "cobbles.png").read_bytes())
    r = run_cli("check", ".", cwd=repo)
    assert r.returncode == 1 and "bricks_normal.png changed" in r.stdout, r.stdout
    assert_clean_run(run_cli("hook", "bricks_normal.png", cwd=repo), 1)  # the texture brings its scene
    assert_clean_run(run_cli("check", ".", cwd=repo))
    kept = digests(repo)
    git(repo, "mv", "brick_wall.obj", "boulder.obj")
    r = run_cli("hook", ".", cwd=repo)  # what pre-commit's hook over the repository does
    assert r.returncode == 1 and "removed" in r.stderr, r.stderr
    assert not (repo / "brick_wall_obj_csm").exists()
    assert {k: v for k, v in digests(repo).items() if k != "boulder.obj"} == \
        {k: v for k, v in kept.items() if k != "brick_wall.obj"}
    text = (repo / "brick_wall.mtl").read_text()  # no relief any more: its outputs go, its textures stay
    (repo / "brick_wall.mtl").write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith(("disp",
                                                                                                          "map_Bump"))))
    r = run_cli("hook", ".", cwd=repo)
    assert "removed" in r.stderr and not (repo / "boulder_obj_csm" / "boulder.obj").exists(), r.stderr
    for name in TEXTURES:
        assert (repo / name).read_bytes() == ((SAMPLES / "cobbles.png") if name == "bricks_normal.png"
                                              else SAMPLES / name).read_bytes()


def test_view_serves_the_referenced_textures_and_nothing_else(tmp_path):
    from view_http import request, served

    repo = repo_with(tmp_path, "gltf")
    (repo / "secret.png").write_bytes(b"\x89PNG secret")
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=repo), 1)
    with served(repo / "brick_wall_gltf_csm" / "brick_wall.gltf") as srv:
        port = srv.server_address[1]
        info = json.loads(request(port, "/api/scene.json")[2])
        assert info["url"] == "scene/brick_wall_gltf_csm/brick_wall.gltf" and not info["warnings"], info
        status, _, body = request(port, "/scene/bricks_color.png")  # ../bricks_color.png from the scene
        assert status == 200 and body == (repo / "bricks_color.png").read_bytes()
        assert request(port, "/scene/brick_wall_gltf_csm/bricks_height_csm.png")[0] == 200
        for other in ("/scene/secret.png", "/scene/brick_wall.gltf", "/scene/brick_wall_gltf_csm/csm-manifest.json",
                      "/scene/../secret.png", "/scene/%2e%2e/secret.png"):
            assert request(port, other)[0] == 404, other


def test_lean_gltf_is_clean_for_the_khronos_validator(tmp_path):
    from khronos import errors, validate

    repo = repo_with(tmp_path, "gltf")
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=repo), 1)
    report = validate(repo / "brick_wall_gltf_csm" / "brick_wall.gltf")
    assert errors(report) == [] and report["issues"]["numWarnings"] == 0, report["issues"]


def test_real_pre_commit_stays_green(tmp_path):
    """The hook through real pre-commit: the first commit adds the lean outputs after one git add,
    the next run is green, and a commit changing only a referenced texture is caught."""
    pytest.importorskip("pre_commit")
    repo = repo_with(tmp_path, "gltf")
    env_path = f"{Path(sys.executable).parent}:{shutil.os.environ.get('PATH', '')}"
    (repo / ".pre-commit-config.yaml").write_text(local_hook_config("csm-assets"))

    def pre_commit(*args):
        env = dict(shutil.os.environ, PATH=env_path, PRE_COMMIT_HOME=str(tmp_path / "cache"), HOME=str(repo),
                   GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com", GIT_COMMITTER_NAME="t",
                   GIT_COMMITTER_EMAIL="t@example.com", GIT_CONFIG_NOSYSTEM="1")
        return subprocess.run([sys.executable, "-m", "pre_commit", *args], cwd=repo, env=env, capture_output=True,
                              text=True, timeout=600)

    git(repo, "add", ".")
    first = pre_commit("run", "--all-files")
    assert first.returncode == 1, first.stdout + first.stderr
    git(repo, "add", ".")
    again = pre_commit("run", "--all-files")
    assert again.returncode == 0, again.stdout + again.stderr
    assert not (repo / "brick_wall_gltf_csm" / "bricks_color.png").exists()
    git(repo, "commit", "-qm", "lean outputs")
    (repo / "bricks_color.png").write_bytes((SAMPLES / "cobbles.png").read_bytes())
    git(repo, "add", "bricks_color.png")
    changed = pre_commit("run")
    assert changed.returncode == 1, changed.stdout + changed.stderr
    assert (repo / "bricks_color.png").read_bytes() == (SAMPLES / "cobbles.png").read_bytes()


def test_a_real_third_party_scene_with_textures_in_a_sibling_folder(tmp_path):
    """LearnOpenGL's bricks2 (colour and depth map, CC BY 4.0) in textures/, a scene in models/
    naming them there; the configuration names the depth map: nothing is copied, verify passes."""
    colour, depth = SHARED_DATA / "bricks2.jpg", SHARED_DATA / "bricks2_disp.jpg"
    if not (colour.is_file() and depth.is_file()):
        pytest.skip("needs ../shared/data")
    repo = tmp_path / "assets"
    (repo / "textures").mkdir(parents=True)
    (repo / "models").mkdir()
    shutil.copy(colour, repo / "textures" / "bricks2.jpg")
    shutil.copy(depth, repo / "textures" / "bricks2_disp.jpg")
    doc = json.loads((SAMPLES / "brick_wall.gltf").read_text())
    shutil.copy(SAMPLES / "brick_wall.bin", repo / "models" / "brick_wall.bin")
    doc["images"] = [{"uri": "../textures/bricks2.jpg"}]
    doc["textures"] = [{"source": 0}]
    doc["materials"][0].pop("extensions", None)
    doc["extensionsUsed"] = [e for e in doc.get("extensionsUsed", []) if e != "KHR_materials_displacement"]
    (repo / "models" / "wall.gltf").write_text(json.dumps(doc))
    (repo / "csm-assets.toml").write_text('[scenes."models/wall.gltf"]\n'
                                          f'depth-map = {{ {doc["materials"][0]["name"]} = "textures/bricks2_disp.jpg" }}\n')
    git(repo, "init", "-q")
    assert_clean_run(run_cli("hook", ".", cwd=repo), 1)
    out = repo / "models" / "wall_gltf_csm"
    assert json.loads((out / "wall.gltf").read_text())["images"][0]["uri"] == "../../textures/bricks2.jpg"
    assert not any(f.suffix == ".jpg" for f in out.iterdir())
    verified(out / "wall.gltf")
    assert_clean_run(run_cli("check", "models", cwd=repo))


def test_a_usd_udim_set_in_one_folder_is_referenced_as_one_pattern(tmp_path):
    """A UDIM colour set in textures/: the output names ``../textures/bricks.<UDIM>.png``, no tile is
    copied."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdShade

    repo = repo_with(tmp_path, "usda")
    (repo / "textures").mkdir()
    for tile in (1001, 1002):
        shutil.copy(SAMPLES / "bricks_color.png", repo / "textures" / f"bricks.{tile}.png")
    stage = Usd.Stage.Open(str(repo / "brick_wall.usda"))
    UsdShade.Shader.Get(stage, "/World/Looks/bricks/colorTex").GetInput("file").Set("./textures/bricks.<UDIM>.png")
    stage.GetRootLayer().Save()
    assert_clean_run(run_cli("hook", "brick_wall.usda", cwd=repo), 1)
    out = repo / "brick_wall_usda_csm"
    written = Usd.Stage.Open(str(out / "brick_wall.usda"))
    assert written.GetAttributeAtPath("/World/Looks/bricks/colorTex.inputs:file").Get().path == \
        "../textures/bricks.<UDIM>.png"
    assert not list(out.glob("bricks.*.png"))
    verified(out / "brick_wall.usda")
