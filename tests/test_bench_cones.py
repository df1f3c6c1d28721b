"""The cone benchmark runs end to end on tiny maps and reports data."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from csm_assets.bench import maps as bench_maps
from csm_assets.bench.cones import PEER_SOURCE, bench_cones, brute_texels
from csm_assets.cli import main
from csm_assets.heightfield import unit_heights
from reference import brute_cone_ratios


def test_procedural_maps_are_uint8_squares():
    for kind in bench_maps.PROCEDURAL:
        m = bench_maps.make_map(kind, 40, {})
        assert m.dtype == np.uint8 and m.shape == (40, 40)
    sea = bench_maps.terrain(64)
    assert 0.3 < np.mean(sea == 0) < 0.5  # a flat sea at 0
    with pytest.raises(ValueError, match="unknown map"):
        bench_maps.make_map("lava", 8, {})


def test_brute_texels_matches_reference():
    h = unit_heights(bench_maps.terrain(24, seed=9))
    rows, cols = np.array([0, 5, 23]), np.array([3, 23, 0])
    for tile in (False, True):
        want = brute_cone_ratios(h, tile, tile, 1.0)[rows, cols]
        np.testing.assert_allclose(brute_texels(h, rows, cols, tile, tile, 1.0), want, rtol=1e-14)


def test_bench_without_peer(tmp_path):
    report = bench_cones([48], maps=["terrain", "noise"], peer=False, data=tmp_path)
    assert [r.map for r in report.runs] == ["terrain", "noise"]
    assert all(r.exact and r.ours_s > 0 and r.ours_tiled_s > 0 for r in report.runs)
    assert all(r.peer_s is None and r.speedup is None for r in report.runs)
    assert "skipped" in report.peer
    json.dumps(report.to_dict())
    assert "terrain" in report.table()


def test_missing_peer_is_skipped_with_a_reason(tmp_path):
    report = bench_cones([16], maps=["tiles"], peer_source=tmp_path / "none.cpp", data=tmp_path)
    assert "not found" in report.peer and report.runs[0].peer_s is None


@pytest.mark.skipif(shutil.which("g++") is None or not PEER_SOURCE.is_file(),
                    reason="needs g++ and ../shared/anchors/dummer_preproc.cpp")
def test_bench_with_peer(tmp_path):
    report = bench_cones([32], maps=["tiles"], repeat=1, data=tmp_path)
    run = report.runs[0]
    assert run.exact and run.peer_s is not None and run.peer_s >= 0  # its clock prints ms
    assert run.peer_wider == 0.0  # untiled, the paper's search is exact up to its rounding


def test_cli_bench_json(capsys, tmp_path):
    assert main(["bench", "cones", "--sizes", "24", "--maps", "noise", "--no-peer", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["runs"][0]["map"] == "noise" and out["runs"][0]["exact"] is True


def test_cli_bench_rejects_unknown_map(capsys):
    assert main(["bench", "cones", "--sizes", "24", "--maps", "lava", "--no-peer"]) == 2
    assert "unknown map" in capsys.readouterr().err
