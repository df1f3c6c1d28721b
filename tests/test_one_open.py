"""Each input file is opened once (issue 14): verify reads a height map or a step map with one
open (no second look for step map settings, no Pillow peek), and convert --max-error works on
the step map in memory instead of reading back what it wrote."""

from __future__ import annotations

import numpy as np
import PIL.Image
import pytest
from conftest import random_field, skip_without_gl

import csm_assets.formats.image as image_module
from csm_assets import StepMapSettings, make_step_map, save_step_map


@pytest.fixture
def opens(monkeypatch):
    """Counts the image reads (read_pixels, read_description) and Pillow opens."""
    counted = {"read_pixels": 0, "read_description": 0, "pil": 0}
    for name in ("read_pixels", "read_description"):
        real = getattr(image_module, name)

        def wrapped(*a, _real=real, _name=name, **k):
            counted[_name] += 1
            return _real(*a, **k)

        monkeypatch.setattr(image_module, name, wrapped)
    real_pil = PIL.Image.open

    def pil(*a, **k):
        counted["pil"] += 1
        return real_pil(*a, **k)

    monkeypatch.setattr(PIL.Image, "open", pil)
    return counted


def _height_png(path):
    PIL.Image.fromarray((random_field(32, 3) * 65535).astype(np.uint16)).save(path)
    return path


@pytest.mark.parametrize("kind", ["height map", "step map", "rgba heights"])
def test_load_packed_opens_the_file_once(tmp_path, opens, kind):
    from csm_assets.verify.maps import load_packed

    path = _height_png(tmp_path / "h.png")
    if kind == "step map":
        from csm_assets import load_heightfield

        sm = make_step_map(load_heightfield(path), StepMapSettings(levels="none"))  # a levels image: another file
        path = tmp_path / "s.png"
        save_step_map(sm, path)
    if kind == "rgba heights":  # grey saved as RGBA: certainly heights
        g = np.asarray(PIL.Image.open(path), np.uint16) // 257
        path = tmp_path / "rgba.png"
        PIL.Image.fromarray(np.dstack([g, g, g, np.full_like(g, 255)]).astype(np.uint8)).save(path)
        opens["pil"] = 0
    for k in opens:
        opens[k] = 0
    load_packed(path)
    assert opens == {"read_pixels": 1, "read_description": 0, "pil": 0}


def test_an_rgba_image_without_settings_is_still_refused(tmp_path):
    from csm_assets.errors import FormatError
    from csm_assets.verify.maps import load_packed

    rgba = (np.random.default_rng(1).random((8, 8, 4)) * 255).astype(np.uint8)
    PIL.Image.fromarray(rgba).save(tmp_path / "x.png")
    with pytest.raises(FormatError, match="--step-map"):
        load_packed(tmp_path / "x.png")


def test_convert_max_error_never_reads_its_step_maps_back(tmp_path, monkeypatch):
    skip_without_gl()
    from conftest import GLTF_WALL, copy_samples

    import csm_assets.formats as formats
    from csm_assets.convert.pipeline import convert

    src = copy_samples(tmp_path / "in", GLTF_WALL)
    calls = []
    real = formats.read_step_map
    monkeypatch.setattr(formats, "read_step_map", lambda p: calls.append(p) or real(p))
    report = convert(src / "brick_wall.gltf", tmp_path / "out", max_error=2.0, variant="auto", depth=0.05)
    assert report.picks and calls == []


def test_verify_with_shadows_reads_a_height_map_once(tmp_path, opens, monkeypatch):
    """``verify --shadows`` hands the map it made to the shadow check: one read, one cone pass."""
    skip_without_gl()
    import csm_assets.stepmap as stepmap
    from csm_assets.cli import main

    path = _height_png(tmp_path / "h.png")
    made = []
    real = stepmap.make_step_maps  # every step map is made through it
    monkeypatch.setattr(stepmap, "make_step_maps", lambda *a, **k: made.append(1) or real(*a, **k))
    for k in opens:
        opens[k] = 0
    code = main(["verify", str(path), "--shadows", "--views", "60/30", "--light-elevation", "45",
                 "--light-azimuth", "0", "--size", "32"])
    assert code in (0, 1) and opens["read_pixels"] == 1 and len(made) == 1


def test_verify_with_shadows_reads_a_converted_scene_once(tmp_path, monkeypatch):
    """``verify --shadows`` on a scene draws verify's and the shadows' views from one read."""
    skip_without_gl()
    from conftest import GLTF_WALL, copy_samples

    import csm_assets.verify.scene as verify_scene
    from csm_assets.cli import main
    from csm_assets.convert.pipeline import convert

    src = copy_samples(tmp_path / "in", GLTF_WALL)
    convert(src / "brick_wall.gltf", tmp_path / "out")
    reads = []
    real = verify_scene.read_converted
    monkeypatch.setattr(verify_scene, "read_converted", lambda p: reads.append(p) or real(p))
    code = main(["verify", str(tmp_path / "out" / "brick_wall.gltf"), "--shadows", "--views", "60/30",
                 "--no-cameras", "--light-elevation", "45", "--light-azimuth", "0", "--size", "32"])
    assert code in (0, 1) and len(reads) == 1


def test_bench_trade_reads_a_height_map_once_with_one_conservative_cone_pass(tmp_path, opens, monkeypatch, capsys):
    """``bench trade`` on a height map measures its conservative and its relaxed map from one
    read of the file and one conservative cone pass (the relaxed kernel's floor)."""
    skip_without_gl()
    import json

    import csm_assets.cones.relaxed as cones_relaxed
    import csm_assets.packing as packing
    from csm_assets.cli import main

    path = _height_png(tmp_path / "h.png")
    passes = []
    for module in (packing, cones_relaxed):  # each calls the conservative kernel by its own name
        monkeypatch.setattr(module, "exact_ratios",
                            lambda *a, _real=module.exact_ratios, **k: passes.append(1) or _real(*a, **k))
    for k in opens:
        opens[k] = 0
    assert main(["bench", "trade", str(path), "--views", "60/30", "--size", "8", "--json", "--no-distance"]) == 0
    assert opens == {"read_pixels": 1, "read_description": 0, "pil": 0} and len(passes) == 1
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert {r["cones"] for r in rows if r["variant"] == "relaxed"} == {"conservative", "relaxed"}
    for k in opens:  # the distance columns: the level chain from the same read
        opens[k] = 0
    assert main(["bench", "trade", str(path), "--views", "60/30", "--size", "8", "--json"]) == 0
    assert opens == {"read_pixels": 1, "read_description": 0, "pil": 0}
    assert json.loads(capsys.readouterr().out)["distance"]["views"]
