"""convert --max-error E writes only settings that verify --max-error E then passes on that scene,
with verify's default views and size; 8-bit maps that cannot meet E are made again at 16 bits."""

from __future__ import annotations

import json

import pytest
from attack import assert_clean_run, run_cli
from conftest import skip_without_gl
from curved_scenes import write_gltf, write_obj

import csm_assets.convert.maps as convert_module  # where convert picks (variant, steps)
import csm_assets.convert.pick as pick_scene
from csm_assets.convert.pipeline import convert
from csm_assets.formats import read_step_map


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()


@pytest.mark.slow
@pytest.mark.parametrize("writer, budget", [(write_gltf, 1.0), (write_obj, 0.03)])
def test_budget_picks_pass_verify_on_the_scene(tmp_path, writer, budget):
    src = writer(tmp_path / "src")
    r = run_cli("convert", src, "-o", tmp_path / "out", "--max-error", budget, "--json")
    assert_clean_run(r, 0)
    picks = json.loads(r.stdout)["results"][0]["picks"]
    assert set(picks) == {"stones", "ridges"}
    r = run_cli("verify", tmp_path / "out" / src.name, "--max-error", budget, "--json")
    assert r.returncode == 0, r.stdout[-2000:]
    d = json.loads(r.stdout)
    got = {p["material"]: (p["variants"][0]["variant"], p["variants"][0]["steps"]) for p in d["primitives"]}
    assert got == {m: (p["variant"], p["steps"] if p["variant"] not in ("exact", "parallax") else 0)
                   for m, p in picks.items()}


@pytest.mark.slow
def test_a_pick_the_scene_fails_is_replaced(tmp_path, monkeypatch):
    """The quad's pick is forced to parallax (far off on deep relief): the confirmation on the
    scene itself replaces it with a setting that passes."""
    monkeypatch.setattr(convert_module, "pick", lambda *a, **k: ("parallax", 0, None))
    src = write_gltf(tmp_path / "src")
    report = convert(src, tmp_path / "out", max_error=0.5, variant="auto", depth=0.3)
    assert all(p["variant"] != "parallax" for p in report.picks.values()), report.picks
    from csm_assets.verify.scene import verify_scene

    assert verify_scene(tmp_path / "out" / src.name, max_error=0.5).passed


@pytest.mark.slow
def test_an_8_bit_map_that_cannot_meet_the_budget_is_made_at_16_bits(tmp_path, monkeypatch):
    """No 8-bit setting passes (the 8-bit candidates are forced to parallax): the map is made
    again at 16 bits, the pick found there, and the report says so."""
    real = pick_scene.candidates

    def candidates(path, mat, opts, configs):
        return [("parallax", 0)] if read_step_map(path).dtype.itemsize == 1 else real(path, mat, opts, configs)

    monkeypatch.setattr(pick_scene, "candidates", candidates)
    monkeypatch.setattr(convert_module, "pick", lambda *a, **k: ("parallax", 0, None))
    src = write_obj(tmp_path / "src")
    report = convert(src, tmp_path / "out", max_error=0.5, variant="auto", depth=0.3)
    assert {p["bits"] for p in report.picks.values()} == {16}, report.picks
    (w,) = report.warnings  # one text about two materials: one warning, counted twice
    assert w.code == "CSM303" and "written at 16 bits" in w.text and w.count == 2, report.warnings
    assert set(w.about) == {"material 'stones'", "material 'ridges'"}
    mtl = (tmp_path / "out" / "curved.mtl").read_text()
    maps = [ln.split()[1] for ln in mtl.splitlines() if ln.startswith("csm_map")]
    assert all(read_step_map(tmp_path / "out" / m).dtype.itemsize == 2 for m in maps)
    r = run_cli("verify", tmp_path / "out" / src.name, "--max-error", "0.5", "--views", "90/0", "10/45")
    assert_clean_run(r, 0)
