"""Quadrant cones through convert: both images of each step map written beside the scene (or inside
a GLB / .usdz), carried by the glTF extension (stepMap2Texture), the MTL (csm_map2) and the USD shader
(stepMap2), read back equal to a direct step map; validators clean; the quadrant-variant rules; the
manifest knows the second image; verify draws the quadrant variant; the --max-error pick."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, OBJ_WALL, copy_samples, skip_without_gl
from usd_stages import USD_WALL, validation_errors

from csm_assets.convert import manifest
from csm_assets.convert.pick import QUADRANT_MIN_STEPS
from csm_assets.convert.pipeline import ConvertOptions, convert, scene_module
from csm_assets.errors import FormatError, OptionError
from csm_assets.formats import load_heightfield, read_step_map
from csm_assets.formats.csm_params import GLTF_EXTENSION
from csm_assets.height_source import HeightSpec
from csm_assets.stepmap import StepMapSettings, make_step_map, second_path
from csm_assets.verify.scene import read_converted, verify_scene

SCENES = {"brick_wall.gltf": GLTF_WALL, "brick_wall.glb": GLTF_WALL, "brick_wall.obj": OBJ_WALL,
          "brick_wall.usda": USD_WALL}
QUAD = dict(cones="quadrant", variant="quadrant", depth=0.05)


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()


def _convert(tmp_path, name, folder="out", **options):
    src = copy_samples(tmp_path / "in", SCENES[name])
    report = convert(src / name, tmp_path / folder, **{**QUAD, **options})
    return src / name, tmp_path / folder / name, report


def _direct(src, settings):
    """The quadrant step map made straight from the scene's height texture, as convert reads it."""
    scene = scene_module(src).read(src)
    (h,) = [m.height for m in scene.materials if m.height is not None]
    with h.texture.as_file() as file:
        return make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings)


def _pixels(texture):
    with texture.as_file() as file:
        return read_step_map(file)


@pytest.mark.parametrize("name", list(SCENES))
def test_both_images_round_trip_in_every_format(tmp_path, name):
    src, out, report = _convert(tmp_path, name)
    _, stored, _, _ = read_converted(out)
    (s,) = stored.values()
    assert s.variant == "quadrant" and s.step_map2 is not None and s.min_step == 0.125
    direct = _direct(src, StepMapSettings(cones="quadrant", tile=s.tile, bits=8, source="bricks_height"))
    np.testing.assert_array_equal(_pixels(s.step_map), direct.pixels)
    np.testing.assert_array_equal(_pixels(s.step_map2), direct.second)
    outputs = json.loads((out.parent / manifest.NAME).read_text())["scenes"][name]["outputs"]
    if name.endswith(".glb"):  # both images inside, as bufferViews; nothing beside it
        assert s.step_map.data is not None and s.step_map2.data is not None
        assert sorted(outputs) == [name]
    else:
        first = s.step_map.path
        assert s.step_map2.path == second_path(first) and first.name == "bricks_height_csm.png"
        assert {first.name, s.step_map2.path.name} <= set(outputs)  # the manifest knows the second image
        assert {p.name for p in report.written} >= {first.name, s.step_map2.path.name}
    if name.endswith((".gltf", ".glb")):
        from khronos import errors, validate

        assert errors(validate(out)) == []
        from csm_assets.formats import gltf_container as gc

        ext = gc.load(out).json["materials"][0]["extensions"][GLTF_EXTENSION]
        assert list(ext)[:2] == ["stepMapTexture", "stepMap2Texture"]
        assert ext["stepMap2Texture"]["texCoord"] == ext["stepMapTexture"]["texCoord"]
        assert ext["stepMap2Texture"]["index"] != ext["stepMapTexture"]["index"]
    if name.endswith(".obj"):
        lines = [x.split() for x in (out.parent / "brick_wall.mtl").read_text().splitlines() if x.startswith("csm_")]
        assert lines[:2] == [["csm_map", "bricks_height_csm.png"], ["csm_map2", "bricks_height_csm_q.png"]]
    if name.endswith(".usda"):
        assert validation_errors(out) == []
        assert "asset inputs:stepMap2 = @./bricks_height_csm_q.png@" in out.read_text()


def test_a_usdz_package_holds_both_images(tmp_path):
    import zipfile

    from curved_scenes import write_usdz

    src = write_usdz(tmp_path / "src")
    report = convert(src, tmp_path / "out", cones="quadrant", variant="quadrant")
    out = tmp_path / "out" / src.name
    names = set(zipfile.ZipFile(out).namelist())
    firsts = {n for n in names if n.endswith("_csm.png")}
    assert len(firsts) == 2 and {second_path(n).name for n in firsts} <= names  # both images inside
    assert {second_path(n).name for n in firsts} <= {p.name for p in report.written}  # and beside, as the first
    _, stored, _, _ = read_converted(out)
    assert all(s.step_map2 is not None and s.step_map2.data for s in stored.values())
    # the test scene itself states no metersPerUnit; nothing else is wrong with the package
    assert [e for e in validation_errors(out) if not e.startswith("MissingMetersPerUnitMetadata")] == []


def _edit_gltf(out, change):
    doc = json.loads(out.read_text())
    change(doc["materials"][0]["extensions"][GLTF_EXTENSION])
    out.write_text(json.dumps(doc))


def _edit_mtl(out, change):
    mtl = out.parent / "brick_wall.mtl"
    mtl.write_text(change(mtl.read_text()))


@pytest.mark.parametrize("name,edit,message", [
    ("brick_wall.gltf", lambda o: _edit_gltf(o, lambda e: e.pop("stepMap2Texture")), "needs the quadrant map's second"),
    ("brick_wall.gltf", lambda o: _edit_gltf(o, lambda e: e.update(variant="exact")), "drawn only by variant 'quadrant'"),
    ("brick_wall.gltf", lambda o: _edit_gltf(o, lambda e: e["stepMap2Texture"].update(texCoord=1)), "share one uv set"),
    ("brick_wall.obj", lambda o: _edit_mtl(o, lambda t: t.replace("csm_map2 ", "# csm_map2 ")),
     "needs the quadrant map's second"),
    ("brick_wall.obj", lambda o: _edit_mtl(o, lambda t: t.replace("csm_variant quadrant", "csm_variant loop")),
     "drawn only by variant 'quadrant'"),
    ("brick_wall.usda", lambda o: o.write_text(o.read_text().replace('token inputs:variant = "quadrant"',
                                                                     'token inputs:variant = "exact"')),
     "drawn only by variant 'quadrant'"),
])
def test_second_image_and_variant_must_agree(tmp_path, name, edit, message):
    _, out, _ = _convert(tmp_path, name)
    edit(out)
    with pytest.raises(FormatError, match=message) as e:
        read_converted(out)
    assert name in str(e.value) or "brick_wall.mtl" in str(e.value)
    assert "bricks" in str(e.value) or "material" in str(e.value)  # names the material
    r = run_cli("verify", out, "--size", "16", "--views", "60")
    assert_clean_error(r, 3, message.split("'")[0])


def test_other_variants_and_cones_are_refused(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL) / "brick_wall.gltf"
    with pytest.raises(OptionError, match="quadrant variant, not 'exact'"):
        convert(src, tmp_path / "a", cones="quadrant")  # the library's default variant, exact
    with pytest.raises(OptionError, match="quadrant variant"):
        convert(src, tmp_path / "a", cones="quadrant", variant="relaxed")
    with pytest.raises(OptionError, match="only quadrant cones, not conservative"):
        convert(src, tmp_path / "a", variant="quadrant")
    assert not (tmp_path / "a").exists()
    assert_clean_error(run_cli("convert", src, "-o", tmp_path / "b", "--cones", "quadrant", "--variant", "exact"),
                       2, "quadrant")
    assert not (tmp_path / "b").exists()
    assert_clean_run(run_cli("convert", src, "-o", tmp_path / "c", "--cones", "quadrant", "-q"))  # its own variant
    ext = json.loads((tmp_path / "c" / "brick_wall.gltf").read_text())["materials"][0]["extensions"][GLTF_EXTENSION]
    assert ext["variant"] == "quadrant" and "stepMap2Texture" in ext


def test_a_deleted_or_edited_second_image_is_stale(tmp_path):
    src, out, _ = _convert(tmp_path, "brick_wall.gltf")
    settings = ConvertOptions(**QUAD).settings(src.parent)
    assert manifest.staleness(src, out.parent, settings, root=src.parent) is None
    second = out.parent / "bricks_height_csm_q.png"
    kept = second.read_bytes()
    second.write_bytes(kept[:-1] + bytes([kept[-1] ^ 1]))
    assert manifest.staleness(src, out.parent, settings, root=src.parent) == \
        "output bricks_height_csm_q.png was modified"
    second.unlink()
    assert manifest.staleness(src, out.parent, settings, root=src.parent) == "output bricks_height_csm_q.png is missing"
    r = run_cli("check", src, "-o", out.parent, "--cones", "quadrant", "--depth", "0.05")
    assert r.returncode == 1 and "bricks_height_csm_q.png is missing" in r.stdout + r.stderr
    again = convert(src, out.parent, **QUAD)  # converted again: the second image is back
    assert again.skipped is None and second.read_bytes() == kept


def test_hook_with_a_configuration_writes_both_images(tmp_path):
    src = copy_samples(tmp_path / "repo", GLTF_WALL)
    (src / ".git").mkdir()
    (src / "csm-assets.toml").write_text('cones = "quadrant"\ndepth = 0.05\n')
    r = run_cli("hook", src / "brick_wall.gltf", cwd=src)
    assert r.returncode == 1, r.stderr  # it wrote outputs
    out = src / "brick_wall_gltf_csm"
    assert (out / "bricks_height_csm.png").is_file() and (out / "bricks_height_csm_q.png").is_file()
    assert run_cli("check", src / "brick_wall.gltf", cwd=src).returncode == 0
    (out / "bricks_height_csm_q.png").unlink()
    assert run_cli("check", src / "brick_wall.gltf", cwd=src).returncode == 1
    assert run_cli("hook", src / "brick_wall.gltf", cwd=src).returncode == 1  # made again
    assert (out / "bricks_height_csm_q.png").is_file()


def test_the_cache_gives_both_images_again(tmp_path):
    src, out, _ = _convert(tmp_path, "brick_wall.obj", cache_dir=tmp_path / "cache")
    _, out2, _ = _convert(tmp_path, "brick_wall.obj", folder="out2", cache_dir=tmp_path / "cache")
    for n in ("bricks_height_csm.png", "bricks_height_csm_q.png"):
        np.testing.assert_array_equal(read_step_map(out.parent / n), read_step_map(out2.parent / n))
    assert read_converted(out2)[1]["bricks"].step_map2.path.name == "bricks_height_csm_q.png"


def test_a_name_another_scene_owns_moves_both_images(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    shutil.copyfile(src / "brick_wall.gltf", src / "other_wall.gltf")
    convert(src / "other_wall.gltf", tmp_path / "out", variant="exact", depth=0.05)  # owns bricks_height_csm.png
    report = convert(src / "brick_wall.gltf", tmp_path / "out", **QUAD)
    (first,) = report.step_maps.values()
    assert first.name == "bricks_height_csm_1.png" and second_path(first).is_file()
    _, stored, _, _ = read_converted(tmp_path / "out" / "brick_wall.gltf")
    assert stored[0].step_map2.path.name == "bricks_height_csm_1_q.png"


def test_verify_passes_on_real_maps(tmp_path, shared_data):
    """bricks2 (glTF) and the toy box (OBJ), depth maps, converted with quadrant cones."""
    for name, image in (("brick_wall.gltf", "bricks2_disp.jpg"), ("brick_wall.obj", "toy_box_disp.png")):
        heights = {"bricks": HeightSpec(shared_data / image, depth_map=True)}
        _, out, _ = _convert(tmp_path / name, name, heights=heights, allow_outside=True, depth=0.08)
        report = verify_scene(out, size=48, views=((90.0, 0.0), (35.0, 200.0), (15.0, 45.0)))
        assert report.passed, report.to_dict()
        assert [v.variant for p in report.primitives for v in p.variants] == ["quadrant"]
    assert_clean_run(run_cli("verify", out, "--size", "32", "--views", "40"))


def test_max_error_picks_a_quadrant_setting(tmp_path, shared_data):
    heights = {"bricks": HeightSpec(shared_data / "bricks2_disp.jpg", depth_map=True)}
    src, out, report = _convert(tmp_path, "brick_wall.gltf", variant="auto", max_error=0.5, heights=heights,
                                allow_outside=True)
    (pick,) = report.picks.values()
    assert pick["variant"] == "quadrant" and pick["min_step"] in QUADRANT_MIN_STEPS
    ext = json.loads(out.read_text())["materials"][0]["extensions"][GLTF_EXTENSION]
    assert ext["variant"] == "quadrant" and ext["minStep"] == pick["min_step"] and "stepMap2Texture" in ext
    assert verify_scene(out, max_error=0.5).passed  # verify's own views and size, as the confirmation drew


def test_the_pick_can_minimise_the_block_cost(tmp_path):
    """pick_cost "block" ranks the settings meeting the budget by the block cost (each 8x4 pixel
    block's worst ray), "fetches" by mean fetches: on a smooth field exact takes the fewest fetches
    on average, but its slow rays make its blocks dearer than a fixed 4 steps."""
    from conftest import random_field

    from csm_assets.bench.trade import pick_settings
    from csm_assets.convert.pick import ranked_settings

    sm = make_step_map(random_field(32, 3, 2.0), StepMapSettings())
    configs = [("exact", 0), ("fixed", 4), ("fixed", 8), ("loop", 4), ("loop", 8)]
    _, _, report = pick_settings(sm.pixels, 2.0, configs=configs, max_ratio=1.0, tile=(True, True), depth=0.05,
                                 min_step=sm.min_step)
    rows = {(r.variant, r.steps): r for r in report.rows if r.p95_error <= 2.0}
    firsts = {}
    for cost, key in (("fetches", "mean_iterations"), ("block", "block_cost")):
        opts = ConvertOptions(variant="auto", max_error=2.0, pick_cost=cost)
        order = [c[:2] for c in ranked_settings(sm.pixels, 1.0, (True, True), 0.05, sm.min_step, "conservative", opts,
                                                configs)]
        costs = [getattr(rows[c], key) for c in order if c in rows]
        assert costs == sorted(costs) and len(costs) >= 3
        firsts[cost] = order[0]
    assert firsts["fetches"] == ("exact", 0) and firsts["block"] != ("exact", 0)
    with pytest.raises(OptionError, match="pick_cost"):
        convert(copy_samples(tmp_path / "in", GLTF_WALL) / "brick_wall.gltf", tmp_path / "out", pick_cost="warp")
    r = run_cli("config", "show", tmp_path / "in" / "brick_wall.gltf", "--pick-cost", "block")
    assert r.returncode == 0 and "block" in r.stdout, r.stderr


def test_verify_variant_all_draws_a_quadrant_scene_with_its_own_variant(tmp_path, capsys):
    """--variant all draws each primitive with every variant that draws its map: a quadrant
    material with quadrant only (with --shadows too, its own variant); naming another variant
    for it, or quadrant for a conservative scene, is exit 2 before anything is drawn."""
    from csm_assets.cli import main

    skip_without_gl()
    _, out, _ = _convert(tmp_path, "brick_wall.gltf")
    base = ["verify", str(out), "--size", "24", "--views", "40", "--json"]
    assert main([*base, "--variant", "all", "--shadows", "--light-elevation", "45", "--light-azimuth", "30"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [v["variant"] for p in data["primitives"] for v in p["variants"]] == ["quadrant"]
    assert data["shadows"]["views"] and data["shadows"]["variant"] == "each material's variant"
    assert main([*base, "--variant", "exact"]) == 2
    assert "drawn by the quadrant variant only, not exact" in capsys.readouterr().err
    src = copy_samples(tmp_path / "c_in", GLTF_WALL)
    convert(src / "brick_wall.gltf", tmp_path / "c", variant="exact")
    assert main(["verify", str(tmp_path / "c" / "brick_wall.gltf"), "--size", "24", "--variant", "quadrant"]) == 2
    assert "quadrant maps (two images)" in capsys.readouterr().err
