"""Step maps of the shared real depth maps, checked texel by texel on sample rows."""

from __future__ import annotations

import numpy as np
import pytest

from csm_assets import load_heightfield, step_map, unpack_step_map
from reference import brute_cone_ratios


@pytest.mark.parametrize("name", ["toy_box_disp.png", "bricks2_disp.jpg"])
@pytest.mark.parametrize("tile", [True, False])
def test_real_depth_maps_match_reference(shared_data, name, tile):
    hf = load_heightfield(shared_data / name, invert=True)
    h = hf.data.astype(np.float64)
    p = step_map(hf.data, tile=tile, bits=32)
    H = h.shape[0]
    rows = [0, H // 3, H - 1]
    want = brute_cone_ratios(h, tile, tile, 1.0, rows=rows)[rows]
    got = unpack_step_map(p)["ratio"][rows]
    assert (got <= want).all()
    np.testing.assert_allclose(got, want, rtol=1e-6)
    p8 = step_map(hf.data, tile=tile)
    g = p8[rows][..., 1] / 255.0
    assert (g ** 2 <= want * (1 + 1e-12)).all() and (np.sqrt(want) - g < 1 / 255 + 1e-12).all()
