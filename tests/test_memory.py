"""Step maps in little memory, with the same bytes as before.

The packing and the cone passes work in bands of rows (:mod:`csm_assets.bands`), share one max
pyramid and free what they are done with; their outputs must stay byte for byte those of the
whole-map code they replaced (commit d64b031): the hashes below are that code's outputs. The
peak memory of ``csm-assets stepmap`` is measured from outside the process (the kernel's count of
the child's resident pages) at 2048 x 2048, against a bound with margin (benchmarks/memory.py
prints the figures; docs/measurements/memory.md).
"""

from __future__ import annotations

import hashlib
import sys
import warnings

import numpy as np
import pytest

import csm_assets.bands
from csm_assets.bench.maps import noise, terrain, tiles
from csm_assets.bench.rss import measure
from csm_assets.formats.image import _write_pixels
from csm_assets.packing import step_maps


def maps() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    return {
        "terrain256": terrain(256), "noise128": noise(128), "tiles128": tiles(128),
        "flat": np.full((40, 50), 77, np.uint8),
        "spike": np.pad(np.array([[255]], np.uint8), ((20, 19), (30, 5))),
        "nonsq": terrain(128)[:77, :123].copy(), "row": noise(64)[:1, :].copy(), "col": noise(64)[:, :1].copy(),
        "t16": terrain(128).astype(np.uint16) * 257 + rng.integers(0, 257, (128, 128)).astype(np.uint16),
        "f32": (terrain(96) / 255.0 + rng.uniform(0, 1e-3, (96, 96))).clip(0, 1).astype(np.float32),
        "one": np.array([[3]], np.uint8),
    }


# sha256 (first 16 hex digits) of each map's packed maps, all three cone kinds at 8, 16 and 32 bits,
# bilinear-safe, max_ratio 0.7, tiled and tiled along y only, as the code before banding made them
BEFORE = {"terrain256": "0a9ce4091a93852c", "noise128": "a6d8a3806528a98c", "tiles128": "9df20c36a6e9fec4",
          "flat": "2d8f046201fc29c6", "spike": "a217b570744db8cb", "nonsq": "a052c97f88cc9432",
          "row": "54f11353c7ee6956", "col": "a1a34751c391b415", "t16": "b3a6c86b80a0daa6",
          "f32": "ebfabf49527ffd6c", "one": "3996243c0d0aa9d3"}
KINDS = ("conservative", "relaxed", "quadrant")


def packed_digest(name: str, a: np.ndarray) -> str:
    """The digest of :data:`BEFORE` for map ``name``, heights ``a``: one cone pass per tiling, packed at each bits."""
    out = {}
    for tile in (True, (False, True)):
        def every_bits(pack):
            for bits in (8, 16, 32):
                for kind in KINDS:
                    out[f"{name}/{tile}/True/{bits}/{kind}"] = pack(bits, kind)
            return 8

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            step_maps(a, tile=tile, bits=every_bits, bilinear_safe=True, cones=KINDS, max_ratio=0.7)
    h = hashlib.sha256()
    for key in sorted(out):
        h.update(key.encode())
        h.update(out[key].tobytes())
    return h.hexdigest()[:16]


@pytest.mark.parametrize("band", [None, 300], ids=["default-bands", "bands-of-300-texels"])
def test_step_maps_are_byte_for_byte_those_of_the_whole_map_code(band, monkeypatch):
    """Terrain, noise, bricks, flat, a spike, non-square, 1xN and Nx1, 16-bit, float and 1x1 maps,
    all cone kinds and bits: the bytes of before; with bands of 300 texels too (a band is then one
    row or a few, so every halo, edge and band seam is crossed)."""
    if band:
        monkeypatch.setattr(csm_assets.bands, "BAND_TEXELS", band)
    got = {name: packed_digest(name, a) for name, a in maps().items()}
    assert got == BEFORE


def peak_rss(args, cwd) -> int:
    """Peak resident bytes of ``python -m csm_assets ARGS`` (:func:`csm_assets.bench.rss.measure`)."""
    return measure([sys.executable, "-m", "csm_assets", *args], cwd=cwd)["peak"]


BOUND = 40  # bytes a texel (the target), the default level chain included: measured at 2048^2 on
# 2026-12-07, chain on (the default): 25.3 (conservative, 8-bit terrain), 33.1 (quadrant, 8-bit), 34.2
# (quadrant, 16-bit); the chain no longer adds to the cones' own peak (quadrant 46.3 before)


def sixteen_bit(n: int) -> np.ndarray:
    """A 16-bit terrain whose low byte is noise, so that ``stepmap`` keeps 16 bits (the heaviest packed map)."""
    rng = np.random.default_rng(5)
    return terrain(n).astype(np.uint16) * 257 + rng.integers(0, 257, (n, n)).astype(np.uint16)


@pytest.mark.slow
@pytest.mark.parametrize("cones, bits", [("conservative", 8), ("quadrant", 8), ("quadrant", 16)])
def test_stepmap_peak_memory_per_texel_at_2048(tmp_path, cones, bits):
    """``csm-assets stepmap`` of a 2048^2 terrain map peaks within :data:`BOUND` bytes a texel above
    the same command on a 64^2 map (the interpreter and its libraries), measured from outside: with
    its default settings (the level chain on) and with ``--levels none`` (the cones and the packing)."""
    make = terrain if bits == 8 else sixteen_bit
    for n in (64, 2048):
        _write_pixels(make(n)[:, :, None], tmp_path / f"t{n}.png")
    for kind in (["--cones", cones], ["--cones", cones, "--levels", "none"]):
        peak_rss(["stepmap", "t64.png", "-o", "warm.png", "-q", *kind], tmp_path)  # kernels compiled, if need be
        base = peak_rss(["stepmap", "t64.png", "-o", "small.png", "-q", *kind], tmp_path)
        peak = peak_rss(["stepmap", "t2048.png", "-o", "big.png", "-q", *kind], tmp_path)
        per_texel = (peak - base) / 2048 ** 2
        assert 0 < per_texel <= BOUND, f"{kind}: {per_texel:.1f} bytes a texel (base {base / 1e6:.0f} MB, " \
                                       f"peak {peak / 1e6:.0f} MB)"
