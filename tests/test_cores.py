"""A step map is the same bytes whatever the thread count.

The cone searches, the packing bands (:mod:`csm_assets.pack_bands`), the bits choice's views
(:func:`csm_assets.verify.march.quad_error`) and the distinct heights of the levels method run on
``numba.get_num_threads()`` threads; the order in which threads finish must never show in the
output. Speed-ups are measured by ``benchmarks/cores.py`` (docs/measurements/speed.md), not here.
"""

from __future__ import annotations

import os
import warnings

import numba
import numpy as np
import pytest

import csm_assets.bands
from attack import assert_clean_run, run_cli
from csm_assets.bench.maps import noise, terrain
from csm_assets.cones.levels import distinct_heights
from csm_assets.formats.image import _write_pixels
from csm_assets.packing import step_maps
from csm_assets.verify.march import quad_error

KINDS = ("conservative", "relaxed", "quadrant")
two_threads = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba has one thread here")


def packed_at(threads: int, a: np.ndarray, tile) -> dict:
    """Every kind at 8, 16 and 32 bits (one cone pass), made on ``threads`` numba threads."""
    out = {}

    def every_bits(pack):
        out.update({(bits, kind): pack(bits, kind) for bits in (8, 16, 32) for kind in KINDS})
        return 16

    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            final = step_maps(a, tile=tile, bits=every_bits, bilinear_safe=True, cones=KINDS, max_ratio=0.7)
    finally:
        numba.set_num_threads(before)
    return {**out, **{("final", k): v for k, v in final.items()}}


@two_threads
@pytest.mark.parametrize("tile", [True, (False, True)], ids=["tiled", "tiled-y"])
def test_packed_maps_are_the_same_on_one_thread_and_two(tile, monkeypatch):
    """Terrain (the levels method on two slots) and noise, every kind and bits, bands of 1000
    texels (many bands, each on whichever thread is free): the same arrays."""
    monkeypatch.setattr(csm_assets.bands, "BAND_TEXELS", 1000)
    for a in (terrain(96), noise(64)[:, :50].copy()):
        one, two = packed_at(1, a, tile), packed_at(2, a, tile)
        assert one.keys() == two.keys()
        for key in one:
            np.testing.assert_array_equal(one[key], two[key], err_msg=str(key))


@two_threads
def test_bits_choice_error_is_the_same_on_one_thread_and_two():
    packed = step_maps(terrain(128), bits=8, bilinear_safe=True, cones=("conservative",))["conservative"]
    got = []
    for threads in (1, 2):
        numba.set_num_threads(threads)
        try:
            got.append(quad_error(packed, 0.1, rays=24))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert got[0] == got[1] > 0


def test_distinct_heights_are_numpys_unique():
    rng = np.random.default_rng(4)
    for levels in (1, 2, 255, 4096, 5000):  # past 4096: np.unique itself
        h = rng.integers(0, levels, (37, 53)) / max(levels - 1, 1)
        np.testing.assert_array_equal(distinct_heights(h), np.unique(h))
    np.testing.assert_array_equal(distinct_heights(terrain(64) / 255.0), np.unique(terrain(64) / 255.0))


@pytest.mark.parametrize("cones", KINDS)
def test_stepmap_writes_the_same_bytes_with_one_thread_and_two(tmp_path, cones):
    """The command, bits chosen, written and read back: the files of ``NUMBA_NUM_THREADS=1`` and
    ``=2`` are equal byte for byte (numba runs two threads even on one core)."""
    _write_pixels(terrain(400)[:, :200, None].copy(), tmp_path / "t.png")  # 80000 texels: two bands
    files = {}
    for threads in (1, 2):
        out = tmp_path / str(threads)
        out.mkdir()
        r = run_cli("stepmap", tmp_path / "t.png", "-o", out / "t_csm.png", "--cones", cones,
                    env={**os.environ, "NUMBA_NUM_THREADS": str(threads)})
        assert_clean_run(r)
        files[threads] = {f.name: f.read_bytes() for f in sorted(out.iterdir())}
    assert files[1].keys() == files[2].keys() and files[1] == files[2]
