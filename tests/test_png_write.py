"""PNGs deflated in parallel bands (csm_assets.formats.png_write): its row filters against the
specification's formulas, written one byte at a time; the files decoded by libpng (OpenImageIO)
and by Pillow; the same file on one thread as on two; the bands' checksum joined as zlib's."""

from __future__ import annotations

import struct
import zlib

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from csm_assets.formats import image, png_write
from csm_assets.formats.png_filter import filter_rows


def paeth(a: int, b: int, c: int) -> int:
    """The Paeth predictor (specification section 9.4) of left ``a``, above ``b``, upper left ``c``."""
    p = a + b - c
    if abs(p - a) <= abs(p - b) and abs(p - a) <= abs(p - c):
        return a
    return b if abs(p - b) <= abs(p - c) else c


def reference_filter(raw: np.ndarray, bpp: int) -> np.ndarray:
    """PNG's five filters of each row (specification section 9.2), byte by byte in Python, and
    the one whose bytes read as signed have the least sum of magnitudes (the first of equals)."""
    rows, n = raw.shape
    out = np.zeros((rows, n + 1), np.uint8)
    for y in range(rows):
        cands = []
        for kind in range(5):
            row = []
            for i in range(n):
                x = int(raw[y, i])
                a = int(raw[y, i - bpp]) if i >= bpp else 0
                b = int(raw[y - 1, i]) if y else 0
                c = int(raw[y - 1, i - bpp]) if y and i >= bpp else 0
                pred = [0, a, b, (a + b) // 2, paeth(a, b, c)][kind]
                row.append((x - pred) % 256)
            cands.append((sum(min(v, 256 - v) for v in row), kind, row))
        _, kind, row = min(cands, key=lambda t: (t[0], t[1]))
        out[y] = [kind, *row]
    return out


def unfilter(filtered: np.ndarray, bpp: int) -> np.ndarray:
    """The rows a decoder rebuilds from PNG-filtered rows (section 9.2, in reverse)."""
    rows, n1 = filtered.shape
    raw = np.zeros((rows, n1 - 1), np.int64)
    for y in range(rows):
        kind = filtered[y, 0]
        for i in range(n1 - 1):
            a = raw[y, i - bpp] if i >= bpp else 0
            b = raw[y - 1, i] if y else 0
            c = raw[y - 1, i - bpp] if y and i >= bpp else 0
            raw[y, i] = (int(filtered[y, i + 1]) + [0, a, b, (a + b) // 2, paeth(a, b, c)][kind]) % 256
    return raw.astype(np.uint8)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 6), st.integers(1, 9), st.sampled_from([1, 2, 3, 4, 6, 8]), st.integers(0, 2**32 - 1),
       st.sampled_from(["random", "smooth", "flat"]))
def test_filter_rows_is_the_specification_and_its_choice(rows, pixels, bpp, seed, kind):
    rng = np.random.default_rng(seed)
    if kind == "random":
        raw = rng.integers(0, 256, (rows, pixels * bpp), dtype=np.uint8)
    elif kind == "smooth":  # where Sub, Up, Average and Paeth win
        raw = (np.add.outer(np.arange(rows) * 3, np.arange(pixels * bpp) // bpp * 5) % 256).astype(np.uint8)
    else:
        raw = np.full((rows, pixels * bpp), 200, np.uint8)
    out = np.empty((rows, pixels * bpp + 1), np.uint8)
    filter_rows(raw, np.zeros(pixels * bpp, np.uint8), bpp, out)
    np.testing.assert_array_equal(out, reference_filter(raw, bpp))
    np.testing.assert_array_equal(unfilter(out, bpp), raw)


def test_every_filter_is_chosen_somewhere():
    rng = np.random.default_rng(5)
    kinds = set()
    for _ in range(40):
        steps = np.cumsum(rng.integers(0, 3, (4, 24)), axis=int(rng.integers(0, 2)))
        raw = (steps * rng.integers(1, 9)).astype(np.uint8)
        if rng.random() < 0.3:
            raw = rng.integers(0, 256, raw.shape, dtype=np.uint8)
        out = np.empty((4, 25), np.uint8)
        filter_rows(raw, np.zeros(24, np.uint8), 3, out)
        np.testing.assert_array_equal(unfilter(out, 3), raw)
        kinds |= set(out[:, 0].tolist())
    assert kinds == {0, 1, 2, 3, 4}


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.binary(max_size=300), st.integers(0, 3))
def test_adler_join_is_zlibs_adler_of_the_joined_bytes(first, second, repeat):
    second = second * (1 + 300 * repeat)  # past 65521 bytes too
    assert png_write._adler_join(zlib.adler32(first), zlib.adler32(second), len(second)) == \
        zlib.adler32(first + second)


def pixels_of(shape, dtype, seed=0):
    """Pixels with smooth parts (filters other than None win) and noise."""
    rng = np.random.default_rng(seed)
    top = np.iinfo(dtype).max
    h, w, c = shape
    ramp = (np.add.outer(np.arange(h), np.arange(w))[:, :, None] * (top // (h + w + 1)) + np.arange(c) * 7)
    noise = rng.integers(0, top + 1, shape)
    return np.where(rng.random(shape) < 0.3, noise, ramp % (top + 1)).astype(dtype)


SHAPES = [(1, 1), (1, 17), (23, 1), (9, 14), (64, 33)]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("band_bytes", [1, 200, png_write.BAND_BYTES])
def test_libpng_and_pillow_decode_the_pixels_written(tmp_path, dtype, channels, band_bytes):
    for k, (h, w) in enumerate(SHAPES):
        px = pixels_of((h, w, channels), dtype, seed=k)
        path = tmp_path / f"m{k}.png"
        assert png_write.write_png(px, path, '{"csm": {"bits": 16}}', band_bytes=band_bytes)
        back, _, text = image.read_pixels(path, describe=True)  # libpng, alpha unassociated
        assert back.dtype == dtype and text == '{"csm": {"bits": 16}}'
        np.testing.assert_array_equal(back, px)
        with Image.open(path) as im:
            assert im.info["Description"] == '{"csm": {"bits": 16}}'
            if dtype == np.uint8 or channels == 1:  # Pillow narrows 16-bit colour to 8 bits
                got = np.asarray(im).reshape(h, w, channels)
                np.testing.assert_array_equal(got.astype(np.int64), px.astype(np.int64))


def test_the_stream_is_one_valid_zlib_stream_across_many_bands(tmp_path):
    px = pixels_of((40, 30, 4), np.uint16)
    path = tmp_path / "m.png"
    png_write.write_png(px, path, band_bytes=300)  # 40 bands, each primed with the one before
    data = path.read_bytes()
    chunks, at = [], 8
    while at < len(data):
        size, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + size]
        assert struct.unpack(">I", data[at + 8 + size:at + 12 + size])[0] == zlib.crc32(kind + body)
        chunks.append((kind, body))
        at += 12 + size
    kinds = [k for k, _ in chunks]
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND" and kinds.count(b"IDAT") == 40
    stream = zlib.decompressobj()
    filtered = stream.decompress(b"".join(b for k, b in chunks if k == b"IDAT"))
    assert stream.eof and not stream.unused_data  # adler32 checked by zlib, nothing after it
    raw = unfilter(np.frombuffer(filtered, np.uint8).reshape(40, 30 * 8 + 1), 8)
    np.testing.assert_array_equal(raw.view(">u2").reshape(px.shape), px)


def test_a_description_that_is_not_ascii_is_kept(tmp_path):
    text = '{"csm": {"source": "höhe_地形.png"}}'
    png_write.write_png(pixels_of((3, 4, 4), np.uint8), tmp_path / "m.png", text)
    assert image.read_description(tmp_path / "m.png") == text


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_one_thread_and_two_write_the_same_file(tmp_path):
    px = pixels_of((300, 200, 4), np.uint16)
    files = []
    for threads in (1, 2):
        numba.set_num_threads(threads)
        try:
            png_write.write_png(px, tmp_path / f"m{threads}.png", "x", band_bytes=20_000)
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        files.append((tmp_path / f"m{threads}.png").read_bytes())
    assert files[0] == files[1]


@pytest.mark.parametrize("after", [0, 3])
def test_stop_abandons_the_file_unfinished(tmp_path, after):
    path, asked = tmp_path / "m.png", []

    def stop():
        asked.append(1)
        return len(asked) > after

    assert not png_write.write_png(pixels_of((50, 50, 4), np.uint8), path, stop=stop, band_bytes=500)
    assert len(asked) == after + 1 and b"IEND" not in path.read_bytes()


@pytest.mark.parametrize("bad", [np.zeros((2, 2, 4), np.float32), np.zeros((2, 2, 5), np.uint8),
                                 np.zeros((0, 3, 4), np.uint8), np.zeros((2, 2, 4), np.int16)])
def test_what_a_png_cannot_hold_is_refused(tmp_path, bad):
    with pytest.raises(ValueError, match="m.png: a PNG holds"):
        png_write.write_png(bad, tmp_path / "m.png")
