"""``stepmap --levels``: the levels image beside the map, what --json says, inputs never overwritten;
a map naming its levels image anywhere but beside it is refused."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from attack import assert_clean_error, assert_clean_run, run_cli
from csm_assets import load_step_map, make_step_map, save_step_map
from csm_assets.errors import FormatError
from csm_assets.formats import read_step_map, read_step_map_meta, write_step_map
from csm_assets.stepmap import StepMapSettings, levels_path


def heights(shape=(24, 40)):
    return (np.random.default_rng(2).random(shape) * 255).astype(np.uint8)


def test_stepmap_writes_the_levels_image_and_says_so(tmp_path):
    d = heights()
    Image.fromarray(d).save(tmp_path / "h.png")
    r = run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "m.png", "--levels", "max", "--cones", "quadrant",
                "--bits", "8", "--json")
    assert_clean_run(r)
    out = json.loads(r.stdout)
    assert out["levels"] == str(tmp_path / "m_levels.png") and out["level_count"] == 5
    assert out["second_levels"] == str(tmp_path / "m_q_levels.png") and out["settings"]["levels"] == "max"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.png", "m.png", "m_levels.png", "m_q.png",
                                                          "m_q_levels.png"]
    sm = load_step_map(tmp_path / "m.png")
    want = make_step_map(d, StepMapSettings(levels="max", cones="quadrant"))
    for a, b in zip(sm.levels + sm.second_levels, want.levels + want.second_levels):
        np.testing.assert_array_equal(a, b)
    assert len(sm.levels) == len(sm.second_levels) == 5


def test_stepmap_writes_the_average_chain_by_default_and_none_on_request(tmp_path):
    Image.fromarray(heights()).save(tmp_path / "h.png")
    r = run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "m.png", "--json")
    assert_clean_run(r)
    out = json.loads(r.stdout)
    assert out["levels"] == str(tmp_path / "m_levels.png") and out["settings"]["levels"] == "average"
    assert len(load_step_map(tmp_path / "m.png").levels) == out["level_count"] == 5
    r = run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "n.png", "--levels", "none", "--json")
    assert_clean_run(r)
    assert "levels" not in json.loads(r.stdout) and not levels_path(tmp_path / "n.png").exists()
    assert load_step_map(tmp_path / "n.png").levels == ()


def test_a_levels_image_never_overwrites_the_input(tmp_path):
    Image.fromarray(heights()).save(tmp_path / "x_levels.png")
    before = (tmp_path / "x_levels.png").read_bytes()
    r = run_cli("stepmap", tmp_path / "x_levels.png", "-o", tmp_path / "x.png", "--levels", "average")
    assert_clean_error(r, 2, "x.png")
    assert (tmp_path / "x_levels.png").read_bytes() == before and not (tmp_path / "x.png").exists()
    assert_clean_error(run_cli("stepmap", tmp_path / "x_levels.png", "-o", tmp_path / "y.png", "--levels", "mean"), 2)


def test_a_map_naming_its_levels_outside_its_folder_is_refused(tmp_path):
    sm = make_step_map(heights((8, 8)), StepMapSettings(levels="average"))
    save_step_map(sm, tmp_path / "m.png")
    for bad in ("../m_levels.png", "", 7):
        meta = {**read_step_map_meta(tmp_path / "m.png"), "levels_image": bad}
        write_step_map(read_step_map(tmp_path / "m.png"), tmp_path / "bad.png", meta)
        with pytest.raises(FormatError, match="expected the name of a file beside it"):
            load_step_map(tmp_path / "bad.png")
