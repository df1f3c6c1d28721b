"""Every output format names a step map's levels images (docs/reference/levels.md): glTF/GLB
``stepMapLevelsTexture``/``stepMap2LevelsTexture``, MTL ``csm_map_levels``/``csm_map2_levels``,
USD the CSM shader's ``stepMapLevels``/``stepMap2Levels`` (in its Sdr definition), and verify
reads them back from each (StoredCsm.levels; verify's primitives cut them into the levels
``load_step_map`` gives), refusing a levels image of the wrong size, or levels named for one image
of a quadrant map, with exit 3 naming the file."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from attack import assert_clean_error, run_cli
from conftest import OBJ_WALL, copy_samples
from test_levels_convert import SCENES, _direct, converted

from csm_assets.convert.pipeline import convert
from csm_assets.errors import FormatError
from csm_assets.stepmap import StepMapSettings, levels_path
from csm_assets.verify.converted import read_converted
from csm_assets.verify.scene import primitives



def _read_back(path):
    scene, stored, _, models = read_converted(path)
    return stored, primitives(scene, stored, models, generate_tangents=False)


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize("cones", ["conservative", "quadrant"])
def test_every_format_names_the_levels_and_verify_reads_them_back(tmp_path, name, cones):
    src = copy_samples(tmp_path / "in", SCENES[name])
    extra = {"variant": "quadrant"} if cones == "quadrant" else {}
    convert(src / name, tmp_path / "out", levels="average", bits=8, cones=cones, **extra)
    sm = _direct(src / name, StepMapSettings(levels="average", bits=8, cones=cones))
    stored, prims = _read_back(tmp_path / "out" / name)
    assert len(stored) == 1 and prims
    (s,) = stored.values()
    assert len(s.levels) == (2 if cones == "quadrant" else 1)
    for p in prims:
        chains = [sm.levels, sm.second_levels][:len(s.levels)]
        assert len(p.levels) == len(chains)
        for got, want in zip(p.levels, chains):
            assert len(got) == len(want) > 0
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)
    if name.endswith(".obj"):
        mtl = (tmp_path / "out" / "brick_wall.mtl").read_text()
        first = re.search(r"^csm_map (\S+)$", mtl, re.M).group(1)
        assert f"csm_map_levels {levels_path(Path(first)).name}\n" in mtl
        assert ("csm_map2_levels" in mtl) == (cones == "quadrant")
    assert run_cli("verify", tmp_path / "out" / name, "--json").returncode == 0


@pytest.mark.parametrize("name", ["brick_wall.obj", "brick_wall.usda"])
def test_without_levels_no_format_names_any(tmp_path, name):
    src = copy_samples(tmp_path / "in", SCENES[name])
    convert(src / name, tmp_path / "out", levels="none")
    (s,) = _read_back(tmp_path / "out" / name)[0].values()
    assert s.levels == ()
    text = (tmp_path / "out" / name.replace(".obj", ".mtl")).read_text()
    named, levels = ("csm_map ", "csm_map_levels") if name.endswith(".obj") else ("inputs:stepMap =", "stepMapLevels")
    assert named in text and levels not in text


@pytest.mark.parametrize("name", ["brick_wall.gltf", "brick_wall.obj", "brick_wall.usda"])
def test_a_levels_image_of_the_wrong_size_is_exit_3_naming_it(tmp_path, name):
    from PIL import Image

    lv = levels_path(converted(tmp_path, name, levels="average", bits=8)[1])
    img = Image.open(lv)
    img.crop((0, 0, img.width - 1, img.height)).save(lv)
    with pytest.raises(FormatError, match="levels image"):
        _read_back(tmp_path / "out" / name)
    line = assert_clean_error(run_cli("verify", tmp_path / "out" / name), 3, lv.name)
    assert "the levels image is 126x64, 4 channel(s) uint8; expected 127x64 RGBA uint8" in line, line


def test_a_quadrant_mtl_naming_one_levels_image_is_refused(tmp_path):
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    convert(src / "brick_wall.obj", tmp_path / "out", levels="average", cones="quadrant", variant="quadrant")
    mtl = tmp_path / "out" / "brick_wall.mtl"
    mtl.write_text("".join(x for x in mtl.read_text().splitlines(True) if not x.startswith("csm_map2_levels")))
    with pytest.raises(FormatError, match="one levels image for each of its 2"):
        _read_back(tmp_path / "out" / "brick_wall.obj")
