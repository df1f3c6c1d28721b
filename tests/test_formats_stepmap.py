"""Seed formats into step maps: Heightfield.normalized (holes, raw altitudes),
POV-Ray's waterlevel, and ``csm-assets stepmap`` on .hf, .txt, .pot and .gif inputs."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from csm_assets import Heightfield, load_heightfield, read_step_map
from csm_assets.cli import EXIT_INPUT, EXIT_OK, EXIT_USAGE, main
from csm_assets.formats import read_step_map_meta
from seed_files import gif_file, hf_file, pot_file, txt_file


# ---- normalization for step maps, waterlevel ---------------------------------------------------

def test_normalized_over_valid_texels_holes_lowest(tmp_path):
    vals = [10.0, 30.0, -1000.0, 20.0]  # bottom row 10 30, top row hole 20
    hf = load_heightfield(hf_file(tmp_path / "n.hf", vals))
    n = hf.normalized()
    assert n.data.tolist() == [[0.0, 0.5], [0.0, 1.0]]
    assert n.meta["height_scale"] == 20.0 and n.meta["height_offset"] == 10.0
    valid = ~n.mask
    np.testing.assert_allclose(n.meta["height_offset"] + n.meta["height_scale"] * n.data[valid], hf.data[valid])
    again = n.normalized()
    np.testing.assert_array_equal(again.data, n.data)
    assert (again.meta["height_scale"], again.meta["height_offset"]) == (20.0, 10.0)
    assert hf.data[0, 0] == -1000  # the original is untouched


def test_normalized_keeps_unit_data_and_edge_cases():
    a = np.array([[0.25, 0.5], [0.75, 1.0]], np.float32)
    n = Heightfield(a).normalized()
    np.testing.assert_array_equal(n.data, a)
    assert (n.meta["height_scale"], n.meta["height_offset"]) == (1.0, 0.0)
    flat = Heightfield(np.full((2, 2), 5.0)).normalized()
    assert flat.data.tolist() == [[0, 0], [0, 0]] and flat.meta["height_offset"] == 5.0
    holes = Heightfield(np.full((2, 2), -1000.0), np.ones((2, 2), bool)).normalized()
    assert holes.data.tolist() == [[0, 0], [0, 0]]
    with pytest.raises(ValueError, match="NaN"):
        Heightfield(np.array([[np.nan, 1.0]])).normalized()


def test_waterlevel(tmp_path):
    idx = np.array([[0, 64, 128], [192, 255, 10]], np.uint8)
    p = gif_file(tmp_path / "w.gif", idx)
    hf = load_heightfield(p, waterlevel=0.5)
    expect = np.maximum(idx / 255.0, 0.5).astype(np.float32)
    np.testing.assert_array_equal(hf.data, expect)
    assert hf.meta["waterlevel"] == 0.5
    np.testing.assert_array_equal(load_heightfield(p, waterlevel=0).data, (idx / 255.0).astype(np.float32))
    inv = load_heightfield(p, invert=True, waterlevel=0.25)  # depth -> height first, then the water
    np.testing.assert_allclose(inv.data, np.maximum(1 - idx / 255.0, 0.25), atol=1e-7)
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="waterlevel"):
            load_heightfield(p, waterlevel=bad)


def test_waterlevel_on_raw_hf_and_invert_keeps_holes_lowest(tmp_path):
    p = hf_file(tmp_path / "w.hf", [0.0, 100.0, -1000.0, 50.0])
    hf = load_heightfield(p, waterlevel=0.6)
    w = float(np.float32(0.6))
    assert hf.data.tolist() == [[w, w], [w, 1.0]]
    inv = load_heightfield(p, invert=True)
    assert inv.data.tolist() == [[0.0, 0.5], [1.0, 0.0]]  # hole stays 0
    valid = ~inv.mask  # raw = offset + scale * h still holds, with a negative scale
    raw = load_heightfield(p).data
    np.testing.assert_allclose(inv.meta["height_offset"] + inv.meta["height_scale"] * inv.data[valid], raw[valid])


# ---- the CLI ---------------------------------------------------------------------------------

def _stepmap(tmp_path, src, *extra):
    out = tmp_path / (src.stem + "_csm.png")
    code = main(["stepmap", str(src), "-o", str(out), "-q", *extra])
    return code, out


def test_cli_stepmap_from_hf_with_holes(tmp_path):
    rng = np.random.default_rng(3)
    vals = (rng.random(36) * 40 + 100).astype(np.float32)
    vals[[0, 7, 20]] = -1000.0
    src = hf_file(tmp_path / "holes.hf", vals.tolist(), ">")
    code, out = _stepmap(tmp_path, src, "--bits", "16")
    assert code == EXIT_OK
    packed = read_step_map(out)
    meta = read_step_map_meta(out)
    valid = np.delete(vals, [0, 7, 20])
    assert meta["height_offset"] == pytest.approx(valid.min())
    assert meta["height_scale"] == pytest.approx(valid.max() - valid.min())
    r = packed[..., 0].reshape(-1)
    hole_pos = [(5 - i // 6) * 6 + i % 6 for i in (0, 7, 20)]  # file index -> image order
    assert (r[hole_pos] == 0).all() and r.max() == 65535
    raw = meta["height_offset"] + meta["height_scale"] * packed[..., 0] / 65535.0
    expect = np.array(vals, np.float64).reshape(6, 6)[::-1]
    ok = expect > -1000
    np.testing.assert_allclose(raw[ok], expect[ok], atol=meta["height_scale"] / 65535)


def test_cli_stepmap_from_pot_and_gif(tmp_path):
    v = (np.arange(30, dtype=np.uint16).reshape(5, 6) * 2000)
    code, out = _stepmap(tmp_path, pot_file(tmp_path / "f.pot", v), "--bits", "16")
    assert code == EXIT_OK
    np.testing.assert_array_equal(read_step_map(out)[..., 0], v)
    assert read_step_map_meta(out)["height_scale"] == 1.0
    idx = np.array([[3, 200, 7], [90, 0, 255]], np.uint8)
    rng = np.random.default_rng(5)
    pal = [tuple(int(c) for c in rng.integers(0, 256, 3)) for _ in range(256)]
    code, out = _stepmap(tmp_path, gif_file(tmp_path / "g.gif", idx, pal), "--waterlevel", str(100 / 255))
    assert code == EXIT_OK
    np.testing.assert_array_equal(read_step_map(out)[..., 0], np.maximum(idx, 100))


def test_cli_stepmap_from_zbuf_txt_with_invert(tmp_path):
    src = txt_file(tmp_path / "z.txt", [["-1", "4", "2"], ["3", "-1000", "2"]])
    code, out = _stepmap(tmp_path, src, "--invert")
    assert code == EXIT_OK
    r = read_step_map(out)[..., 0]
    assert r.tolist() == [[128, 0, 255], [0, 0, 255]]  # near (2) is high, far (4) low, background 0


def test_cli_bad_inputs(tmp_path, capsys):
    (tmp_path / "bad.hf").write_bytes(struct.pack("<i", 1000) + b"\0" * 8)
    code, out = _stepmap(tmp_path, tmp_path / "bad.hf")
    assert code == EXIT_INPUT and not out.exists()
    assert "bad.hf" in capsys.readouterr().err
    gif_file(tmp_path / "g.gif", np.zeros((2, 2), np.uint8))
    for w in ("1.5", "-1", "x"):
        code, _ = _stepmap(tmp_path, tmp_path / "g.gif", "--waterlevel", w)
        assert code == EXIT_USAGE
