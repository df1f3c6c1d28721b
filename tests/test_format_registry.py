"""The format tables (csm_assets/formats/registry.py) drive dispatch and match the docs: every
heightfield extension writes and reads back through its module, stores exactly the step map bits
its row says, and every extension of both tables is in the docs' tables (docs/reference/formats.md,
docs/reference/scenes.md), a scene format's row with the step map bits it takes."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from csm_assets import Heightfield, load_heightfield, save_heightfield
from csm_assets.convert.pipeline import SCENE_FORMATS
from csm_assets.formats import FORMATS, write_step_map
from csm_assets.formats.registry import HEIGHTFIELD_FORMATS, SCENE_FORMAT_ROWS

DOCS = Path(__file__).resolve().parents[1] / "docs" / "reference"
HEIGHT_FORMATS_PAGE = (DOCS / "formats.md").read_text()
SCENES_PAGE = (DOCS / "scenes.md").read_text()
DTYPES = {8: np.uint8, 16: np.uint16, 32: np.float32}


def test_dispatch_tables_come_from_the_registry():
    assert FORMATS == {f.extension: f.module for f in HEIGHTFIELD_FORMATS}
    assert SCENE_FORMATS == {f.extension: f.module for f in SCENE_FORMAT_ROWS}


@pytest.mark.parametrize("row", HEIGHTFIELD_FORMATS, ids=lambda r: r.extension)
def test_every_heightfield_format_round_trips(tmp_path, row):
    n = 8
    data = (np.arange(n * n, dtype=np.float32).reshape(n, n) / (n * n - 1))
    path = tmp_path / f"h{row.extension}"
    save_heightfield(Heightfield(data, None, {}), path)
    back = load_heightfield(path).normalized().data
    assert back.shape == (n, n)
    step = 1 / 255 if row.height_bits == 8 else 1e-4
    assert np.abs(back - data).max() <= (0.05 if row.extension in (".jpg", ".jpeg") else step)
    table = HEIGHT_FORMATS_PAGE.split("## Height maps", 1)[1].split("\n## ", 1)[0]
    assert re.search(rf"`[^`]*{re.escape(row.extension)}\b[^`]*`", table), row.extension


@pytest.mark.parametrize("row", HEIGHTFIELD_FORMATS, ids=lambda r: r.extension)
def test_step_map_bits_are_what_the_row_says(tmp_path, row):
    for bits, dtype in DTYPES.items():
        packed = np.zeros((4, 4, 4), dtype)
        target = tmp_path / f"s{bits}{row.extension}"
        if bits in row.step_map_bits:
            write_step_map(packed, target)
            assert target.is_file()
        else:
            with pytest.raises(ValueError):
                write_step_map(packed, target)


def test_scene_formats_are_in_the_docs():
    table = SCENES_PAGE.split("## Scene formats", 1)[1].split("\n#", 1)[0]
    for row in SCENE_FORMAT_ROWS:
        line = next((ln for ln in table.splitlines() if f"`{row.extension}`" in ln), None)
        assert line is not None, row.extension
        bits = line.split("|")[3]  # the row's step map bits column
        assert set(map(int, re.findall(r"\b(8|16|32)\b", bits))) == set(row.step_map_bits), row.extension
