"""Batches: layout, freshness from the manifest, parallel and Dask runs, bad files, kills."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from csm_assets.convert import batch, manifest
from csm_assets.cli import main
from csm_assets.convert.pipeline import ConvertOptions, convert

from conftest import GLTF_WALL, OBJ_WALL, SAMPLES, copy_samples

WALL = sorted(set(GLTF_WALL) | set(OBJ_WALL))


def wall_folder(folder: Path) -> Path:
    return copy_samples(folder, WALL)


def test_plan_layouts(tmp_path):
    a = wall_folder(tmp_path / "assets" / "a")
    wall_folder(tmp_path / "assets" / "b" / "deep")
    jobs = batch.plan([tmp_path / "assets"], tmp_path / "out")
    rel = sorted(str(j.out_dir.relative_to(tmp_path / "out")) for j in jobs)
    assert rel == ["a/brick_wall_glb", "a/brick_wall_gltf", "a/brick_wall_obj", "b/deep/brick_wall_glb",
                   "b/deep/brick_wall_gltf", "b/deep/brick_wall_obj"]
    (single,) = batch.plan([a / "brick_wall.gltf"], tmp_path / "out")
    assert single.out_dir == tmp_path / "out"
    beside = batch.plan([a / "brick_wall.obj"])
    assert beside[0].out_dir == a / "brick_wall_obj_csm"


def test_fresh_outputs_are_skipped_and_changes_are_seen(tmp_path):
    src = wall_folder(tmp_path / "in")
    out = tmp_path / "out"
    first = convert(src / "brick_wall.gltf", out)
    assert first.skipped is None and (out / manifest.NAME).is_file()
    m = json.loads((out / manifest.NAME).read_text())["scenes"]["brick_wall.gltf"]
    assert set(m["inputs"]) == {"brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"}
    t = time.perf_counter()
    assert convert(src / "brick_wall.gltf", out).skipped == "outputs are fresh"
    assert time.perf_counter() - t < 0.5
    opts = ConvertOptions()
    assert manifest.staleness(src / "brick_wall.gltf", out, opts.settings()) is None
    assert manifest.staleness(src / "brick_wall.gltf", out, ConvertOptions(bits=16).settings()) == \
        "settings changed"
    img = np.asarray(Image.open(src / "bricks_height.png")).copy()
    img[0, 0] ^= 1
    Image.fromarray(img).save(src / "bricks_height.png")
    assert manifest.staleness(src / "brick_wall.gltf", out, opts.settings()) == \
        "input bricks_height.png changed"
    assert convert(src / "brick_wall.gltf", out).skipped is None
    (out / "bricks_height_csm.png").write_bytes(b"tampered")
    assert manifest.staleness(src / "brick_wall.gltf", out, opts.settings()) == \
        "output bricks_height_csm.png was modified"


def test_batch_goes_on_past_a_bad_file_and_reports_it(tmp_path, capsys):
    src = wall_folder(tmp_path / "in")
    (src / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00\xff\xff\x00\x00")
    (src / "escape.gltf").write_text(json.dumps({"asset": {"version": "2.0"},
                                                 "images": [{"uri": "../../etc/passwd"}]}))
    code = main(["convert", str(src), "-o", str(tmp_path / "out"), "--report", str(tmp_path / "r.json"),
                 "--jobs", "2"])
    assert code == 3
    report = json.loads((tmp_path / "r.json").read_text())
    status = {Path(r["scene"]).name: r["status"] for r in report["results"]}
    assert status == {"broken.glb": "failed", "escape.gltf": "failed", "brick_wall.glb": "converted",
                      "brick_wall.gltf": "converted", "brick_wall.obj": "converted"}
    errors = {Path(r["scene"]).name: r["error"] for r in report["results"] if r["error"]}
    assert "truncated GLB" in errors["broken.glb"] and "refused" in errors["escape.gltf"]
    assert not (tmp_path / "out" / "broken_glb").exists()  # no partial outputs
    assert "3 converted, 0 unchanged, 0 fresh, 2 failed" in report["summary"]
    out = capsys.readouterr().out
    assert "broken.glb" in out and "[5/5]" in out  # plain progress lines off a terminal, on stdout


def test_shared_texture_is_computed_once_across_scenes(tmp_path):
    wall_folder(tmp_path / "in" / "a")
    wall_folder(tmp_path / "in" / "b")
    jobs = [j for j in batch.plan([tmp_path / "in"], tmp_path / "out") if j.scene.suffix == ".gltf"]
    opts = ConvertOptions(cache_dir=tmp_path / "out" / ".csm-cache")
    report = batch.run(jobs, opts, jobs_at_once=1)
    assert report.count("converted") == 2
    (made,) = (tmp_path / "out" / ".csm-cache").glob("*[0-9a-f].png")  # beside it, the bits' reason (.json)
    assert sorted(p.name for p in made.parent.glob("*.png")) == [made.name, f"{made.stem}_levels.png"]  # its levels
    a, b = (j.out_dir / "bricks_height_csm.png" for j in jobs)
    assert a.read_bytes() == b.read_bytes()


def test_check_writes_nothing_and_exits_1_when_stale(tmp_path, capsys):
    src = wall_folder(tmp_path / "in")
    assert main(["check", str(src / "brick_wall.gltf")]) == 1
    assert "never converted" in capsys.readouterr().out
    assert not (src / "brick_wall_gltf_csm").exists()
    assert main(["hook", str(src / "brick_wall.gltf")]) == 1  # wrote outputs
    assert main(["check", str(src / "brick_wall.gltf")]) == 0
    assert main(["hook", str(src / "brick_wall.gltf"), str(src / "brick_wall_gltf_csm" / "brick_wall.gltf")]) == 0


@given(st.data())
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_fuzzed_glb_gives_clear_errors_and_no_partial_outputs(tmp_path, data):
    raw = bytearray((SAMPLES / "brick_wall.glb").read_bytes())
    for _ in range(data.draw(st.integers(1, 8))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(12, len(raw)))
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    (folder / "x.glb").write_bytes(bytes(raw[:cut]))
    result = batch.run_job(batch.Job(folder / "x.glb", folder / "out"), ConvertOptions())
    if result.status == "failed":
        assert "x.glb" in result.error or "out" in result.error
        leftovers = list((folder / "out").iterdir()) if (folder / "out").exists() else []
        assert leftovers == []
    else:
        assert (folder / "out" / manifest.NAME).is_file()


def test_dask_local_cluster_converts_the_samples(tmp_path):
    distributed = pytest.importorskip("distributed")
    wall_folder(tmp_path / "in")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        code = main(["convert", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--scheduler",
                     cluster.scheduler_address, "-q", "--report", str(tmp_path / "r.json")])
    assert code == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert [r["status"] for r in report["results"]] == ["converted"] * 3
    for r in report["results"]:
        assert manifest.staleness(r["scene"], r["out_dir"], ConvertOptions().settings()) is None


def noisy_scenes(folder: Path, n: int, seed: int):
    """n copies of the glTF wall, each with its own 384x384 noise height map."""
    wall_folder(folder)
    rng = np.random.default_rng(seed)
    for i in range(n):
        sub = folder / f"s{i:02d}"
        sub.mkdir(exist_ok=True)
        for name in ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png"]:
            shutil.copy(folder / name, sub / name)
        Image.fromarray(rng.integers(0, 256, (384, 384), dtype=np.uint8)).save(sub / "bricks_height.png")
    for name in WALL:
        (folder / name).unlink()


def _read(path: Path) -> bytes | None:
    """The file's bytes, or None when a rename took it away meanwhile."""
    try:
        return path.read_bytes()
    except FileNotFoundError:
        return None


def snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
            and ".csm-" not in str(p)}


def test_killed_batch_leaves_old_or_new_files_and_a_rerun_finishes(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    noisy_scenes(src, 6, seed=1)
    assert main(["convert", str(src), "-o", str(out), "-q", "--jobs", "1"]) == 0
    old = snapshot(out)
    noisy_scenes(src, 6, seed=2)  # every height map changes
    assert main(["convert", str(src), "-o", str(tmp_path / "want"), "-q", "--jobs", "1"]) == 0
    new = snapshot(tmp_path / "want")
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "convert", str(src), "-o", str(out), "-q",
                             "--jobs", "1"], start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        try:
            done = [m for m in out.rglob(manifest.NAME) if ".csm-stage" not in str(m)
                    and _read(m) == (tmp_path / "want" / m.relative_to(out)).read_bytes()]
        except FileNotFoundError:  # a staging folder vanished while rglob walked it
            continue
        if len(done) >= 2:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    mid = snapshot(out)
    assert set(mid) == set(old)
    changed = 0
    for name, data in mid.items():
        assert data in (old[name], new[name]), f"{name} is neither the old nor the new output"
        changed += data != old[name]
    assert changed > 0
    assert main(["convert", str(src), "-o", str(out), "-q", "--jobs", "1"]) == 0
    assert snapshot(out) == new
    assert not list(out.rglob(".csm-stage-*"))
