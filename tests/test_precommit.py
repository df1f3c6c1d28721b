"""The pre-commit hook for real: the pre-commit package runs it against a temporary git repository."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"


@pytest.fixture
def repo(tmp_path):
    if shutil.which("git") is None or subprocess.run(["git", "-C", str(ROOT), "rev-parse"],
                                                     capture_output=True).returncode:
        pytest.skip("needs git and the project as a git checkout")
    pytest.importorskip("pre_commit")
    env = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com", GIT_COMMITTER_NAME="t",
               GIT_COMMITTER_EMAIL="t@example.com", PRE_COMMIT_HOME=str(tmp_path / "cache"),
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    r = tmp_path / "assets"
    r.mkdir()
    for name in ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"]:
        shutil.copy(SAMPLES / name, r / name)
    subprocess.run(["git", "init", "-q"], cwd=r, check=True, env=env)
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    subprocess.run(["git", "commit", "-qm", "assets"], cwd=r, check=True, env=env)
    return r, env


def try_repo(repo_dir: Path, env, hook: str):
    return subprocess.run([sys.executable, "-m", "pre_commit", "try-repo", str(ROOT), hook, "--all-files"],
                          cwd=repo_dir, env=env, capture_output=True, text=True, timeout=600)


def run_local(repo_dir: Path, env, hook: str):
    """``pre-commit run HOOK --all-files`` with the manifest's hook as a local system hook
    (:func:`conftest.local_hook_config`): try-repo builds a python hook's environment anew each
    time (about 30 s), so one try-repo of a python hook proves that build."""
    from conftest import local_hook_config

    (repo_dir / ".pre-commit-config.yaml").write_text(local_hook_config(hook))
    subprocess.run(["git", "add", ".pre-commit-config.yaml"], cwd=repo_dir, check=True, env=env)
    return subprocess.run([sys.executable, "-m", "pre_commit", "run", hook, "--all-files"],
                          cwd=repo_dir, env=env, capture_output=True, text=True, timeout=600)


def test_hook_regenerates_stale_outputs_and_fails_when_it_wrote(repo):
    r, env = repo
    first = try_repo(r, env, "csm-assets-system")
    assert first.returncode == 1, first.stdout + first.stderr
    out = r / "brick_wall_gltf_csm"
    assert (out / "brick_wall.gltf").is_file() and (out / "bricks_height_csm.png").is_file()
    assert "add them to the commit" in first.stdout
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    second = try_repo(r, env, "csm-assets-system")
    assert second.returncode == 0, second.stdout + second.stderr  # fresh: nothing written
    check = try_repo(r, env, "csm-assets-check")
    assert check.returncode == 0, check.stdout + check.stderr
    img = np.asarray(Image.open(r / "bricks_height.png")).copy()
    img[5, 5] ^= 3
    Image.fromarray(img).save(r / "bricks_height.png")
    stale = run_local(r, env, "csm-assets-check")
    assert stale.returncode == 1, stale.stdout + stale.stderr  # stale, and check writes nothing
    assert "stale: brick_wall.gltf -> brick_wall_gltf_csm: input bricks_height.png changed" in stale.stdout
    assert try_repo(r, env, "csm-assets-system").returncode == 1  # regenerated
    assert try_repo(r, env, "csm-assets-system").returncode == 0


FILE_HOOKS = ("csm-assets", "csm-assets-system", "csm-assets-check")  # the hooks given the staged scenes


def ran(result) -> bool:
    """pre-commit ran the hook on some file (it did not skip it for want of matching files)."""
    return "no files to check" not in result.stdout


def test_scene_suffixes_match_in_any_letter_case(repo):
    """``Wall.GLTF`` is a scene for every hook, as it is for ``csm-assets check`` (issue 34)."""
    r, env = repo
    subprocess.run(["git", "mv", "brick_wall.gltf", "Wall.GLTF"], cwd=r, check=True, env=env)
    stale = run_local(r, env, "csm-assets-check")
    assert stale.returncode == 1 and "stale: Wall.GLTF -> Wall_gltf_csm" in stale.stdout, stale.stdout
    for hook in ("csm-assets", "csm-assets-system"):
        shutil.rmtree(r / "Wall_gltf_csm", ignore_errors=True)
        wrote = run_local(r, env, hook)
        assert wrote.returncode == 1 and (r / "Wall_gltf_csm" / "Wall.GLTF").is_file(), (hook, wrote.stdout)
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    for hook in FILE_HOOKS:  # the outputs (Wall_gltf_csm/Wall.GLTF among them) are passed too, and skipped
        fresh = run_local(r, env, hook)
        assert fresh.returncode == 0 and ran(fresh), (hook, fresh.stdout)
    assert not (r / "Wall_gltf_csm" / "Wall_gltf_csm").exists()


def test_a_scene_in_a_folder_named_like_an_output_is_converted(repo):
    """Only folders holding a csm-manifest.json are outputs: a real scene in ``props_csm/`` is
    converted by every hook; the outputs beside it, once committed, are skipped."""
    r, env = repo
    (r / "props_csm").mkdir()
    for name in ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"]:
        subprocess.run(["git", "mv", name, f"props_csm/{name}"], cwd=r, check=True, env=env)
    out = r / "props_csm" / "brick_wall_gltf_csm"
    stale = run_local(r, env, "csm-assets-check")
    assert stale.returncode == 1 and "stale: props_csm/brick_wall.gltf" in stale.stdout, stale.stdout
    for hook in ("csm-assets", "csm-assets-system"):
        shutil.rmtree(out, ignore_errors=True)
        wrote = run_local(r, env, hook)
        assert wrote.returncode == 1 and (out / "bricks_height_csm.png").is_file(), (hook, wrote.stdout)
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    for hook in (*FILE_HOOKS, "csm-assets-all"):
        fresh = run_local(r, env, hook)
        assert fresh.returncode == 0 and ran(fresh), (hook, fresh.stdout)
    assert not (out / "brick_wall_gltf_csm").exists()  # the converted scene is never a scene


def test_a_commit_of_a_texture_alone_runs_the_hook_on_its_scenes(repo):
    """Was: pre-commit passed the hooks only scene files, so a commit of a repainted shared
    texture landed with stale outputs. The texture goes to the scenes whose manifests record
    it; a passing hook's output is shown (verbose), so its warnings reach the artist."""
    from conftest import local_hook_config

    r, env = repo
    assert run_local(r, env, "csm-assets-system").returncode == 1  # the first outputs
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    subprocess.run(["git", "commit", "-qm", "outputs", "--no-verify"], cwd=r, check=True, env=env)
    img = np.asarray(Image.open(r / "bricks_height.png")).copy()
    img[5, 5] ^= 3
    Image.fromarray(img).save(r / "bricks_height.png")
    subprocess.run(["git", "add", "bricks_height.png"], cwd=r, check=True, env=env)
    for hook in ("csm-assets-check", "csm-assets-system"):
        (r / ".pre-commit-config.yaml").write_text(local_hook_config(hook))
        subprocess.run(["git", "add", ".pre-commit-config.yaml"], cwd=r, check=True, env=env)  # else: "unstaged"
        staged = subprocess.run([sys.executable, "-m", "pre_commit", "run", hook], cwd=r, env=env,
                                capture_output=True, text=True, timeout=600)  # the staged texture only
        assert staged.returncode == 1 and ran(staged) and "brick_wall" in staged.stdout, (hook, staged.stdout)
    assert "stale: brick_wall.gltf" in staged.stdout or "add them to the commit" in staged.stdout, staged.stdout
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    fresh = subprocess.run([sys.executable, "-m", "pre_commit", "run", "csm-assets-system"], cwd=r, env=env,
                           capture_output=True, text=True, timeout=600)
    assert fresh.returncode == 0 and "1 fresh" in fresh.stdout, fresh.stdout  # shown although it passed


def test_the_guides_setup_block_pins_a_clone_at_a_commit(repo):
    """docs/guides/pre-commit.md's setup block with ``CSM_ASSETS`` set to this checkout writes a
    config naming the clone and its HEAD SHA, and pre-commit clones it at that SHA and runs its
    hook (the ``-system`` variant here, so no environment is built; the install line left out)."""
    r, env = repo
    page = (ROOT / "docs" / "guides" / "pre-commit.md").read_text(encoding="utf-8")
    block = page.split("## Set it up", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    script = "\n".join(ln for ln in block.splitlines() if not ln.startswith(("CSM_ASSETS=", "pip install")))
    subprocess.run(["bash", "-euc", script], cwd=r, env=dict(env, CSM_ASSETS=str(ROOT)), check=True, timeout=60)
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                         check=True).stdout.strip()
    config = (r / ".pre-commit-config.yaml").read_text()
    assert f"- repo: {ROOT}\n  rev: {sha}\n" in config and "  - id: csm-assets " in config, config
    (r / ".pre-commit-config.yaml").write_text(config.replace("id: csm-assets ", "id: csm-assets-system "))
    subprocess.run(["git", "add", ".pre-commit-config.yaml"], cwd=r, check=True, env=env)
    wrote = subprocess.run([sys.executable, "-m", "pre_commit", "run", "--all-files"], cwd=r, env=env,
                           capture_output=True, text=True, timeout=600)
    assert wrote.returncode == 1 and (r / "brick_wall_gltf_csm" / "brick_wall.gltf").is_file(), wrote.stdout


def test_a_commit_that_renames_a_texture_alone_fails_on_the_scenes_that_lose_it(repo):
    """Was: pre-commit passes the files a commit keeps, never a deleted one, and a commit that only
    deletes runs no hook; ``git mv bricks_height.png`` landed while the wall lost its relief
    (``check .`` then: orphaned). Now the hooks always run and take every scene whose manifest
    records a file that is gone."""
    from conftest import local_hook_config

    r, env = repo
    assert run_local(r, env, "csm-assets-system").returncode == 1  # the first outputs
    subprocess.run(["git", "add", "."], cwd=r, check=True, env=env)
    subprocess.run(["git", "commit", "-qm", "outputs", "--no-verify"], cwd=r, check=True, env=env)
    subprocess.run(["git", "mv", "bricks_height.png", "renamed_height.png"], cwd=r, check=True, env=env)
    for hook in ("csm-assets-check", "csm-assets-system"):
        (r / ".pre-commit-config.yaml").write_text(local_hook_config(hook))
        subprocess.run(["git", "add", ".pre-commit-config.yaml"], cwd=r, check=True, env=env)
        run = subprocess.run([sys.executable, "-m", "pre_commit", "run", hook], cwd=r, env=env,
                             capture_output=True, text=True, timeout=600)
        assert run.returncode == 1 and ran(run) and "brick_wall" in run.stdout, (hook, run.stdout)
    subprocess.run(["git", "rm", "-q", "renamed_height.png", "--cached"], cwd=r, check=True, env=env)
    (r / "renamed_height.png").unlink()  # a commit deleting it: no file is passed at all
    out = r / "brick_wall_gltf_csm"  # the hook removed the outputs that lost their relief, kept a record
    assert [p.name for p in out.iterdir()] == ["csm-manifest.json"]  # waiting for the texture (test_precommit_relief)
    subprocess.run(["git", "add", "-A"], cwd=r, check=True, env=env)
    after = subprocess.run([sys.executable, "-m", "pre_commit", "run", "csm-assets-system"], cwd=r, env=env,
                           capture_output=True, text=True, timeout=600)
    assert after.returncode == 0, after.stdout
