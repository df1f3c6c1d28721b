"""Relaxed cones through convert, verify, bench trade and the --max-error pick."""

from __future__ import annotations

import json

import numpy as np
import pytest

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, copy_samples, random_field
from csm_assets.bench.trade import RELAXED_CONFIGS, trade_heights
from csm_assets.cli import main
from csm_assets.convert.pipeline import convert
from csm_assets.errors import OptionError
from csm_assets.formats import gltf_container as gc
from csm_assets.formats import read_step_map_meta
from csm_assets.verify.scene import verify_scene


def ext_of(out):
    doc = gc.load(out / "brick_wall.gltf")
    return doc.json["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]


@pytest.fixture
def wall(tmp_path):
    return copy_samples(tmp_path / "in", GLTF_WALL) / "brick_wall.gltf"


def test_library_convert_relaxed_cones_writes_relaxed_map_and_variant(wall, tmp_path):
    out = tmp_path / "out"
    report = convert(wall, out, cones="relaxed", variant="relaxed", depth=0.05)
    (path,) = report.step_maps.values()
    assert read_step_map_meta(path)["cones"] == "relaxed"
    ext = ext_of(out)
    assert ext["variant"] == "relaxed" and ext["steps"] == 2  # the relaxed variant's default search steps
    rep = verify_scene(out / "brick_wall.gltf", size=48, views=((90.0, 0.0), (20.0, 290.0)))
    assert rep.primitives and all(v.variant == "relaxed" for p in rep.primitives for v in p.variants)
    assert rep.passed  # max_error 1 texel


def test_library_refuses_another_variant_for_relaxed_cones(wall, tmp_path):
    with pytest.raises(OptionError, match="relaxed variant"):
        convert(wall, tmp_path / "out", cones="relaxed")  # the default variant, exact, would pass through walls
    with pytest.raises(OptionError, match="cones"):
        convert(wall, tmp_path / "out", cones="loose")
    assert not (tmp_path / "out" / "brick_wall.gltf").exists()


def test_cli_convert_cones_relaxed(wall, tmp_path):
    assert_clean_run(run_cli("convert", wall, "-o", tmp_path / "a", "--cones", "relaxed", "-q"))
    assert ext_of(tmp_path / "a")["variant"] == "relaxed"
    manifest = json.loads((tmp_path / "a" / "csm-manifest.json").read_text())["scenes"]["brick_wall.gltf"]
    assert manifest["settings"]["cones"] == "relaxed"
    assert_clean_run(run_cli("verify", tmp_path / "a" / "brick_wall.gltf", "--size", "32", "--views", "60"))
    assert_clean_error(run_cli("convert", wall, "-o", tmp_path / "b", "--cones", "relaxed", "--variant", "exact"),
                       2)
    assert_clean_error(run_cli("convert", wall, "-o", tmp_path / "c", "--cones", "loose"), 2)


def test_cli_convert_max_error_with_relaxed_cones_picks_relaxed(wall, tmp_path):
    assert main(["convert", str(wall), "-o", str(tmp_path / "a"), "--cones", "relaxed", "--max-error", "1",
                 "--depth", "0.05", "-q"]) == 0
    ext = ext_of(tmp_path / "a")
    assert ext["variant"] == "relaxed" and ("relaxed", ext["steps"]) in RELAXED_CONFIGS


def test_trade_on_relaxed_cones_measures_the_relaxed_variant_only():
    h = random_field(24, 7)
    rep = trade_heights(h, cones="relaxed", views=((60.0, 0.0),), size=24, draws=1)
    assert [(r.variant, r.steps) for r in rep.rows] == list(RELAXED_CONFIGS)
    assert {r.cones for r in rep.rows} == {"relaxed"} and rep.rows[0].label.endswith("relaxed cones")
    with pytest.raises(ValueError, match="relaxed variant"):
        trade_heights(h, cones="relaxed", configs=[("exact", 0)], views=((60.0, 0.0),), size=24, draws=1)


def test_bench_trade_adds_rows_on_the_relaxed_cones(tmp_path, capsys):
    from PIL import Image

    path = tmp_path / "h.png"
    Image.fromarray(np.round(random_field(24, 8) * 255).astype(np.uint8)).save(path)
    assert main(["bench", "trade", str(path), "--views", "60", "--size", "16", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    relaxed = [(r["variant"], r["steps"]) for r in rows if r["cones"] == "relaxed"]
    assert relaxed == list(RELAXED_CONFIGS)
    assert ("relaxed", 1) in [(r["variant"], r["steps"]) for r in rows if r["cones"] == "conservative"]
    # a step map of relaxed cones: only the relaxed variant
    assert main(["stepmap", str(path), "-o", str(tmp_path / "r.png"), "--cones", "relaxed"]) == 0
    capsys.readouterr()
    assert main(["bench", "trade", str(tmp_path / "r.png"), "--views", "60", "--size", "16", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert {(r["variant"], r["cones"]) for r in rows} == {("relaxed", "relaxed")}
