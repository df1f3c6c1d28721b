"""UDIM height sets on a Dask cluster (``convert --scheduler``): each tile's step map is a task there,
and the outputs are the bytes of a local run; a scheduler that refuses or never answers is one line
(exit 2), never a hang."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from attack import assert_clean_error
from conftest import copy_samples
from csm_assets.cli import main
from test_udim import cut_tiles, udim_stage

OUTPUTS = ("h_csm.1001.png", "h_csm.1002.png", "h_csm.1011.png", "tiles.usda")


def tasks_run(address: str, prefix: str) -> int:
    """How many tasks named ``prefix`` the scheduler at ``address`` has had so far (in any state)."""
    from distributed import Client

    with Client(address) as client:
        return client.run_on_scheduler(
            lambda dask_scheduler: sum(dask_scheduler.task_prefixes[prefix].state_counts.values())
            if prefix in dask_scheduler.task_prefixes else 0)


def convert_twice(dask_cluster, tmp_path: Path, scene: Path, *extra: str) -> tuple[Path, Path]:
    here, there = tmp_path / "here", tmp_path / "there"
    assert main(["convert", str(scene), "-o", str(here), "-q", *extra]) == 0
    before = tasks_run(dask_cluster.scheduler_address, "tile_task")
    assert main(["convert", str(scene), "-o", str(there), "-q", *extra,
                 "--scheduler", dask_cluster.scheduler_address]) == 0
    assert tasks_run(dask_cluster.scheduler_address, "tile_task") - before >= 3  # a task per tile, there
    return here, there


@pytest.mark.parametrize("cones", ["conservative", "quadrant"])
def test_a_usd_udim_set_on_a_cluster_is_the_local_bytes(dask_cluster, tmp_path, cones):
    folder = tmp_path / "in"
    cut_tiles(folder)
    here, there = convert_twice(dask_cluster, tmp_path, udim_stage(folder / "tiles.usda"), "--cones", cones)
    names = sorted(p.name for p in here.iterdir())
    assert names == sorted(p.name for p in there.iterdir())
    assert set(OUTPUTS) <= set(names)
    for name in names:
        if name != "csm-manifest.json":  # it names its own folder
            assert (here / name).read_bytes() == (there / name).read_bytes(), name


def test_a_height_option_naming_a_set_on_a_cluster_is_the_local_bytes(dask_cluster, tmp_path):
    folder = copy_samples(tmp_path / "in", ("brick_wall.usda", "bricks_color.png", "bricks_height.png"))
    cut_tiles(folder / "rock", name="rock")
    here, there = convert_twice(dask_cluster, tmp_path, folder / "brick_wall.usda", "--height",
                                f"bricks={folder / 'rock' / 'rock.<UDIM>.png'}")
    for name in ("rock_csm.1001.png", "rock_csm.1002.png", "rock_csm.1011.png", "brick_wall.usda"):
        assert (here / name).read_bytes() == (there / name).read_bytes(), name


def test_an_unreadable_tile_on_a_cluster_is_the_local_warning(dask_cluster, tmp_path, capsys):
    folder = tmp_path / "in"
    cut_tiles(folder)
    (folder / "h.1002.png").write_bytes(b"\x89PNG\r\n\x1a\n not a png")
    scene = udim_stage(folder / "tiles.usda")
    said = []
    for extra in ([], ["--scheduler", dask_cluster.scheduler_address]):
        assert main(["convert", str(scene), "-o", str(tmp_path / f"out{len(said)}"), *extra]) == 0
        said.append([line for line in capsys.readouterr().err.splitlines() if "CSM102" in line])
    assert said[0] == said[1] and len(said[0]) == 1 and "h.1002.png" in said[0][0], said


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csm_assets", *map(str, args)], capture_output=True, text=True,
                          timeout=240)


def test_a_scheduler_that_refuses_or_never_answers_is_one_line(tmp_path):
    pytest.importorskip("distributed")
    folder = tmp_path / "in"
    cut_tiles(folder)
    scene = udim_stage(folder / "tiles.usda")
    line = assert_clean_error(_cli("convert", scene, "-o", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:1"), 2)
    assert line.startswith("csm-assets: error: --scheduler tcp://127.0.0.1:1: cannot reach the Dask scheduler"), line
    for address in ("nonsense", "host:notaport"):  # the option named, not the scene
        line = assert_clean_error(_cli("convert", scene, "-o", tmp_path / "out", "--scheduler", address), 2)
        assert line == f"csm-assets: error: --scheduler {address}: expected tcp://HOST:PORT", line
    silent = socket.create_server(("127.0.0.1", 0))  # takes connections, says nothing
    taken = []
    threading.Thread(target=lambda: [taken.append(silent.accept()) for _ in range(64)], daemon=True).start()
    address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
    start = time.monotonic()
    line = assert_clean_error(_cli("convert", scene, "-o", tmp_path / "out", "--scheduler", address), 2)
    assert line.startswith(f"csm-assets: error: --scheduler {address}: no Dask scheduler answered"), line
    assert time.monotonic() - start < 200  # bounded (about 35 s): no hang
    assert taken and not (tmp_path / "out").exists()
    silent.close()
