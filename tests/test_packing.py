"""The packed map: layout, rounding that never widens a cone, and decoding as the shader does."""

from __future__ import annotations

import numpy as np
import pytest

from csm_assets import cone_ratios, step_map, unpack_step_map
from csm_assets.packing import slopes
from reference import brute_cone_ratios

W, H = 64, 48


def analytic(amp=0.2):
    """h(u, v) = 0.5 + amp sin(2 pi u) cos(2 pi v) at texel centres, and its uv gradient."""
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    U, V = np.meshgrid(u, v)
    h = 0.5 + amp * np.sin(2 * np.pi * U) * np.cos(2 * np.pi * V)
    dhdu = amp * 2 * np.pi * np.cos(2 * np.pi * U) * np.cos(2 * np.pi * V)
    dhdv = -amp * 2 * np.pi * np.sin(2 * np.pi * U) * np.sin(2 * np.pi * V)
    return h, dhdu, dhdv


def shader_normal(packed, depth):
    """The paper's main(): t.xy = t.ba - 0.5; t.x *= -depth * texsize; t.y likewise; z = 1."""
    d = unpack_step_map(packed)
    hgt, wid = packed.shape[:2]
    b, a = d["dhdx"], -d["dhdy"]  # t.b - 0.5 and t.a - 0.5
    n = np.stack([-b * depth * wid, -a * depth * hgt, np.ones_like(b)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@pytest.mark.parametrize("bits", [16, 32])
def test_decoded_normal_matches_analytic_surface(bits):
    h, dhdu, dhdv = analytic()
    depth = 0.1
    n = shader_normal(step_map(h, bits=bits), depth)
    # surface z = depth * h over (u, y) with y = 1 - v pointing up the image (OpenGL's t axis)
    want = np.stack([-depth * dhdu, depth * dhdv, np.ones_like(h)], -1)
    want /= np.linalg.norm(want, axis=-1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip((n * want).sum(-1), -1, 1)))
    assert angle.max() < 0.1  # central differences on 64 texels per period


@pytest.mark.parametrize("bits, top", [(8, 255), (16, 65535)])
def test_integer_channels_round_as_documented(bits, top):
    h, _, _ = analytic()
    p = step_map(h, bits=bits, max_ratio=0.5)
    exact = brute_cone_ratios(h, max_ratio=0.5)
    assert p.dtype == (np.uint8 if bits == 8 else np.uint16)
    np.testing.assert_array_equal(p[..., 0], np.rint(h * top))
    g = p[..., 1].astype(np.float64) / top
    assert (g ** 2 * 0.5 <= exact * (1 + 1e-12)).all(), "stored cone wider than exact"
    assert (np.sqrt(exact / 0.5) - g < 1.0 / top + 1e-12).all(), "rounded down by more than a step"
    assert p[..., 1].min() >= 1
    sx, sy = slopes(h, True, True)
    np.testing.assert_array_equal(p[..., 2], np.rint(np.clip(0.5 + sx, 0, 1) * top))
    np.testing.assert_array_equal(p[..., 3], np.rint(np.clip(0.5 - sy, 0, 1) * top))


def test_float_map_is_unrounded_and_never_wider():
    h = np.random.default_rng(3).random((20, 17))
    p = step_map(h, bits=32, tile=False)
    exact = brute_cone_ratios(h, False, False)
    assert p.dtype == np.float32
    g2 = p[..., 1].astype(np.float64) ** 2
    assert (g2 <= exact).all()
    np.testing.assert_allclose(g2, exact, rtol=1e-6)
    np.testing.assert_allclose(unpack_step_map(p)["ratio"], exact, rtol=1e-6)
    np.testing.assert_array_equal(p[..., 0], h.astype(np.float32))


def test_8_bit_ratio_agrees_with_cone_ratios():
    h = np.random.default_rng(5).integers(0, 256, (16, 16), dtype=np.uint8)
    p = step_map(h)
    r = cone_ratios(h).astype(np.float64)
    np.testing.assert_array_equal(p[..., 1], np.maximum(np.floor(np.sqrt(r) * 255 + 1e-9), 1))


def test_slopes_edges_one_sided_or_wrapped():
    h = np.array([[0.0, 0.2, 0.6, 0.7]])
    sx, sy = slopes(h, False, False)
    np.testing.assert_allclose(sx[0], [0.2, 0.3, 0.25, 0.1])  # edges not halved
    assert (sy == 0).all()  # one row: no slope along rows
    sx, _ = slopes(h, True, False)
    np.testing.assert_allclose(sx[0], [(0.2 - 0.7) / 2, 0.3, 0.25, (0.0 - 0.6) / 2])
    col = h.T
    _, sy = slopes(col, False, False)
    np.testing.assert_allclose(sy[:, 0], [0.2, 0.3, 0.25, 0.1])


def test_a_channel_sign_is_reversed():
    h = np.linspace(0, 0.5, 8)[:, None].repeat(3, 1)  # rises down the image
    p = step_map(h, tile=False, bits=32)
    assert (p[..., 3] < 0.5).all() and np.allclose(p[..., 2], 0.5)


def test_one_step_floor_warns_when_it_widens_a_cone():
    h = spike = np.zeros((64, 64))
    spike[0, 0] = 1.0
    with pytest.warns(RuntimeWarning, match="one 8-bit step"):
        p = step_map(h, max_ratio=1e6)
    assert p[..., 1].min() == 1


def test_one_by_one_and_flat():
    p = step_map(np.array([[0.25]]), bits=16)
    assert p.tolist() == [[[round(0.25 * 65535), 65535, 32768, 32768]]]
    p = step_map(np.zeros((3, 5), np.uint8))
    assert (p[..., 1] == 255).all()


@pytest.mark.parametrize("bits", [0, 12, 64, "8"])
def test_bad_bits(bits):
    with pytest.raises(ValueError, match="bits"):
        step_map(np.zeros((2, 2)), bits=bits)


def test_unpack_rejects_wrong_shape():
    with pytest.raises(ValueError, match=r"\(H, W, 4\)"):
        unpack_step_map(np.zeros((4, 4, 3), np.uint8))


def brute_neighbourhood_min(g, tile_x, tile_y):
    H, W = g.shape
    out = np.empty_like(g)
    for r in range(H):
        for c in range(W):
            vals = []
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if tile_y:
                        rr %= H
                    if tile_x:
                        cc %= W
                    if 0 <= rr < H and 0 <= cc < W:
                        vals.append(g[rr, cc])
            out[r, c] = min(vals)
    return out


@pytest.mark.parametrize("tile", [True, False, (True, False), (False, True)])
@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (6, 1), (7, 9)])
@pytest.mark.parametrize("bits", [8, 32])
def test_bilinear_safe_takes_the_neighbourhood_minimum(tile, shape, bits):
    h = np.random.default_rng(sum(shape)).random(shape)
    plain = step_map(h, tile=tile, bits=bits)
    safe = step_map(h, tile=tile, bits=bits, bilinear_safe=True)
    tx, ty = (tile, tile) if isinstance(tile, bool) else tile
    np.testing.assert_array_equal(safe[..., 1], brute_neighbourhood_min(plain[..., 1], tx, ty))
    np.testing.assert_array_equal(safe[..., [0, 2, 3]], plain[..., [0, 2, 3]])
    assert (safe[..., 1] <= plain[..., 1]).all()  # never wider than exact
