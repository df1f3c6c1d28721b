"""Safety of quadrant cones on adversarial maps: a ray inside the stored cone of its quadrant
stays above the surface while inside the cone (thin walls, spikes, white noise, terraces, a
tiled seam, non-tiled edges; 8-bit and float, with and without the bilinear safety pass)."""

from __future__ import annotations

import numpy as np
import pytest

from csm_assets import step_map, trace_heightfield
from csm_assets.bench.maps import terrain
from reference import brute_quadrant_ratios

SIGNS = ((1, 1), (-1, 1), (-1, -1), (1, -1))


def adversarial(name, shape=(20, 24), seed=4):
    rng = np.random.default_rng(seed)
    h = np.zeros(shape)
    if name == "thin_walls":
        h[:, ::7] = 1.0
        h[::9, :] = 0.8
    elif name == "spikes":
        h[rng.integers(0, shape[0], 9), rng.integers(0, shape[1], 9)] = 1.0
    elif name == "noise":
        h = rng.random(shape)
    elif name == "terraces":
        h = np.floor(terrain(32)[: shape[0], : shape[1]] / 255.0 * 5) / 5
    elif name == "seam_ramp":  # a ramp whose tiled seam drops from 1 to 0
        h = np.tile(np.linspace(0, 1, shape[1]), (shape[0], 1))
    return np.round(h * 255).astype(np.uint8)  # 8-bit input, as real maps are: stored heights are exact


MAPS = ("thin_walls", "spikes", "noise", "terraces", "seam_ramp")


def stored_cones(h, tile, bits, safe):
    p = step_map(h, tile=tile, bits=bits, bilinear_safe=safe, cones="quadrant")
    top = 1.0 if bits == 32 else float(np.iinfo(p.dtype).max)
    heights = p[..., 0].astype(np.float64) / top
    return np.stack([(p[..., k].astype(np.float64) / top) ** 2 for k in (1, 2, 3, 5)]), heights


@pytest.mark.parametrize("name", MAPS)
@pytest.mark.parametrize("tile", [True, False, (True, False)])
@pytest.mark.parametrize("bits, safe", [(8, False), (8, True), (32, False)])
def test_every_texel_of_a_quadrant_lies_under_its_stored_cone(name, tile, bits, safe):
    """The cone above texel p in quadrant k (apex at p's stored height, ratio the stored one)
    holds every texel centre q that a ray going into k can reach, on the torus when tiling."""
    h = adversarial(name)
    cones, hs = stored_cones(h, tile, bits, safe)
    H, W = h.shape
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    for k, (su, sv) in enumerate(SIGNS):
        for r in range(H):
            for c in range(W):
                dx, dy = su * (np.arange(W) - c), sv * (np.arange(H) - r)
                dx, dy = (dx % W if tx else dx), (dy % H if ty else dy)
                reach = (dy[:, None] >= 0) & (dx[None, :] >= 0)
                dist = np.hypot(dx[None, :] / W, dy[:, None] / H)
                ceiling = hs[r, c] + dist / cones[k, r, c]
                tol = 1e-6 if bits == 32 else 1e-12  # float32 heights round k / 255 by < 1e-7
                assert (hs[reach] <= ceiling[reach] + tol).all(), (k, r, c)


def test_the_stored_cones_are_the_exact_ones_rounded_down():
    h = adversarial("noise")
    cones, _ = stored_cones(h, True, 32, False)
    exact = brute_quadrant_ratios(h / 255.0)
    assert (cones <= exact * (1 + 1e-14)).all()
    np.testing.assert_allclose(cones, exact, rtol=1e-6)


@pytest.mark.parametrize("name", MAPS)
@pytest.mark.parametrize("tile", [True, False])
def test_rays_inside_the_cone_stay_above_the_bilinear_surface(name, tile):
    """Rays from texel centres at random heights above the surface, in random directions of each
    quadrant, traced exactly through the bilinear surface (csm_assets.verify.trace): the first hit
    is no nearer than the point where the ray leaves the bilinear-safe cone (8-bit), minus the
    0.25-texel minimum step the shader adds to every step."""
    h = adversarial(name)
    H, W = h.shape
    cones, hs = stored_cones(h, tile, 8, True)
    rng = np.random.default_rng(7)
    n = 400
    rows, cols = rng.integers(0, H, n), rng.integers(0, W, n)
    if not tile:  # keep the cone steps inside the map: start away from the sides
        rows, cols = rng.integers(H // 4, H - H // 4, n), rng.integers(W // 4, W - W // 4, n)
    for k, (su, sv) in enumerate(SIGNS):
        ang = rng.uniform(0, np.pi / 2, n)
        elev = rng.uniform(np.radians(5), np.radians(85), n)
        d = np.stack([su * np.cos(ang) * np.cos(elev), sv * np.sin(ang) * np.cos(elev), -np.sin(elev)], -1)
        z0 = hs[rows, cols] + rng.uniform(0.0, 1.0, n) * (1.0 - hs[rows, cols])
        o = np.stack([(cols + 0.5) / W, (rows + 0.5) / H, z0], -1)
        ratio = cones[k, rows, cols]
        above = z0 - hs[rows, cols]
        iz = np.cos(elev)
        step = above * ratio / (np.sin(elev) * ratio + iz)  # csm_cone_step, along the unit ray
        _, t, hit = trace_heightfield(h, o, d, tile=tile)
        slack = 0.25 / max(H, W)  # the shader's minimum step (bilinear-safe maps)
        inside = hit & (t < step - slack - 1e-9)
        assert not inside.any(), (k, np.flatnonzero(inside)[:5], t[inside][:5], step[inside][:5])


@pytest.mark.parametrize("name", ["noise", "thin_walls", "terraces", "seam_ramp"])
@pytest.mark.parametrize("tile", [True, False])
def test_quadrant_variant_agrees_with_the_exact_tracer(name, tile):
    """The shader's quadrant variant on a quadrant map, with the map's own minimum step, within
    a texel p95 of the exact tracer at every view from straight down to 10 degrees."""
    from conftest import skip_without_gl

    from csm_assets.bench.trade import trade_heights

    skip_without_gl()
    h = adversarial(name, (32, 32))
    rep = trade_heights(h, cones="quadrant", tile=tile, size=48, draws=1)
    (row,) = rep.rows
    assert row.variant == "quadrant" and row.cones == "quadrant"
    assert all(v.p95_error <= 1.0 for v in row.views), [round(v.p95_error, 3) for v in row.views]
    assert row.nonconverged_share == 0.0


@pytest.mark.parametrize("name, size", [("bricks2_disp.jpg", 512), ("toy_box_disp.png", 256)])
@pytest.mark.parametrize("min_step", [None, 1.0])
def test_quadrant_variant_within_a_texel_of_the_tracer_on_real_maps(shared_data, name, size, min_step):
    """The real depth maps of ../shared/data at their own size, as convert makes them (8-bit,
    bilinear-safe), drawn by the quadrant variant at the map's own minimum step and at 1 texel
    (the cheapest the benchmark picks): within a texel p95 of the exact tracer at every view
    from straight down to 10 degrees, at most 0.5% of the pixels on a wrong surface."""
    from conftest import skip_without_gl

    from csm_assets.bench.maps import load_real
    from csm_assets.bench.trade import trade_heights

    skip_without_gl()
    h = load_real(shared_data / name, size)
    kw = {} if min_step is None else {"min_step": min_step}
    (row,) = trade_heights(h, cones="quadrant", size=64, draws=1, **kw).rows
    assert all(v.p95_error <= 1.0 for v in row.views), [round(v.p95_error, 3) for v in row.views]
    assert all(v.wrong_share <= 0.005 for v in row.views), [round(v.wrong_share, 4) for v in row.views]
    assert row.nonconverged_share == 0.0
