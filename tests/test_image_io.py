"""Images in and packed maps out through OpenImageIO; inputs written independently by Pillow."""

from __future__ import annotations

import os

import numpy as np
import pytest
from PIL import Image

from csm_assets import (FormatError, Heightfield, load_heightfield, read_step_map, read_step_map_meta,
                        save_heightfield, step_map, write_step_map)


def ramp(shape=(5, 7)):
    """An asymmetric field: distinct values, brightest at the bottom right."""
    return np.arange(shape[0] * shape[1], dtype=np.float64).reshape(shape) / (shape[0] * shape[1] - 1)


@pytest.mark.parametrize("ext, bits", [(".png", 8), (".png", 16), (".tga", 8), (".tif", 8),
                                       (".tif", 16), (".tif", 32), (".exr", 32)])
def test_packed_map_round_trips_bit_exactly(tmp_path, ext, bits):
    h = np.random.default_rng(bits).random((13, 10))
    p = step_map(h, bits=bits)
    p[0, 0, 3] = 0  # zero alpha beside non-zero colour: premultiplication would wipe it
    path = tmp_path / f"map{ext}"
    write_step_map(p, path, {"max_ratio": 1.0, "tile": [True, True]})
    back = read_step_map(path)
    assert back.dtype == p.dtype
    np.testing.assert_array_equal(back, p)
    assert read_step_map_meta(path) == {"max_ratio": 1.0, "tile": [True, True]}


def test_pillow_reads_our_png_unpremultiplied(tmp_path):
    p = step_map(np.random.default_rng(0).random((6, 6)))
    p[..., 3] = 7
    write_step_map(p, tmp_path / "m.png")
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "m.png")), p)


@pytest.mark.parametrize("ext, dtype", [(".png", np.float32), (".tga", np.uint16), (".exr", np.uint8),
                                        (".jpg", np.uint8), (".bmp", np.uint8)])
def test_lossy_or_narrowing_pairs_are_refused(tmp_path, ext, dtype):
    with pytest.raises(ValueError, match=ext):
        write_step_map(np.zeros((2, 2, 4), dtype), tmp_path / f"m{ext}")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("top", [255, 65535])
def test_grey_8_and_16_bit_are_normalized(tmp_path, top):
    h = ramp()
    ints = np.rint(h * top).astype(np.uint8 if top == 255 else np.uint16)
    Image.fromarray(ints).save(tmp_path / "g.png")
    hf = load_heightfield(tmp_path / "g.png")
    assert hf.data.dtype == np.float32 and hf.mask is None
    np.testing.assert_allclose(hf.data, ints / top, atol=1e-7)
    assert hf.data[-1, -1] == 1.0 and hf.data[0, 0] == 0.0  # image order: row 0 on top


def test_colour_uses_luminance_and_channel_picks(tmp_path):
    rgba = np.zeros((3, 4, 4), np.uint8)
    rgba[..., 0], rgba[..., 1], rgba[..., 2], rgba[..., 3] = 255, 0, 0, 51
    Image.fromarray(rgba).save(tmp_path / "c.png")
    assert np.allclose(load_heightfield(tmp_path / "c.png").data, 0.2126)
    assert np.allclose(load_heightfield(tmp_path / "c.png", channel="A").data, 0.2)
    assert np.allclose(load_heightfield(tmp_path / "c.png", channel=3).data, 0.2)
    assert np.allclose(load_heightfield(tmp_path / "c.png", channel="1").data, 0.0)
    with pytest.raises(FormatError, match="no channel 'Z'"):
        load_heightfield(tmp_path / "c.png", channel="Z")
    with pytest.raises(FormatError, match="out of range"):
        load_heightfield(tmp_path / "c.png", channel=4)


def test_invert_turns_depth_into_height(tmp_path):
    Image.fromarray(np.array([[0, 255]], np.uint8)).save(tmp_path / "d.png")
    assert load_heightfield(tmp_path / "d.png", invert=True).data.tolist() == [[1.0, 0.0]]


def test_jpeg_and_tga_read(tmp_path):
    flat = np.full((8, 8), 200, np.uint8)
    Image.fromarray(flat).save(tmp_path / "f.jpg", quality=100)
    Image.fromarray(flat).save(tmp_path / "f.tga")
    assert np.allclose(load_heightfield(tmp_path / "f.jpg").data, 200 / 255, atol=2 / 255)
    assert np.allclose(load_heightfield(tmp_path / "f.tga").data, 200 / 255)


@pytest.mark.parametrize("ext", [".png", ".tif", ".exr", ".tga"])
def test_heightfield_round_trip(tmp_path, ext):
    h = ramp((4, 6)).astype(np.float32)
    save_heightfield(Heightfield(h), tmp_path / f"h{ext}")
    back = load_heightfield(tmp_path / f"h{ext}").data
    step = {".png": 1 / 65535, ".tga": 1 / 255}.get(ext, 0)
    np.testing.assert_allclose(back, h, atol=step / 2 + 1e-7)


def test_float_outside_unit_range_is_rescaled(tmp_path):
    raw = np.array([[-2.0, 0.0], [2.0, 6.0]], np.float32)
    Image.fromarray(raw).save(tmp_path / "r.tif")
    hf = load_heightfield(tmp_path / "r.tif")
    np.testing.assert_allclose(hf.data, [[0, 0.25], [0.5, 1.0]])
    assert (hf.meta["height_scale"], hf.meta["height_offset"]) == (8.0, -2.0)


def test_errors_name_the_file(tmp_path):
    with pytest.raises(FormatError, match="missing.png: no such file"):
        load_heightfield(tmp_path / "missing.png")
    (tmp_path / "junk.png").write_bytes(b"not a png at all")
    with pytest.raises(FormatError, match="junk.png"):
        load_heightfield(tmp_path / "junk.png")
    (tmp_path / "empty.exr").write_bytes(b"")
    with pytest.raises(FormatError, match="empty.exr"):
        load_heightfield(tmp_path / "empty.exr")
    with pytest.raises(FormatError, match="unknown heightfield format '.xyz'"):
        load_heightfield(tmp_path / "a.xyz")
    assert issubclass(FormatError, ValueError)


def test_truncated_png_is_a_format_error(tmp_path):
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (64, 64), np.uint8)).save(tmp_path / "t.png")
    data = (tmp_path / "t.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match="t.png"):
        load_heightfield(tmp_path / "t.png")


def test_failed_write_leaves_old_output_and_no_temporary(tmp_path):
    out = tmp_path / "m.png"
    good = step_map(np.zeros((2, 2)))
    write_step_map(good, out)
    before = out.read_bytes()
    with pytest.raises(ValueError):
        write_step_map(np.zeros((2, 2, 4), np.float32), out)
    assert out.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["m.png"]


@pytest.mark.parametrize("top, dtype", [(255, np.uint8), (65535, np.uint16)])
def test_exact_heights_recover_integer_levels(tmp_path, top, dtype):
    ints = np.random.default_rng(4).integers(0, top + 1, (6, 5)).astype(dtype)
    Image.fromarray(ints).save(tmp_path / "i.png")
    assert load_heightfield(tmp_path / "i.png").exact_heights().tolist() == ints.tolist()
    inv = load_heightfield(tmp_path / "i.png", invert=True).exact_heights()
    assert inv.dtype == dtype and inv.tolist() == (top - ints.astype(np.int64)).tolist()
    off_grid = Heightfield(np.full((2, 2), 0.3, np.float32), meta={"bits": 8})
    assert off_grid.exact_heights().dtype == np.float32
