"""Packed step maps on float maps of exact and near ties: the stored cone, decoded as the
shader does ((G / N)^2 max_ratio), is never wider than the exact cone, checked in rational
arithmetic; with the bilinear safety pass, never wider than any exact cone of the texel's
3x3 neighbourhood (a bilinear sample between four texels gets at most the narrowest)."""

from __future__ import annotations

import warnings
from fractions import Fraction

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st

from conftest import examples
from csm_assets import step_map
from csm_assets.heightfield import height_levels
from exact_reference import exact_cone_squares
from relaxed_reference import relaxed_squares
from tie_maps import tie_fields

TILINGS = [(True, True), (False, False), (True, False)]


def neighbourhood(sq, r, c, tile):
    """The exact squares of texel (r, c)'s 3x3 neighbourhood (wrapped or cut at the edges)."""
    H, W = sq.shape
    out = []
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            rr, cc = r + dr, c + dc
            if tile[1]:
                rr %= H
            if tile[0]:
                cc %= W
            if 0 <= rr < H and 0 <= cc < W:
                out.append(sq[rr, cc])
    return out


def stored_ratio(g, bits, max_ratio):
    """The ratio the shader decodes from G (exactly)."""
    n = {8: 255, 16: 65535, 32: 1}[bits]
    return (Fraction(float(g)) / n) ** 2 * Fraction(float(max_ratio))


@examples(0.5)
@given(tie_fields(5), st.sampled_from(TILINGS), st.sampled_from([1.0, 0.3]), st.sampled_from([8, 16, 32]),
       st.booleans(), st.sampled_from(["conservative", "relaxed"]))
@example(np.array([[0.0, 0.1] + [0.0] * 14]), (False, False), 1.0, 32, False, "conservative")
# 1/4 over 1 - 0.5's lower neighbour: just under the cap 0.5, which G = 255 stood for before
@example(np.array([[np.nextafter(0.5, 0), 1.0, np.nextafter(0.5, 0), 0.5]]), (False, False), 0.5, 8, False,
         "conservative")
def test_stored_cones_are_never_wider_than_exact(h, tile, max_ratio, bits, safe, cones):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the documented one-step floor
        packed = step_map(h, tile=tile, max_ratio=max_ratio, bits=bits, bilinear_safe=safe, cones=cones)
    exact = exact_cone_squares if cones == "conservative" else relaxed_squares
    sq = exact(h, tile[0], tile[1], max_ratio, levels=height_levels(h))
    one_step = stored_ratio(1, bits, max_ratio) if bits < 32 else 0
    for (r, c), g in np.ndenumerate(packed[..., 1]):
        limit = min(neighbourhood(sq, r, c, tile)) if safe else sq[r, c]
        got = stored_ratio(g, bits, max_ratio)
        if got == one_step and limit < one_step ** 2:
            continue  # narrower than one step: stored as one step (it warns)
        assert got ** 2 <= limit, f"texel {(r, c)}: stored {float(got)}, exact {float(limit) ** 0.5}"
