"""Levels through convert: ``levels`` (option, flag and configuration key) writes each step map's
levels image beside it (or inside a GLB / .usdz), named by the glTF extension
(stepMapLevelsTexture), listed in the manifest, fresh on the next run; the average chain by default."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest
from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from usd_stages import USD_WALL

from csm_assets.convert import manifest
from csm_assets.convert.pipeline import ConvertOptions, convert, scene_module
from csm_assets.errors import FormatError
from csm_assets.formats import load_heightfield
from csm_assets.formats.csm_params import GLTF_EXTENSION
from csm_assets.stepmap import StepMapSettings, levels_path, load_step_map, make_step_map

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
SCENES = {"brick_wall.gltf": GLTF_WALL, "brick_wall.glb": GLTF_WALL, "brick_wall.obj": OBJ_WALL,
          "brick_wall.usda": USD_WALL}


def _direct(src, settings):
    """The step map made straight from the scene's height texture, as convert reads it."""
    scene = scene_module(src).read(src)
    (h,) = [m.height for m in scene.materials if m.height is not None]
    with h.texture.as_file() as file:
        return make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings)


def converted(tmp_path, name: str, **options):
    """(the report, the one step map's path) of sample scene ``name`` (:data:`SCENES`) copied to
    ``tmp_path/in`` and converted into ``tmp_path/out`` with ``options``."""
    src = copy_samples(tmp_path / "in", SCENES[name])
    report = convert(src / name, tmp_path / "out", **options)
    (path,) = report.step_maps.values()
    return report, path


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.obj", "brick_wall.usda"])
def test_levels_images_are_written_beside_each_map_and_fresh_next_run(tmp_path, name):
    report, path = converted(tmp_path, name, levels="average", bits=8)
    src = tmp_path / "in"
    sm = load_step_map(path)
    want = _direct(src / name, StepMapSettings(levels="average", bits=8))
    assert sm.settings.levels == "average" and len(sm.levels) == len(want.levels) > 0
    for a, b in zip(sm.levels, want.levels):
        np.testing.assert_array_equal(a, b)
    assert levels_path(path) in report.written
    settings = ConvertOptions(levels="average", bits=8).settings()
    assert manifest.staleness(src / name, tmp_path / "out", settings) is None
    assert manifest.staleness(src / name, tmp_path / "out", ConvertOptions(bits=8).settings()) is None  # default
    assert manifest.staleness(src / name, tmp_path / "out", ConvertOptions(levels="none", bits=8).settings()) \
        == "settings changed"


def test_gltf_names_the_levels_image_in_its_extension(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    convert(src / "brick_wall.gltf", tmp_path / "out", levels="max", cones="quadrant", variant="quadrant")
    doc = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())
    ext = doc["materials"][0]["extensions"][GLTF_EXTENSION]
    schema = json.loads((ROOT / "docs" / "EXT_materials_cone_step_mapping.schema.json").read_text())
    assert [e.message for e in jsonschema.Draft202012Validator(schema).iter_errors(ext)] == []
    uris = {key: doc["images"][doc["textures"][ext[key]["index"]]["source"]]["uri"]
            for key in ("stepMapTexture", "stepMap2Texture", "stepMapLevelsTexture", "stepMap2LevelsTexture")}
    assert uris == {"stepMapTexture": "bricks_height_csm.png", "stepMap2Texture": "bricks_height_csm_q.png",
                    "stepMapLevelsTexture": "bricks_height_csm_levels.png",
                    "stepMap2LevelsTexture": "bricks_height_csm_q_levels.png"}
    assert all((tmp_path / "out" / u).is_file() for u in uris.values())
    assert ext["stepMapLevelsTexture"]["texCoord"] == ext["stepMapTexture"]["texCoord"]
    from khronos import errors, validate

    assert errors(validate(tmp_path / "out" / "brick_wall.gltf")) == []


def test_glb_embeds_the_levels_image(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    report = convert(src / "brick_wall.glb", tmp_path / "out", levels="average")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["brick_wall.glb", manifest.NAME]
    assert report.step_maps
    from csm_assets.formats import gltf_container as gc

    doc = gc.load(tmp_path / "out" / "brick_wall.glb")
    ext = doc.json["materials"][0]["extensions"][GLTF_EXTENSION]
    image = doc.json["images"][doc.json["textures"][ext["stepMapLevelsTexture"]["index"]]["source"]]
    assert "bufferView" in image and image["mimeType"] == "image/png"
    from khronos import errors, validate

    assert errors(validate(tmp_path / "out" / "brick_wall.glb")) == []


def test_the_average_chain_by_default_and_the_manifest_records_it(tmp_path):
    """The default chain is written and named; the manifest records ``levels`` always, so outputs
    made without it (an entry without the key: before the default was "average") are stale."""
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    convert(src / "brick_wall.gltf", tmp_path / "out")
    ext = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())["materials"][0]["extensions"][GLTF_EXTENSION]
    assert "stepMapLevelsTexture" in ext and [p.name for p in (tmp_path / "out").glob("*_levels*")] == \
        ["bricks_height_csm_levels.png"]
    assert ConvertOptions().settings()["levels"] == "average"
    assert ConvertOptions(levels="none").settings()["levels"] == "none"
    assert_clean_run(run_cli("check", src / "brick_wall.gltf", "-o", tmp_path / "out"))
    path = tmp_path / "out" / manifest.NAME
    m = json.loads(path.read_text())
    del m["scenes"]["brick_wall.gltf"]["settings"]["levels"]  # as a manifest written under the old default
    path.write_text(json.dumps(m))
    r = run_cli("check", src / "brick_wall.gltf", "-o", tmp_path / "out")
    assert r.returncode == 1 and "settings changed" in r.stdout + r.stderr


def test_configuration_key_and_flag(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    (src / "csm-assets.toml").write_text('levels = "max"\n')
    assert_clean_run(run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "out", "-q"))
    (path,) = (tmp_path / "out").glob("*_csm.png")
    assert load_step_map(path).settings.levels == "max" and levels_path(path).is_file()
    r = run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "none", "--levels", "none", "-q")
    assert_clean_run(r)
    assert not list((tmp_path / "none").glob("*_levels*"))
    (src / "csm-assets.toml").write_text('levels = "mean"\n')
    assert_clean_error(run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "bad"), 2, "csm-assets.toml")


def test_a_cached_map_comes_back_with_its_levels(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    cache = tmp_path / "cache"
    first = convert(src / "brick_wall.gltf", tmp_path / "a", levels="average", cache_dir=cache)
    second = convert(src / "brick_wall.gltf", tmp_path / "b", levels="average", cache_dir=cache)
    (a,), (b,) = first.step_maps.values(), second.step_maps.values()
    assert levels_path(b).is_file() and levels_path(b).read_bytes() == levels_path(a).read_bytes()
    assert len(load_step_map(b).levels) == len(load_step_map(a).levels) > 0
    assert len(list(cache.rglob("*_levels.png"))) == 1  # the cache holds the levels beside the map


def test_a_bad_levels_texture_index_is_refused_naming_it(tmp_path):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    convert(src / "brick_wall.gltf", tmp_path / "out", levels="average")
    out = tmp_path / "out" / "brick_wall.gltf"
    doc = json.loads(out.read_text())
    doc["materials"][0]["extensions"][GLTF_EXTENSION]["stepMapLevelsTexture"]["index"] = 99
    out.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="stepMapLevelsTexture/index"):
        scene_module(out).read(out)


def test_a_usdz_package_holds_the_levels_images(tmp_path):
    import zipfile

    from curved_scenes import write_usdz
    from usd_stages import validation_errors

    src = write_usdz(tmp_path / "src")
    convert(src, tmp_path / "out", levels="average")
    out = tmp_path / "out" / src.name
    names = set(zipfile.ZipFile(out).namelist())
    firsts = {n for n in names if n.endswith("_csm.png")}
    assert len(firsts) == 2 and {levels_path(n).name for n in firsts} <= names
    assert [e for e in validation_errors(out) if not e.startswith("MissingMetersPerUnitMetadata")] == []
