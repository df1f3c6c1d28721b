"""The shadow reference on float maps of exact and near ties (tests/tie_maps.py): every
answer comes with evidence checked without the tracer. Shadowed: the tracer's first hit
lies on the bilinear surface (scipy's) before the tolerance, or on the side of a
non-tiled map under it (the ray enters the block there). Lit: no point of the ray
from the tolerance up to where it enters the relief is under the surface, sampled finely.
Points sit at texel centres (the cells' corners, where ties meet), on texel edges and
anywhere; lights come from any side, along the axes and diagonals too."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from conftest import examples
from csm_assets.verify.shadow_reference import HEIGHT_TOLERANCE, TOLERANCE, entry_distance, hard_shadows, sample_surface
from csm_assets.verify.trace import trace_heightfield
from test_shadow_reference import surface
from tie_maps import tie_fields

TILINGS = [(True, True), (False, False), (True, False), (False, True)]
SLACK = 1e-9  # of height: far above float64 rounding, far below any tie map's real steps


def points_and_lights(h, rng, n=12):
    rows, cols = h.shape
    k = rng.integers(0, 3, n)
    cells = np.column_stack([rng.integers(0, cols, n), rng.integers(0, rows, n)])
    uv = np.where(k[:, None] == 0, (cells + 0.5) / [cols, rows],
                  np.where(k[:, None] == 1, cells / [cols, rows], rng.random((n, 2))))
    az = np.where(rng.random(n) < 0.5, rng.integers(0, 8, n) * np.pi / 4, rng.uniform(0, 2 * np.pi, n))
    el = rng.uniform(np.radians(3), np.radians(89), n)
    return uv, np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


@examples(0.5)
@given(tie_fields(6), st.sampled_from(TILINGS), st.integers(0, 2 ** 32 - 1))
def test_every_answer_has_evidence(h, tile, seed):
    uv, light = points_and_lights(h, np.random.default_rng(seed))
    p = np.column_stack([uv, sample_surface(h, uv, tile)])
    assert np.allclose(p[:, 2], surface(h, uv[:, 0], uv[:, 1], tile), rtol=0, atol=SLACK)
    lit = hard_shadows(h, p, light, tile=tile)
    start = entry_distance(p, light, tile)
    tol = np.maximum(TOLERANCE / max(h.shape), HEIGHT_TOLERANCE / light[:, 2])
    hit_uv, t, hit = trace_heightfield(h, p + light * start[:, None], -light, tile=tile)
    for i in np.flatnonzero(~lit):
        assert hit[i] and t[i] < start[i] - tol[i]
        z = p[i, 2] + light[i, 2] * (start[i] - t[i])
        gap = surface(h, hit_uv[i, :1], hit_uv[i, 1:], tile)[0] - z
        side = any(not tiled and min(hit_uv[i, a], 1 - hit_uv[i, a]) < 1e-12 for a, tiled in enumerate(tile))
        assert (gap >= -SLACK if side else abs(gap) <= SLACK), (i, p[i], light[i])  # the block's side, or on top
    for i in np.flatnonzero(lit & (start > tol)):
        s = np.linspace(tol[i], start[i], 4000)
        q = p[i] + s[:, None] * light[i]
        under = surface(h, q[:, 0], q[:, 1], tile) - q[:, 2]
        assert under.max() <= SLACK, (i, p[i], light[i], s[np.argmax(under)])
