"""Verification: _exact within a texel of the exact tracer at every view; the report and CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import random_field, skip_without_gl

from csm_assets import Heightfield, save_heightfield, step_map, write_step_map
from csm_assets.cli import main
from csm_assets.render.renderer import VARIANTS
from csm_assets.verify.maps import DEFAULT_VIEWS, format_report, verify_file, verify_step_map

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SIZE = 64


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()




def assert_exact_within_a_texel(report):
    (exact,) = report.variants
    assert len(exact.views) == len(DEFAULT_VIEWS)
    for v in exact.views:
        assert v.pixels > 300, v
        assert v.p95_error <= 1.0, v
        assert v.nonconverged_share == 0.0, v
    assert report.passed


@pytest.mark.parametrize("n, seed, tile, bits, smooth", [
    (64, 1, True, 8, 1.5), (96, 2, False, 8, 1.5), ((48, 96), 5, True, 8, 1.5), ((96, 40), 6, False, 8, 1.5), (64, 3, True, 16, 0.75), (128, 4, True, 32, 3.0),
    pytest.param(64, 3, True, 16, 0.0, marks=pytest.mark.xfail(strict=True, reason=(
        "white noise with the paper's settings: cones exact at texel centres are too wide for the "
        "bilinear surface between them, and a one-texel minimum step skips sub-texel features at "
        "grazing views: p95 2.4 texels at 35 degrees, 9 at 10"))),
])
def test_exact_matches_the_reference_on_random_fields(n, seed, tile, bits, smooth):
    sm = step_map(random_field(n, seed, smooth), tile=tile, bits=bits)
    assert_exact_within_a_texel(verify_step_map(sm, tile=tile, size=SIZE))


@pytest.mark.parametrize("n, seed, tile, bits", [(64, 3, True, 8), ((48, 64), 7, False, 16), (64, 8, True, 32)])
def test_bilinear_safe_maps_with_a_quarter_texel_step_hold_on_white_noise(n, seed, tile, bits):
    """The optional safety pass (G = 3x3 minimum) and min_step 0.25 bring white noise, the
    hardest case, within budget at every view down to 10 degrees."""
    sm = step_map(random_field(n, seed, smooth=0), tile=tile, bits=bits, bilinear_safe=True)
    report = verify_step_map(sm, tile=tile, size=SIZE, min_step=0.25)
    assert_exact_within_a_texel(report)
    assert report.variants[0].worst_p95 < 0.5


@pytest.mark.parametrize("name", ["bricks2_disp.jpg", "toy_box_disp.png"])
def test_exact_matches_the_reference_on_the_real_maps(name):
    path = SHARED_DATA / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    report = verify_file(path, invert=True, size=SIZE, as_step_map=False)  # toy_box_disp.png is RGBA
    assert_exact_within_a_texel(report)


def test_fewer_steps_and_peers_do_worse_and_fail_a_tight_budget():
    sm = step_map(random_field(64, 5), bits=8)
    rep = verify_step_map(sm, variants=("exact", "loop", "parallax"), steps=4, size=SIZE, max_error=1.0)
    worst = {v.variant: v.worst_p95 for v in rep.variants}
    assert worst["exact"] <= 1.0 < worst["parallax"]
    assert worst["loop"] > worst["exact"]
    assert not rep.passed
    loop = rep.variants[1]
    assert all(v.mean_iterations == 4 and v.max_iterations == 4 for v in loop.views)
    assert any(v.nonconverged_share > 0 for v in loop.views)


def test_report_is_data_and_json_ready():
    sm = step_map(random_field(32, 6), bits=8)
    rep = verify_step_map(sm, variants=("parallax",), views=((30.0, 10.0),), size=32)
    d = rep.to_dict()
    text = json.dumps(d, allow_nan=False)
    back = json.loads(text)
    assert back["variants"][0]["variant"] == "parallax" and back["shape"] == [32, 32]
    assert back["passed"] == rep.passed
    assert "parallax" in format_report(rep)


def test_bad_arguments_are_refused():
    sm = step_map(random_field(16, 7), bits=8)
    with pytest.raises(ValueError, match="unknown variant"):
        verify_step_map(sm, variants=("steep",))
    with pytest.raises(ValueError, match="depth"):
        verify_step_map(sm, depth=0.0)
    with pytest.raises(ValueError, match=r"\(H, W, 4\)"):
        verify_step_map(sm[..., :3])


# --- the command line -------------------------------------------------------------------------

@pytest.fixture
def height_png(tmp_path):
    path = tmp_path / "h.png"
    save_heightfield(Heightfield(random_field(48, 8)), path)
    return path


def test_cli_verify_passes_exact_and_prints_json(height_png, capsys):
    assert main(["verify", str(height_png), "--size", "48", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["passed"] and [v["variant"] for v in d["variants"]] == ["exact"]
    assert all(v["p95_error"] <= 1.0 for v in d["variants"][0]["views"])


def test_cli_verify_exits_1_over_budget_and_writes_images(height_png, tmp_path, capsys):
    out = tmp_path / "pics"
    code = main(["verify", str(height_png), "--variant", "parallax", "--size", "32", "--max-error", "0.5",
                 "--images", str(out)])
    assert code == 1
    assert "FAIL" in capsys.readouterr().out
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 5 * len(DEFAULT_VIEWS) + 1 and "contact_sheet.png" in names  # as scenes have
    assert "parallax_el90_az0_error.png" in names and "parallax_el10_az45_iterations.png" in names
    from PIL import Image

    assert Image.open(out / "parallax_el90_az0_error.png").size == (32, 32)


def test_cli_verify_reads_settings_from_a_step_map(tmp_path, capsys):
    path = tmp_path / "s.png"
    sm = step_map(random_field(32, 9), tile=False, max_ratio=0.5, bits=16)
    write_step_map(sm, path, {"max_ratio": 0.5, "tile": [False, False], "bits": 16})
    assert main(["verify", str(path), "--size", "32", "--json", "--steps", "4", "--variant", "all"]) in (0, 1)
    d = json.loads(capsys.readouterr().out)
    assert d["dtype"] == "uint16" and d["tile"] == [False, False] and d["max_ratio"] == 0.5
    assert len(d["variants"]) == len(VARIANTS) - 1  # --variant all: every variant of a conservative map
    assert d["variants"][0]["worst_p95"] <= 1.0  # exact


def test_cli_verify_bad_input_and_usage(tmp_path, capsys):
    assert main(["verify", str(tmp_path / "missing.png")]) == 3
    assert "missing.png" in capsys.readouterr().err
    assert main(["verify", "x.png", "--variant", "steep"]) == 2
    assert main(["verify", "x.png", "--steps", "0"]) == 2
    assert main(["verify", "x.png", "--max-iterations", "-1"]) == 2


def test_cli_verify_reports_the_cap(height_png, capsys):
    assert main(["verify", str(height_png), "--size", "32", "--json", "--max-iterations", "1",
                 "--depth", "0.5"]) in (0, 1)
    views = json.loads(capsys.readouterr().out)["variants"][0]["views"]
    assert max(v["max_iterations"] for v in views) == 1
    assert any(v["nonconverged_share"] > 0 for v in views)


def test_verify_reads_raw_altitude_formats(tmp_path):
    """A Rayshade .hf of raw altitudes is normalized before its step map is made."""
    raw = random_field(48, 5, smooth=1.5) * 300.0 - 120.0
    save_heightfield(Heightfield(raw), tmp_path / "terrain.hf")
    report = verify_file(tmp_path / "terrain.hf", size=64)
    assert_exact_within_a_texel(report)


def test_cli_verify_white_noise_passes_with_the_default_safety_pass(tmp_path, capsys):
    noise = (random_field(48, 11, smooth=0) * 255).astype(np.uint8)
    from PIL import Image

    Image.fromarray(noise).save(tmp_path / "noise.png")
    assert main(["verify", str(tmp_path / "noise.png"), "--size", "48", "--json"]) == 0
    capsys.readouterr()
    assert main(["verify", str(tmp_path / "noise.png"), "--size", "48", "--no-bilinear-safe",
                 "--json"]) == 1  # the paper's settings miss thin features at grazing views
    capsys.readouterr()
    assert main(["stepmap", str(tmp_path / "noise.png"), "-o", str(tmp_path / "safe.png"),
                 "--bilinear-safe"]) == 0
    assert main(["verify", str(tmp_path / "safe.png"), "--size", "48", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["variants"][0]["views"][-1]["p95_error"] < 1
