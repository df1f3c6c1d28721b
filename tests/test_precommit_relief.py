"""A height texture renamed or deleted and brought back, through real ``git commit`` with pre-commit
installed (the ``csm-assets-system`` hook of .pre-commit-hooks.yaml as a local system hook): the scenes
that lost their relief keep a waiting record, and the texture's return regenerates their outputs."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
SCENES = ("a", "b")


def git(cwd: Path, env, *args, check=True) -> subprocess.CompletedProcess:
    """``git ARGS`` in ``cwd``; ``stdout`` holds stderr too (where ``git commit`` shows the hook's output)."""
    return subprocess.run(["git", *args], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, check=check, timeout=600)


def cli(cwd: Path, env, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csm_assets", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture
def repo(tmp_path):
    """models/a.gltf and models/b.gltf naming ../textures/bricks_height.png, pre-commit installed,
    their outputs committed."""
    from conftest import local_hook_config

    if shutil.which("git") is None:
        pytest.skip("needs git")
    pytest.importorskip("pre_commit")
    env = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com", GIT_COMMITTER_NAME="t",
               GIT_COMMITTER_EMAIL="t@example.com", GIT_CONFIG_NOSYSTEM="1", PRE_COMMIT_HOME=str(tmp_path / "cache"),
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    r = tmp_path / "assets"
    (r / "models").mkdir(parents=True)
    (r / "textures").mkdir()
    doc = json.loads((SAMPLES / "brick_wall.gltf").read_text())
    for image in doc["images"]:
        image["uri"] = "../textures/" + image["uri"]
    for name in SCENES:
        (r / "models" / f"{name}.gltf").write_text(json.dumps(doc, indent=1))
    shutil.copy(SAMPLES / "brick_wall.bin", r / "models")
    for name in ("bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, r / "textures")
    (r / ".pre-commit-config.yaml").write_text(local_hook_config("csm-assets-system"))
    git(r, env, "init", "-q")
    subprocess.run([sys.executable, "-m", "pre_commit", "install"], cwd=r, env=env, check=True, capture_output=True)
    git(r, env, "add", ".")
    assert git(r, env, "commit", "-qm", "assets", check=False).returncode == 1  # the hook wrote the outputs
    git(r, env, "add", "-A")
    git(r, env, "commit", "-qm", "assets")
    return r, env


def committed(r: Path, env, name: str) -> list[str]:
    return git(r, env, "ls-files", "--", f"models/{name}_gltf_csm").stdout.split()


@pytest.mark.parametrize("how, where", [("rename", "."), ("delete", "models")])  # from the root, from a sub-folder
def test_a_height_texture_away_and_back_regenerates_the_outputs(repo, how, where):
    """Was: the hook removed the manifests with the outputs that lost their relief, so nothing tied
    the texture to its scenes: bringing it back was a texture-only commit that landed with no
    outputs, and ``check .`` said "never converted". Now the manifests stay as records waiting for
    it, and its return fails the commit until the regenerated outputs are staged."""
    r, env = repo
    cwd = r / where
    texture = os.path.relpath(r / "textures" / "bricks_height.png", cwd)
    away = os.path.relpath(r / "textures" / "h.png", cwd)
    git(cwd, env, *(("mv", texture, away) if how == "rename" else ("rm", "-q", texture)))
    lost = git(cwd, env, "commit", "-qm", "away", check=False)
    assert lost.returncode == 1, lost.stdout
    assert "lost its relief" in lost.stdout and "waiting for textures/bricks_height.png" in lost.stdout, lost.stdout
    for name in SCENES:
        out = r / "models" / f"{name}_gltf_csm"
        assert sorted(p.name for p in out.iterdir()) == ["csm-manifest.json"]
        entry = json.loads((out / "csm-manifest.json").read_text())["scenes"][f"{name}.gltf"]
        assert entry["outputs"] == {} and entry["absent"] == ["textures/bricks_height.png"]
    git(cwd, env, "add", "-A")
    landed = git(cwd, env, "commit", "-qm", "away", check=False)
    assert landed.returncode == 0, landed.stdout
    assert committed(r, env, "a") == ["models/a_gltf_csm/csm-manifest.json"]
    waiting = cli(cwd, env, "check", ".")
    assert waiting.returncode == 0, waiting.stdout + waiting.stderr
    assert "skipped (no relief): " in waiting.stdout and "(waiting for textures/bricks_height.png)" in waiting.stdout
    assert "CSM101" in waiting.stderr  # the lost relief is still said

    if how == "rename":
        git(cwd, env, "mv", away, texture)
    else:
        git(cwd, env, "checkout", "HEAD~1", "--", texture)
    stale = cli(cwd, env, "check", ".")
    assert stale.returncode == 1 and "textures/bricks_height.png appeared" in stale.stdout, stale.stdout
    back = git(cwd, env, "commit", "-qm", "back", check=False)  # the texture alone is committed
    assert back.returncode == 1 and "wrote " in back.stdout, back.stdout
    assert cli(cwd, env, "check", ".").returncode == 0
    git(cwd, env, "add", "-A")
    done = git(cwd, env, "commit", "-qm", "back", check=False)
    assert done.returncode == 0, done.stdout
    for name in SCENES:
        assert f"models/{name}_gltf_csm/bricks_height_csm.png" in committed(r, env, name)
    assert git(r, env, "status", "--porcelain").stdout == ""
    final = cli(cwd, env, "check", ".")
    assert final.returncode == 0 and "skipped" not in final.stdout, final.stdout + final.stderr
