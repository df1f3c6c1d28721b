"""ConeCodes: a plane of cone codes kept as its finest codes plus corrections gives exactly
cone_codes' codes at every bit depth kept, whatever order its bands come in."""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest

from csm_assets.cone_codes import ConeCodes, cone_codes


def hard_ratios(shape, max_ratio, seed=0) -> np.ndarray:
    """Ratios at and beside code boundaries of every depth (where a code derived from finer codes
    goes wrong), below one 8-bit step (the one-step floor), at the cap, and random."""
    rng = np.random.default_rng(seed)
    n = shape[0] * shape[1]
    k8 = rng.integers(0, 256, n) / 255.0
    k16 = rng.integers(0, 65536, n) / 65535.0
    picks = [
        (k8 ** 2) * max_ratio,
        (k16 ** 2) * max_ratio,
        np.nextafter((k8 ** 2) * max_ratio, 0),
        np.nextafter((k8 ** 2) * max_ratio, 2),
        np.nextafter((k16 ** 2) * max_ratio, 0),
        rng.uniform(0, 1e-5, n) * max_ratio,
        np.full(n, max_ratio),
        rng.uniform(0, 1, n) * max_ratio,
    ]
    which = rng.integers(0, len(picks), n)
    return np.choose(which, picks).reshape(shape)


@pytest.mark.parametrize("keep", [(8,), (16,), (32,), (8, 16), (8, 32), (16, 32), (8, 16, 32)])
def test_every_depth_kept_gives_cone_codes_exactly(keep):
    max_ratio = 0.7
    ratio = hard_ratios((37, 53), max_ratio)
    plane = ConeCodes(ratio.shape, max_ratio, keep)
    bands = [(r0, min(37, r0 + 5)) for r0 in range(0, 37, 5)]
    threads = [threading.Thread(target=plane.add, args=(r0, ratio[r0:r1])) for r0, r1 in reversed(bands)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    rows = np.array([36, 0, 1, 2, 17, 36, 0])  # halo rows: wrapped and repeated
    for bits in keep:
        want, low = cone_codes(ratio, max_ratio, bits)
        assert plane.low[bits] == low
        got = plane.rows(rows, bits)
        assert got.dtype == {8: np.uint8, 16: np.uint16, 32: np.float32}[bits]
        np.testing.assert_array_equal(got, want[rows].astype(got.dtype))
        np.testing.assert_array_equal(plane.rows(np.arange(37), bits), want.astype(got.dtype))
    assert plane.base.itemsize == (2 if max(keep) == 16 else 4 if max(keep) == 32 else 1)


def test_a_depth_not_kept_is_refused():
    plane = ConeCodes((2, 2), 1.0, (8, 16))
    plane.add(0, np.full((2, 2), 0.5))
    with pytest.raises(ValueError, match="kept for"):
        plane.rows(np.arange(2), 32)
    with pytest.raises(ValueError, match="bits must be"):
        ConeCodes((2, 2), 1.0, (12,))


def test_corrections_are_few_on_real_cones():
    """The finest codes say the coarser ones almost everywhere: corrections are a short list."""
    from csm_assets.bench.maps import terrain
    from csm_assets.cones.exact import exact_ratios
    from csm_assets.heightfield import unit_heights

    ratio = exact_ratios(unit_heights(terrain(128)), True, True, 1.0)
    for keep in itertools.combinations((8, 16, 32), 2):
        plane = ConeCodes(ratio.shape, 1.0, keep)
        plane.add(0, ratio)
        fixed = len(plane._fixes(keep[0])[0])
        assert fixed <= ratio.size // 50, (keep, fixed)
