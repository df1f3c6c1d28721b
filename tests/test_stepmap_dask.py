"""One map's cone search in bands of rows on a Dask cluster (``stepmap --scheduler``, the library's
``executor``): the same bytes as a local run, for every cone kind and search method."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import csm_assets.cones.remote as remote
from csm_assets.bench.maps import noise, terrain
from csm_assets.cli import main
from csm_assets.cones.exact import exact_ratios
from csm_assets.cones.quadrant import quadrant_exact
from csm_assets.cones.remote import remote_ratios
from csm_assets.formats.image import _write_pixels, read_pixels
from csm_assets.heightfield import tile_pair, unit_heights
from csm_assets.packing import step_maps

KINDS = ("conservative", "relaxed", "quadrant")


def every_map(a, tile, executor=None) -> dict:
    """The packed maps of ``a``, every kind at 8, 16 and 32 bits (one cone pass)."""
    out = {}

    def every_bits(pack):
        for bits in (8, 16, 32):
            for kind in KINDS:
                out[bits, kind] = pack(bits, kind)
        return 8

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        step_maps(a, tile=tile, bits=every_bits, bilinear_safe=True, cones=KINDS, max_ratio=0.7, executor=executor)
    return out


def test_bands_on_a_cluster_give_the_local_bytes(dask_cluster, monkeypatch):
    """Terrain, noise, a non-square 16-bit map and a map of few heights, tiled and not, every kind
    and bits: bands of 10 to 14 rows, so many seams."""
    from distributed import Client

    rng = np.random.default_rng(3)
    maps = {"terrain": terrain(96), "noise": noise(64)[:, :50].copy(), "steps": terrain(64) // 64 * 64,
            "t16": (terrain(64)[:45].astype(np.uint16) * 257 + rng.integers(0, 257, (45, 64)).astype(np.uint16))}
    monkeypatch.setattr(remote, "BAND_TEXELS", 700)
    with Client(dask_cluster.scheduler_address) as client:
        executor = client.get_executor()
        for name, a in maps.items():
            for tile in (True, (False, True)):
                here, there = every_map(a, tile), every_map(a, tile, executor)
                assert here.keys() == there.keys()
                for key in here:
                    assert np.array_equal(here[key], there[key]), (name, tile, key)


def test_each_search_method_in_bands_gives_the_whole_map_ratios(dask_cluster):
    """The ring and pyramid searches of bands of rows (and the levels method, whole) on the cluster:
    the float64 ratios of the whole-map search, bit for bit."""
    from distributed import Client

    a = terrain(80)[:, :70].copy()
    h = unit_heights(a)
    with Client(dask_cluster.scheduler_address) as client:
        for method in ("ring", "pyramid", "levels"):
            for tile in (True, (True, False)):
                want = exact_ratios(h, *tile_pair(tile), 0.7, method=method)
                got = np.full(h.shape, np.nan)
                remote_ratios(client.get_executor(), a, "conservative", lambda r0, band: got.__setitem__(
                    slice(r0, r0 + len(band)), band), tile=tile, max_ratio=0.7, method=method, texels=600)
                assert np.array_equal(got, want), (method, tile)
        got = np.full((4,) + h.shape, np.nan)
        remote_ratios(client.get_executor(), a, "quadrant", lambda r0, band: got.__setitem__(
            (slice(None), slice(r0, r0 + band.shape[1])), band), max_ratio=0.7, texels=600)
        assert np.array_equal(got, quadrant_exact(h, True, True, 0.7))


@pytest.mark.parametrize("cones", ["conservative", "quadrant"])
def test_stepmap_scheduler_writes_the_local_files(dask_cluster, tmp_path, cones):
    _write_pixels(terrain(128)[:, :, None], tmp_path / "t.png")
    assert main(["stepmap", str(tmp_path / "t.png"), "-o", str(tmp_path / "here.png"), "--cones", cones, "-q"]) == 0
    assert main(["stepmap", str(tmp_path / "t.png"), "-o", str(tmp_path / "there.png"), "--cones", cones, "-q",
                 "--scheduler", dask_cluster.scheduler_address]) == 0
    suffixes = ("", "_q") if cones == "quadrant" else ("",)
    for s in suffixes:
        here, _, here_text = read_pixels(tmp_path / f"here{s}.png", describe=True)
        there, _, there_text = read_pixels(tmp_path / f"there{s}.png", describe=True)
        assert here.dtype == there.dtype and np.array_equal(here, there)
        assert here_text.replace("here", "there") == there_text


def test_unreachable_scheduler_is_one_clear_line(tmp_path, capsys):
    pytest.importorskip("distributed")
    _write_pixels(terrain(16)[:, :, None], tmp_path / "t.png")
    code = main(["stepmap", str(tmp_path / "t.png"), "-o", str(tmp_path / "o.png"), "-q",
                 "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code != 0 and "tcp://127.0.0.1:9" in err and "Dask scheduler" in err
    assert not (tmp_path / "o.png").exists()
