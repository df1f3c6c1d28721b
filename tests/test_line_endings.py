"""Freshness does not depend on line endings: a clone with ``core.autocrlf=true`` (what Git for
Windows sets) checks out the text scene files with CRLF, and its ``check`` agrees with the
clone that converted them. Binary files are hashed as they are."""

from __future__ import annotations

import hashlib

import pytest
from attack import assert_clean_run, run_cli
from test_repo_pipeline import git, make_repo

from csm_assets.convert.manifest import content_hash, file_hash


@pytest.mark.parametrize("size", [0, 1, (1 << 20) - 1, 1 << 20, (1 << 20) + 1, 3 << 20])
def test_text_scene_files_hash_the_same_with_either_line_ending(tmp_path, size):
    body = (b"v 0 0 0\nvt 0.5 0.5\n" * (size // 20 + 1))[:size]
    lf, crlf = tmp_path / "lf.obj", tmp_path / "crlf.OBJ"
    lf.write_bytes(body)
    crlf.write_bytes(body.replace(b"\n", b"\r\n"))
    assert file_hash(lf) == file_hash(crlf) == hashlib.sha256(body).hexdigest()
    assert content_hash(crlf.read_bytes(), "x.gltf") == file_hash(lf)


def test_a_crlf_split_between_reads_is_still_one_line_ending(tmp_path):
    body = b"a" * ((1 << 20) - 1) + b"\r\n" + b"b"  # the CR ends the first 1 MiB block
    (tmp_path / "x.usda").write_bytes(body)
    assert file_hash(tmp_path / "x.usda") == hashlib.sha256(body.replace(b"\r\n", b"\n")).hexdigest()
    (tmp_path / "y.usda").write_bytes(body[:1 << 20])  # a lone CR at the very end stays
    assert file_hash(tmp_path / "y.usda") == hashlib.sha256(body[:1 << 20]).hexdigest()


def test_binary_files_are_hashed_as_they_are(tmp_path):
    (tmp_path / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    assert file_hash(tmp_path / "x.png") == hashlib.sha256(b"\x89PNG\r\n\x1a\n").hexdigest()


def test_an_autocrlf_clone_finds_the_committed_outputs_fresh(tmp_path):
    """Was: 'check .' in a core.autocrlf=true clone reported the text scenes stale (their
    inputs hashed as raw bytes), so a mixed Windows/Linux studio regenerated back and forth."""
    repo = make_repo(tmp_path)
    assert_clean_run(run_cli("hook", ".", cwd=repo), 1)
    git(repo, "add", ".")
    git(repo, "commit", "-qm", "outputs")
    clone = tmp_path / "windows"
    git(tmp_path, "-c", "core.autocrlf=true", "clone", "-q", str(repo), str(clone))
    git(clone, "config", "core.autocrlf", "true")
    assert b"\r\n" in (clone / "models" / "wall.gltf").read_bytes()  # checked out as Windows would
    assert b"\r\n" in (clone / "models" / "wall_gltf_csm" / "wall.gltf").read_bytes()
    assert_clean_run(run_cli("check", ".", cwd=clone))
    assert_clean_run(run_cli("hook", ".", cwd=clone))
    assert git(clone, "status", "--porcelain").stdout == ""
