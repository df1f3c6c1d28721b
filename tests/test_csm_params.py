"""The one CSM material parameter list (formats/csm_params.py): every parameter written and read
back in every format (glTF, GLB, OBJ/MTL, USD), in the schema's order, self-shadowing included;
outputs without self-shadowing as before; the schema document and the USD shader definition
list the same parameters."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from usd_stages import USD_WALL, validation_errors

from csm_assets.convert.pipeline import ConvertOptions, convert
from csm_assets.errors import OptionError
from csm_assets.formats.csm_params import BY_NAME, GLTF_EXTENSION, PARAMETERS
from csm_assets.height_source import HeightSpec
from csm_assets.verify.scene import read_converted

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"brick_wall.gltf": GLTF_WALL, "brick_wall.glb": GLTF_WALL, "brick_wall.obj": OBJ_WALL,
          "brick_wall.usda": USD_WALL}
# every parameter away from its default: a depth map gives heightScale -1 and heightOffset 1
SET = dict(depth=0.07, max_ratio=0.5, tile=False, variant="loop", steps=24, bilinear_safe=False,
           self_shadow=True, light_size=0.05)
EXPECT = dict(depth_scale=0.07, max_ratio=0.5, tile=(False, False), height_scale=-1.0, height_offset=1.0,
              variant="loop", steps=24, min_step=1.0, self_shadow=True, light_size=0.05)


def _convert(tmp_path, name, **options):
    src = copy_samples(tmp_path / "in", SCENES[name])
    heights = {"bricks": HeightSpec(src / "bricks_height.png", depth_map=True)} if options else {}
    convert(src / name, tmp_path / "out", heights=heights, **options)
    return tmp_path / "out" / name


def test_the_list_follows_the_schema():
    schema = json.loads((ROOT / "docs" / "EXT_materials_cone_step_mapping.schema.json").read_text())
    props = [k for k in schema["properties"] if not k.endswith("Texture")]  # the textureInfos
    assert [p.name for p in PARAMETERS] == props
    kinds = {"number": "number", "integer": "integer", "boolean": "boolean", "string": "string", "tile": "array"}
    for p in PARAMETERS:
        assert schema["properties"][p.name]["type"] == kinds[p.kind], p.name
        assert schema["properties"][p.name].get("description"), p.name
        if p.default is not None and p.kind != "tile":
            assert schema["properties"][p.name]["default"] == p.default, p.name
    defs = (ROOT / "shaders" / "csm_shaderDefs.usda").read_text()
    assert "bool inputs:selfShadow = 0" in defs and "float inputs:lightSize = 0" in defs


@pytest.mark.parametrize("name", list(SCENES))
def test_every_parameter_round_trips(tmp_path, name):
    out = _convert(tmp_path, name, **SET)
    _, stored, _, _ = read_converted(out)
    (s,) = stored.values()
    for attr, value in EXPECT.items():
        got = getattr(s, attr)
        assert got == pytest.approx(value, rel=1e-6) if isinstance(value, float) else got == value, attr
    if name.endswith(".gltf"):
        from khronos import errors, validate

        assert errors(validate(out)) == []
        ext = json.loads(out.read_text())["materials"][0]["extensions"][GLTF_EXTENSION]
        assert list(ext)[2:] == [p.name for p in PARAMETERS]  # the schema's order
        assert list(ext)[:2] == ["stepMapTexture", "stepMapLevelsTexture"]  # the level chain: on by default
        assert ext["selfShadow"] is True and ext["lightSize"] == 0.05
        import pygltflib  # a third-party reader sees the same extension

        g = pygltflib.GLTF2().load(str(out))
        assert g.materials[0].extensions[GLTF_EXTENSION]["selfShadow"] is True
        assert GLTF_EXTENSION in g.extensionsUsed
    if name.endswith(".obj"):
        lines = [x.split()[0] for x in (out.parent / "brick_wall.mtl").read_text().splitlines()
                 if x.startswith("csm_")]
        assert lines == ["csm_map", "csm_map_levels", *(p.mtl for p in PARAMETERS)]
    if name.endswith(".usda"):
        assert validation_errors(out) == []


@pytest.mark.parametrize("name", list(SCENES))
def test_without_self_shadow_nothing_new_is_written(tmp_path, name):
    out = _convert(tmp_path, name)
    text = (out.parent / "brick_wall.mtl" if name.endswith(".obj") else out).read_bytes()
    for word in (b"selfShadow", b"lightSize", b"csm_self_shadow", b"csm_light_size"):
        assert word not in text
    manifest = json.loads((out.parent / "csm-manifest.json").read_text())
    settings = manifest["scenes"][name]["settings"]
    assert "self_shadow" not in settings and "light_size" not in settings  # old manifests stay fresh
    _, stored, _, _ = read_converted(out)
    (s,) = stored.values()
    assert s.self_shadow is False and s.light_size == 0.0


def test_hard_self_shadows_write_only_the_switch(tmp_path):
    out = _convert(tmp_path, "brick_wall.gltf", self_shadow=True)
    ext = json.loads(out.read_text())["materials"][0]["extensions"][GLTF_EXTENSION]
    assert ext["selfShadow"] is True and "lightSize" not in ext


@pytest.mark.parametrize("bad", [dict(light_size=-0.1, self_shadow=True), dict(light_size=float("nan"),
                                 self_shadow=True), dict(light_size=float("inf"), self_shadow=True),
                                 dict(light_size="wide", self_shadow=True), dict(self_shadow="yes"),
                                 dict(light_size=0.1)])
def test_bad_self_shadow_options_are_option_errors(tmp_path, bad):
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    with pytest.raises(OptionError):
        convert(src / "brick_wall.gltf", tmp_path / "out", **bad)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("steps", [-1, 128, 200, 2.5, True, "8"])
def test_steps_a_material_cannot_carry_are_option_errors(tmp_path, steps):
    """`steps` outside 0..127 (the schema's and verify's range; 0: the variant's default) used to
    be written and only refused by verify later; now convert refuses it (exit 2 on the command
    line, where --steps takes 1..127), writing nothing."""
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    with pytest.raises(OptionError, match="0..127"):
        convert(src / "brick_wall.gltf", tmp_path / "out", variant="loop", steps=steps)
    assert not (tmp_path / "out").exists()
    if steps == 128:
        from attack import assert_clean_error, run_cli

        r = run_cli("convert", src / "brick_wall.gltf", "-o", tmp_path / "cli", "--variant", "loop", "--steps", "128")
        assert_clean_error(r, 2, "--steps")
        assert not (tmp_path / "cli").exists()


def test_defaults_come_from_the_list():
    o = ConvertOptions()
    assert o.self_shadow is BY_NAME["selfShadow"].default and o.light_size == BY_NAME["lightSize"].default
