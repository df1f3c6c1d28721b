"""One answer for the whole repository: committed outputs whose scene is gone are findings
(``check`` reports them, exit 1; ``hook`` removes them), and a commit of a texture alone
checks the scenes that read it; in a git repository laid out as test_repo_pipeline's, from
the repository's root and from a sub-folder."""

from __future__ import annotations

import json
import shutil

from attack import assert_clean_run, run_cli
from test_repo_pipeline import git, make_repo


def converted_repo(tmp_path):
    repo = make_repo(tmp_path)
    assert_clean_run(run_cli("hook", ".", cwd=repo), 1)
    git(repo, "add", ".")
    git(repo, "commit", "-qm", "outputs")
    assert_clean_run(run_cli("check", ".", cwd=repo))
    return repo


def test_a_renamed_scene_leaves_orphans_check_reports_and_hook_removes(tmp_path):
    """Was: after ``git mv``, the old outputs stayed committed and ``check .`` exited 0."""
    repo = converted_repo(tmp_path)
    git(repo, "mv", "models/wall.gltf", "models/big_wall.gltf")
    for cwd, where in ((repo, "."), (repo / "models", ".")):
        r = run_cli("check", where, cwd=cwd)
        assert_clean_run(r, 1)
        assert "orphaned: " in r.stdout and "wall_gltf_csm (wall.gltf): its scene" in r.stdout, r.stdout
        assert "is gone (renamed, moved or deleted)" in r.stdout
        assert "stale: " in r.stdout and "big_wall.gltf" in r.stdout
    kept = (repo / "models" / "wall_obj_csm" / "csm-manifest.json").read_bytes()
    r = run_cli("hook", ".", cwd=repo)
    assert_clean_run(r, 1)
    assert "removed" in r.stderr and "stage the removal" in r.stderr
    assert not (repo / "models" / "wall_gltf_csm").exists()
    assert (repo / "models" / "big_wall_gltf_csm" / "csm-manifest.json").is_file()
    assert (repo / "models" / "wall_obj_csm" / "csm-manifest.json").read_bytes() == kept  # others untouched
    assert_clean_run(run_cli("check", ".", cwd=repo))
    assert_clean_run(run_cli("hook", ".", cwd=repo))


def test_a_scene_that_loses_its_relief_leaves_orphans(tmp_path):
    """Was: the scene became 'skipped (no relief)' and its stale outputs stayed, exit 0."""
    repo = converted_repo(tmp_path)
    scene = repo / "models" / "wall.gltf"
    doc = json.loads(scene.read_text())
    doc["materials"][0].pop("extensions")  # its displacement texture no longer named
    scene.write_text(json.dumps(doc, indent=1))
    r = run_cli("check", "models/wall.gltf", cwd=repo)  # as pre-commit passes it
    assert_clean_run(r, 1)
    assert "orphaned: " in r.stdout and "no longer has relief" in r.stdout, r.stdout
    assert_clean_run(run_cli("check", ".", cwd=repo), 1)
    out = repo / "models" / "wall_gltf_csm"
    shutil.copytree(out, tmp_path / "before")
    r = run_cli("hook", "models/wall.gltf", cwd=repo)
    assert_clean_run(r, 1)
    assert not out.exists() and "no longer has relief" in r.stderr
    assert_clean_run(run_cli("check", ".", cwd=repo))


def test_check_and_hook_name_every_scene_and_say_it_as_json(tmp_path):
    """Skipped scenes are named (one line each), and --json gives every scene's state, the
    layers that are parts of other scenes and the orphans."""
    repo = converted_repo(tmp_path)
    r = run_cli("check", ".", cwd=repo)
    assert "skipped (no relief): props/ship.gltf" in r.stdout, r.stdout
    git(repo, "mv", "models/wall.gltf", "models/big_wall.gltf")
    r = run_cli("check", ".", "--json", cwd=repo)
    assert r.returncode == 1
    data = json.loads(r.stdout)
    states = {s["scene"]: s["state"] for s in data["scenes"]}
    assert states["models/big_wall.gltf"] == "stale" and states["props/ship.gltf"] == "skipped"
    assert [o["scene"] for o in data["orphans"]] == ["wall.gltf"]
    assert list(data["parts"]) == ["usd/parts/wall.usda"]
    r = run_cli("hook", ".", "--json", cwd=repo)
    assert r.returncode == 1
    data = json.loads(r.stdout)
    assert {x["scene"]: x["status"] for x in data["results"]}["models/big_wall.gltf"] == "converted"
    assert data["orphans"][0]["scene"] == "wall.gltf" and data["orphans"][0]["removed"]


def test_a_texture_alone_brings_the_scenes_that_read_it(tmp_path):
    """Was: pre-commit passed only the texture, the hook found no scene in it and the commit of
    a changed shared texture landed with stale outputs."""
    repo = converted_repo(tmp_path)
    texture = repo / "textures" / "bricks_height.png"
    shutil.copy(repo / "textures" / "cobbles.png", texture)  # repainted
    for cwd, name in ((repo, "textures/bricks_height.png"), (repo / "textures", "bricks_height.png")):
        r = run_cli("check", name, cwd=cwd)
        assert_clean_run(r, 1)
        assert "stale: " in r.stdout and "wall.gltf" in r.stdout, r.stdout
    r = run_cli("hook", "textures/bricks_height.png", cwd=repo)
    assert_clean_run(r, 1)
    assert "wall_gltf_csm" in r.stderr
    assert_clean_run(run_cli("check", "textures/bricks_height.png", cwd=repo))
    assert_clean_run(run_cli("check", ".", cwd=repo))
    r = run_cli("check", "csm-assets.toml", "--bits", "16", cwd=repo)  # the configuration: every scene below it
    assert_clean_run(r, 1)
    assert r.stdout.count("stale: ") >= 3, r.stdout


def test_a_broken_configuration_entry_fails_only_the_scene_it_names(tmp_path):
    """Was: a height texture named in csm-assets.toml and deleted made every command on every
    scene exit 2, blocking unrelated work."""
    repo = converted_repo(tmp_path)
    (repo / "textures" / "crate_disp.png").unlink()
    where = f"{(repo / 'csm-assets.toml').resolve()}:9: "
    for argv in (["check", "."], ["hook", "."], ["convert", ".", "-o", tmp_path / "out"]):
        r = run_cli(*argv, cwd=repo)
        assert r.returncode == 2, (argv, r.stderr)
        errors = [ln for ln in r.stderr.splitlines() if ln.startswith("csm-assets: error:")]
        assert errors == [f"csm-assets: error: {where}scenes.\"models/crate.obj\".depth-map.bricks: no such file "
                          "'textures/crate_disp.png' (paths are relative to csm-assets.toml's folder)"], r.stderr
    assert (tmp_path / "out" / "models" / "wall_gltf" / "wall.gltf").is_file()  # the others converted
    assert_clean_run(run_cli("check", "models/wall.gltf", cwd=repo))  # unrelated work goes on
    assert_clean_run(run_cli("hook", "models/wall.gltf", "models/wall.obj", cwd=repo))


def test_strict_means_the_same_in_check_and_hook(tmp_path):
    """Was: hook . --strict exited 3 where check . --strict exited 0 on the same tree (a scene
    without relief whose height texture is missing: CSM101 is read, not recorded)."""
    repo = converted_repo(tmp_path)
    ship = repo / "props" / "ship.gltf"
    doc = json.loads(ship.read_text())
    doc["images"].append({"uri": "missing_height.png"})
    doc["textures"].append({"source": len(doc["images"]) - 1})
    doc["materials"][0]["extensions"] = {"KHR_materials_displacement": {
        "displacementGeometryTexture": {"index": len(doc["textures"]) - 1}, "displacementGeometryFactor": 0.05}}
    ship.write_text(json.dumps(doc, indent=1))
    for command in ("check", "hook"):
        r = run_cli(command, ".", "--strict", cwd=repo)
        assert r.returncode == 3 and "CSM101" in r.stderr, (command, r.stderr)
        r = run_cli(command, ".", cwd=repo)
        assert r.returncode == 0 and "warning: CSM101 props/ship.gltf" in r.stderr, (command, r.stderr)


def test_each_scene_of_a_shared_folder_keeps_the_version_that_converted_it(tmp_path, monkeypatch):
    """Was: the version sat at the manifest's top level; converting one scene of a shared folder
    with a new version made the others, made by the old one, count as fresh."""
    from csm_assets.convert import manifest
    from csm_assets.convert.pipeline import ConvertOptions, convert
    from conftest import SAMPLES

    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png", "brick_wall.obj",
                 "brick_wall.mtl"):
        shutil.copy(SAMPLES / name, tmp_path / name)
    out, opts = tmp_path / "out", ConvertOptions(bits=8)
    for scene in ("brick_wall.gltf", "brick_wall.obj"):
        convert(tmp_path / scene, out, opts)
    m = json.loads((out / manifest.NAME).read_text())
    for e in m["scenes"].values():  # as a manifest written before entries held their version
        e.pop("version")
    m["version"] = "0.0.9"
    (out / manifest.NAME).write_text(json.dumps(m))
    monkeypatch.setattr(manifest, "__version__", "0.2.0")
    settings = opts.settings(tmp_path)
    before = manifest.staleness(tmp_path / "brick_wall.obj", out, settings, root=tmp_path)
    assert before == "made by csm-assets 0.0.9, this is 0.2.0"
    m = manifest.load(out)
    m["scenes"]["brick_wall.gltf"]["version"] = "0.2.0"  # one scene converted by the new version
    manifest.write(out / manifest.NAME, m, version="0.2.0")
    assert manifest.staleness(tmp_path / "brick_wall.obj", out, settings, root=tmp_path) == \
        "made by csm-assets 0.0.9, this is 0.2.0"


def test_a_configured_depth_nothing_can_be_measured_at_fails_its_scene_alone_in_check_and_hook(tmp_path):
    """Was: ``check`` called the scene "settings changed" (exit 1) where ``hook`` refused the depth
    (exit 2). Both now fail that scene alone (exit 2) with one line naming the file and line."""
    repo = converted_repo(tmp_path)
    config = repo / "csm-assets.toml"
    config.write_text(config.read_text().replace("depth = 0.05", "depth = 1e-12"))
    for command in ("check", "hook"):
        r = run_cli(command, ".", cwd=repo)
        assert r.returncode == 2, (command, r.stdout, r.stderr)
        errors = [ln for ln in r.stderr.splitlines() if "error:" in ln]
        assert len(errors) == 1 and "models/wall.obj" in errors[0], (command, r.stderr)
        assert f"{config}:6" in errors[0] and "nothing can be measured" in errors[0], errors
        assert "stale: " not in r.stdout, r.stdout
    r = run_cli("check", ".", "--json", cwd=repo)
    states = {s["scene"]: s["state"] for s in json.loads(r.stdout)["scenes"]}
    assert states["models/wall.obj"] == "error" and states["models/crate.obj"] == "fresh", states


def test_an_output_folder_renamed_by_hand_is_a_duplicate_check_reports_and_hook_removes(tmp_path):
    """Was: ``models/wall_gltf_csm/`` moved to ``models/wall_copy/`` (its manifest still naming the
    scene) was no finding. Now it is a ``duplicate`` (exit 1, ``--json`` too); ``hook`` given the
    renamed folder's files (as pre-commit passes them) removes it and makes the scene's own outputs."""
    repo = converted_repo(tmp_path)
    git(repo, "mv", "models/wall_gltf_csm", "models/wall_copy")
    for cwd in (repo, repo / "models"):
        r = run_cli("check", ".", cwd=cwd)
        assert_clean_run(r, 1)
        assert "duplicate: " in r.stdout and "wall_copy (wall.gltf): a copy of the outputs of" in r.stdout, r.stdout
        assert "1 duplicate output folder entry" in r.stderr, r.stderr
    data = json.loads(run_cli("check", ".", "--json", cwd=repo).stdout)
    assert [(o["scene"], o["kind"]) for o in data["orphans"]] == [("wall.gltf", "duplicate")]
    given = git(repo, "diff", "--cached", "--name-only", "--diff-filter=AR").stdout.split()  # what pre-commit passes
    assert given and all(g.startswith("models/wall_copy/") for g in given), given
    r = run_cli("hook", *given, cwd=repo)
    assert_clean_run(r, 1)
    assert "removed " in r.stderr and "models/wall_copy" in r.stderr, r.stderr
    assert not (repo / "models" / "wall_copy").exists()
    assert (repo / "models" / "wall_gltf_csm" / "csm-manifest.json").is_file()
    assert_clean_run(run_cli("check", ".", cwd=repo))


def test_a_height_texture_the_configuration_names_renamed_away_fails_its_scene_and_back_is_fresh(tmp_path):
    """A texture ``csm-assets.toml`` names that is renamed away makes that entry broken: the scenes it
    applies to fail (exit 2, one line naming the file and line), the others and the outputs stay;
    renamed back, everything is fresh again (nothing was lost)."""
    repo = converted_repo(tmp_path)
    git(repo, "mv", "textures/cobbles.png", "textures/c2.png")
    for command in ("check", "hook"):
        r = run_cli(command, "--removed-inputs", cwd=repo)
        assert r.returncode == 2, (command, r.stdout, r.stderr)
        errors = [ln for ln in r.stderr.splitlines() if "error:" in ln]
        assert len(errors) == 1 and "csm-assets.toml:5" in errors[0] and "textures/cobbles.png" in errors[0], errors
    assert (repo / "models" / "wall_obj_csm" / "csm-manifest.json").is_file()
    git(repo, "mv", "textures/c2.png", "textures/cobbles.png")
    assert_clean_run(run_cli("hook", "textures/cobbles.png", "--removed-inputs", cwd=repo))
    assert_clean_run(run_cli("check", ".", cwd=repo))


def test_a_waiting_record_is_refreshed_fails_strict_and_goes_when_nothing_is_missing(tmp_path):
    """The record a scene that lost its relief keeps (lost_relief): fresh while its texture is
    missing (``--strict`` fails on its CSM101 in check and hook alike); stale when another input
    changes (the hook writes it again); removed when the scene no longer names the texture."""
    repo = converted_repo(tmp_path)
    out = repo / "models" / "wall_gltf_csm"
    (repo / "textures" / "bricks_height.png").unlink()
    r = run_cli("hook", "--removed-inputs", cwd=repo)
    assert_clean_run(r, 1)
    assert "models/wall.gltf lost its relief" in r.stderr and "waiting for textures/bricks_height.png" in r.stderr
    entry = json.loads((out / "csm-manifest.json").read_text())["scenes"]["wall.gltf"]
    assert entry["outputs"] == {} and entry["absent"] == ["textures/bricks_height.png"]
    assert sorted(p.name for p in out.iterdir()) == ["csm-manifest.json"]
    r = run_cli("check", ".", cwd=repo)
    assert_clean_run(r, 0)
    assert "skipped (no relief): models/wall.gltf (waiting for textures/bricks_height.png)" in r.stdout, r.stdout
    for command in ("check", "hook"):
        r = run_cli(command, "models/wall.gltf", "--strict", cwd=repo)
        assert r.returncode == 3 and "CSM101" in r.stderr, (command, r.stdout, r.stderr)
    shutil.copy(repo / "textures" / "cobbles.png", repo / "models" / "bricks_color.png")  # repainted colour
    r = run_cli("check", "models/wall.gltf", cwd=repo)
    assert_clean_run(r, 1)
    assert "input models/bricks_color.png changed" in r.stdout, r.stdout
    r = run_cli("hook", "models/bricks_color.png", cwd=repo)  # a commit of the colour alone
    assert_clean_run(r, 1)
    assert "its record in models/wall_gltf_csm was updated" in r.stderr, r.stderr
    assert_clean_run(run_cli("check", ".", cwd=repo))
    scene = repo / "models" / "wall.gltf"
    doc = json.loads(scene.read_text())
    doc["materials"][0].pop("extensions")  # the height texture no longer named: nothing to wait for
    doc["images"].pop()
    doc["textures"].pop()
    scene.write_text(json.dumps(doc, indent=1))
    assert_clean_run(run_cli("check", "models/wall.gltf", cwd=repo), 1)
    r = run_cli("hook", "models/wall.gltf", cwd=repo)
    assert_clean_run(r, 1)
    assert "nothing is kept" in r.stderr and not out.exists(), r.stderr
    r = run_cli("check", ".", cwd=repo)
    assert_clean_run(r, 0)
    assert "skipped (no relief): models/wall.gltf\n" in r.stdout, r.stdout
