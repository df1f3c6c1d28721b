"""Attacks on converted materials (issues 14, 16): a CSM parameter of the wrong type, negative,
NaN or infinite in a glTF extension, an MTL statement or a USD shader input is exit 3 naming
the file and the material, for every format, through the real CLI (tests/attack.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from attack import Attack, assert_clean_error, run_cli
from conftest import GLTF_WALL, OBJ_WALL, copy_samples
from usd_stages import USD_WALL, edit

from csm_assets.convert.pipeline import convert
from csm_assets.formats.csm_params import GLTF_EXTENSION


def _converted(tmp_path: Path, files, name: str) -> Path:
    src = copy_samples(tmp_path / "in", files)
    convert(src / name, tmp_path / "out", self_shadow=True, light_size=0.02)
    return tmp_path / "out" / name


GLTF_CASES = [("selfShadow", "yes", "selfShadow must be a boolean"), ("selfShadow", 1, "selfShadow must be a boolean"),
              ("lightSize", -0.5, "lightSize must be a finite number >= 0"), ("lightSize", "0.1", "lightSize must be a number"),
              ("lightSize", True, "lightSize must be a number"), ("lightSize", 1e400, "lightSize"),
              ("heightScale", "x", "heightScale must be a number"), ("tile", [1, 0], "tile must be two booleans"),
              ("steps", 2.5, "steps must be an integer"), ("maxRatio", 0, "maxRatio must be a finite number > 0")]


@pytest.mark.parametrize("key, value, said", GLTF_CASES)
def test_gltf_extension_values(tmp_path, key, value, said):
    out = _converted(tmp_path, GLTF_WALL, "brick_wall.gltf")
    doc = json.loads(out.read_text())
    doc["materials"][0]["extensions"][GLTF_EXTENSION][key] = value
    text = json.dumps(doc)
    out.write_text(text.replace("1e+400", "1e400").replace("Infinity", "1e400"))
    with Attack(out.parent):
        r = run_cli("verify", out, "--size", "16")
    line = assert_clean_error(r, 3, "brick_wall.gltf")
    assert ("'bricks'" in line or "/materials/0/" in line) and said in line, line  # NaN/inf: the JSON check


@pytest.mark.parametrize("statement, said", [
    ("csm_self_shadow 2", "csm_self_shadow expected 0 or 1"), ("csm_self_shadow yes", "csm_self_shadow expected 0 or 1"),
    ("csm_light_size -1", "lightSize must be a finite number >= 0"), ("csm_light_size nan", "lightSize"),
    ("csm_light_size inf", "lightSize"), ("csm_light_size wide", "csm_light_size expected a number"),
    ("csm_height_scale nan", "heightScale"), ("csm_tile 1", "csm_tile expected two of 0 and 1")])
def test_mtl_statements(tmp_path, statement, said):
    out = _converted(tmp_path, OBJ_WALL, "brick_wall.obj")
    mtl = out.parent / "brick_wall.mtl"
    key = statement.split()[0]
    lines = [x for x in mtl.read_text().splitlines() if not x.startswith(key + " ")]
    mtl.write_text("\n".join(lines + [statement]) + "\n")
    with Attack(out.parent):
        r = run_cli("verify", out, "--size", "16")
    line = assert_clean_error(r, 3, "brick_wall.mtl")
    assert "'bricks'" in line and said in line, line


@pytest.mark.parametrize("name, type_name, value, said", [
    ("selfShadow", "Int", 1, "selfShadow must be a boolean"), ("lightSize", "Float", -0.25, "lightSize must be"),
    ("lightSize", "Float", float("nan"), "lightSize"), ("lightSize", "Float", float("inf"), "lightSize"),
    ("lightSize", "Token", "wide", "lightSize must be a number")])
def test_usd_shader_inputs(tmp_path, name, type_name, value, said):
    from pxr import Sdf, UsdShade

    out = _converted(tmp_path, USD_WALL, "brick_wall.usda")

    def change(stage):
        for prim in stage.Traverse():
            if prim.IsA(UsdShade.Shader) and UsdShade.Shader(prim).GetShaderId() == "CsmConeStepSurface":
                prim.RemoveProperty(f"inputs:{name}")
                UsdShade.Shader(prim).CreateInput(name, getattr(Sdf.ValueTypeNames, type_name)).Set(value)

    edit(out, change)
    with Attack(out.parent):
        r = run_cli("verify", out, "--size", "16")
    line = assert_clean_error(r, 3, "brick_wall.usda")
    assert "bricks" in line and said in line, line
