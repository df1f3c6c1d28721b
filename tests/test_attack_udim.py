"""UDIM height sets attacked: a set of many tiles (1001-1999) is published without comparing
each output with each input (was: 999 tiny tiles took 154 s on this 2-core machine, most of it
in outputs x inputs path resolutions), and an output still may not overwrite an input."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from csm_assets.convert import output_folder
from csm_assets.errors import OutputError


def _files(folder: Path, n: int, stem: str) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    files = [folder / f"{stem}.{1001 + i}.png" for i in range(n)]
    for f in files:
        f.write_bytes(b"x")
    return files


def test_checking_many_outputs_against_many_inputs_is_linear(tmp_path, monkeypatch):
    """The outputs of a 600-tile set against its 600 tiles: path resolutions grow with
    outputs + inputs (was: outputs x inputs, 720,000 of them)."""
    inputs = _files(tmp_path / "tiles", 600, "h")
    stage = tmp_path / "stage"
    names = [f.name.replace("h.", "h_csm.") for f in _files(stage, 600, "h")]
    count = 0
    resolve = Path.resolve

    def counted(self, *a, **k):
        nonlocal count
        count += 1
        return resolve(self, *a, **k)

    monkeypatch.setattr(Path, "resolve", counted)
    output_folder.check_names(stage, names, tmp_path / "out", inputs, {})
    assert count <= 4 * (len(names) + len(inputs)), count


@pytest.mark.parametrize("how", ["same path", "hard link", "symbolic link"])
def test_an_output_that_is_an_input_is_still_refused(tmp_path, how):
    tiles = _files(tmp_path / "tiles", 3, "h")
    out = tmp_path / "out"
    out.mkdir()
    if how == "same path":
        out = tiles[0].parent
    elif how == "hard link":
        os.link(tiles[1], out / tiles[1].name)
    else:
        (out / tiles[1].name).symlink_to(tiles[1])
    with pytest.raises(OutputError, match="would overwrite the input"):
        output_folder.check_names(tmp_path, [tiles[1].name], out, tiles, {})


def test_a_pattern_naming_udim_twice_is_a_clear_error(tmp_path):
    """Was: ``--height bricks=t/h.<UDIM>.<UDIM>.png`` said "no file h.1001.1001.png ... beside
    it" while a file ``h.1001.<UDIM>.png`` would have been taken as tile 1001 (only the first
    ``<UDIM>`` was matched)."""
    from attack import assert_clean_error, run_cli
    from conftest import SAMPLES

    tiles = tmp_path / "t"
    tiles.mkdir()
    shutil.copy(SAMPLES / "bricks_height.png", tiles / "h.1001.<UDIM>.png")
    shutil.copy(SAMPLES / "brick_wall.usda", tmp_path / "wall.usda")
    r = run_cli("convert", "wall.usda", "-o", "out", "--height", "bricks=t/h.<UDIM>.<UDIM>.png", cwd=tmp_path)
    line = assert_clean_error(r, 3, "h.<UDIM>.<UDIM>.png")
    assert "2 times" in line, line
    assert not (tmp_path / "out").exists()
