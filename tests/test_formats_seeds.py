"""The seeds' heightfield formats: Rayshade .hf, z-buffer .txt/.etxt, POV-Ray .gif, Fractint .pot.

Fixture files come from tests/seed_files.py, written independently of csm_assets (struct, text,
Pillow), from the seeds' descriptions, so the readers are checked against the
formats and not against our own writers.
"""

from __future__ import annotations

import struct
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from PIL import Image

from csm_assets import FormatError, Heightfield, load_heightfield, save_heightfield
from seed_files import etxt_file, gif_file, hf_file, pot_file, txt_file

SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


# ---- orientation: which corner lands where ----------------------------------------------------

@pytest.mark.parametrize("order", ["<", ">"])
def test_hf_orientation_and_both_byte_orders(tmp_path, order):
    n = 3
    hf = load_heightfield(hf_file(tmp_path / "a.hf", [float(i) for i in range(n * n)], order))
    # the file's value 0 is the lower-left corner (x=0, y=0): bottom-left of the image
    assert hf.data[-1, 0] == 0 and hf.data[-1, -1] == n - 1
    assert hf.data[0, 0] == n * (n - 1) and hf.data[0, -1] == n * n - 1
    assert hf.meta["byteorder"] == order and hf.mask is None and hf.data.dtype == np.float32


def test_txt_orientation_bottom_row_first(tmp_path):
    rows = [[0, 1, 2, 3], [10, 11, 12, 13], [20, 21, 22, 23]]  # file order: bottom row first
    hf = load_heightfield(txt_file(tmp_path / "a.txt", rows))
    assert hf.shape == (3, 4)
    assert hf.data[-1, 0] == 0 and hf.data[-1, -1] == 3 and hf.data[0, 0] == 20 and hf.data[0, -1] == 23


def test_etxt_orientation_any_line_order(tmp_path):
    w, h = 4, 3
    triples = [(x, y, 10 * y + x) for x in range(w) for y in range(h)]  # x fixed in a block, as the seed
    rng = np.random.default_rng(1)
    for name, tr, win in [("a.etxt", triples, (0, 0, w - 1, h - 1)),
                          ("b.etxt", [triples[i] for i in rng.permutation(len(triples))], None)]:
        hf = load_heightfield(etxt_file(tmp_path / name, tr, win))
        assert hf.shape == (h, w)
        assert hf.data[-1, 0] == 0 and hf.data[-1, -1] == 3 and hf.data[0, 0] == 20 and hf.data[0, -1] == 23


def test_etxt_window_offset(tmp_path):
    triples = [(10 + x, 5 + y, 10 * y + x) for x in range(3) for y in range(2)]
    hf = load_heightfield(etxt_file(tmp_path / "w.etxt", triples, (10, 5, 12, 6)))
    assert hf.data.tolist() == [[10, 11, 12], [0, 1, 2]]
    assert hf.meta["window"] == (10, 5, 12, 6)
    save_heightfield(hf, tmp_path / "w2.etxt")
    assert "# window from (10,5) to (12,6)" in (tmp_path / "w2.etxt").read_text()
    assert load_heightfield(tmp_path / "w2.etxt").data.tolist() == hf.data.tolist()


def test_gif_orientation_and_index_not_colour(tmp_path):
    idx = np.array([[0, 1, 2, 3], [100, 101, 102, 103], [252, 253, 254, 255]], np.uint8)
    rng = np.random.default_rng(7)
    shuffled = [tuple(int(c) for c in rng.integers(0, 256, 3)) for _ in range(256)]
    for name, pal in [("grey.gif", None), ("shuffled.gif", shuffled)]:
        hf = load_heightfield(gif_file(tmp_path / name, idx, pal))
        np.testing.assert_array_equal(hf.data, (idx / 255.0).astype(np.float32))  # row 0 on top
    # a reversed grey palette gives the same heights: colour never matters
    rev = [(255 - i,) * 3 for i in range(256)]
    hf = load_heightfield(gif_file(tmp_path / "rev.gif", idx, rev))
    assert hf.data[0, 0] == 0 and hf.data[-1, -1] == 1


def test_pot_orientation_hi_left_lo_right(tmp_path):
    v = np.array([[0x0001, 0x0100, 0x1234], [0xFFFF, 0x8000, 0x00FF]], np.uint16)
    hf = load_heightfield(pot_file(tmp_path / "a.pot", v))
    assert hf.shape == (2, 3)
    np.testing.assert_array_equal(hf.data, (v / 65535.0).astype(np.float32))
    assert hf.data[1, 0] == 1.0 and hf.data[0, 0] == np.float32(1 / 65535)


# ---- holes and backgrounds --------------------------------------------------------------------

def test_hf_holes_keep_raw_altitudes(tmp_path):
    vals = [5.5, -1000.0, 7.25, -2.0, -5000.0, 3.0, float("-inf"), 0.0, -999.5]
    hf = load_heightfield(hf_file(tmp_path / "h.hf", vals, ">"))
    raw = np.array(vals, np.float32).reshape(3, 3)[::-1]
    np.testing.assert_array_equal(hf.mask, raw <= -1000)
    np.testing.assert_array_equal(hf.data[~hf.mask], raw[~(raw <= -1000)])  # not normalized
    assert hf.meta["holes"] == 3


@pytest.mark.parametrize("bg", ["-1", "-1000", "-0.5"])
def test_zbuf_negative_depth_is_background(tmp_path, bg):
    rows = [[bg, "3.75485", "3.60294"], ["3.52262", bg, "0"]]
    for hf in (load_heightfield(txt_file(tmp_path / "z.txt", rows)),
               load_heightfield(etxt_file(tmp_path / "z.etxt",
                                          [(x, y, rows[y][x]) for x in range(3) for y in range(2)]))):
        assert hf.mask.tolist() == [[False, True, False], [True, False, False]]
        assert hf.data[0, 0] == np.float32(3.52262) and hf.data[1, 1] == np.float32(3.75485)
        assert hf.data[0, 2] == 0  # zero is a distance, not background


def test_hf_written_from_depth_keeps_minus_1000_for_background(tmp_path):
    depth = load_heightfield(txt_file(tmp_path / "d.txt", [["-1", "2.5"], ["4", "-1"]]))
    save_heightfield(depth, tmp_path / "d.hf")
    raw = np.frombuffer((tmp_path / "d.hf").read_bytes()[4:], "<f4")
    assert raw.tolist() == [-1000.0, 2.5, 4.0, -1000.0]
    back = load_heightfield(tmp_path / "d.hf")
    np.testing.assert_array_equal(back.mask, depth.mask)


def test_seed_example_etxt(tmp_path):
    """The seed's sample output, with its deleted lines filled in as background."""
    shown = {(12, y): d for y, d in zip(range(16, 22), ["3.75485", "3.60294", "3.52262", "3.46714",
                                                        "3.42647", "3.40308"])}
    triples = [(x, y, shown.get((x, y), "-1")) for x in range(50) for y in range(50)]
    hf = load_heightfield(etxt_file(tmp_path / "planet.etxt", triples, (0, 0, 49, 49)))
    assert hf.shape == (50, 50) and hf.meta["ray_file"] == "../Examples/planet.ray"
    assert hf.mask.sum() == 2500 - 6
    assert hf.data[49 - 16, 12] == np.float32(3.75485) and hf.data[49 - 21, 12] == np.float32(3.40308)


# ---- round trips ------------------------------------------------------------------------------

def _same(a: Heightfield, b: Heightfield):
    ma = np.zeros(a.shape, bool) if a.mask is None else a.mask
    mb = np.zeros(b.shape, bool) if b.mask is None else b.mask
    np.testing.assert_array_equal(ma, mb)
    np.testing.assert_array_equal(a.data[~ma], b.data[~mb])


F32MAX = float(np.finfo(np.float32).max)
finite32 = st.floats(-999.0, F32MAX, width=32)


@SETTINGS
@given(n=st.integers(1, 6), data=st.data(), order=st.sampled_from(["<", ">", "little", "big"]))
def test_hf_round_trip(tmp_path, n, data, order):
    z = data.draw(arrays(np.float32, (n, n), elements=finite32))
    mask = data.draw(arrays(np.bool_, (n, n)))
    hf = Heightfield(np.where(mask, np.float32(-1000), z), mask if mask.any() else None)
    save_heightfield(hf, tmp_path / "r.hf", byteorder=order)
    back = load_heightfield(tmp_path / "r.hf")
    _same(hf, back)
    assert back.meta["byteorder"] == {"little": "<", "big": ">"}.get(order, order)
    before = (tmp_path / "r.hf").read_bytes()
    save_heightfield(back, tmp_path / "r2.hf", byteorder=order)
    assert (tmp_path / "r2.hf").read_bytes() == before  # byte-identical, odd holes included


@SETTINGS
@given(shape=st.tuples(st.integers(1, 5), st.integers(1, 5)), data=st.data(),
       ext=st.sampled_from([".txt", ".etxt"]))
def test_zbuf_round_trip(tmp_path, shape, data, ext):
    d = data.draw(arrays(np.float32, shape, elements=st.floats(0, F32MAX, width=32)))
    mask = data.draw(arrays(np.bool_, shape))
    hf = Heightfield(np.where(mask, np.float32(-1), d), mask if mask.any() else None)
    save_heightfield(hf, tmp_path / f"r{ext}", source="scene.ray")
    back = load_heightfield(tmp_path / f"r{ext}")
    _same(hf, back)
    assert back.meta["ray_file"] == "scene.ray"


@SETTINGS
@given(shape=st.tuples(st.integers(1, 6), st.integers(1, 6)), data=st.data(), pot=st.booleans())
def test_gif_pot_round_trip(tmp_path, shape, data, pot):
    top = 65535 if pot else 255
    v = data.draw(arrays(np.uint16 if pot else np.uint8, shape))
    hf = Heightfield((v / top).astype(np.float32))
    path = tmp_path / ("r.pot" if pot else "r.gif")
    save_heightfield(hf, path)
    back = load_heightfield(path)
    np.testing.assert_array_equal(back.data, hf.data)
    # and the file holds what the seeds describe: indices (and hi/lo halves)
    with Image.open(path) as im:
        idx = np.array(im)
    if pot:
        np.testing.assert_array_equal(idx[:, : shape[1]].astype(int) * 256 + idx[:, shape[1]:], v)
    else:
        np.testing.assert_array_equal(idx, v)


def test_zbuf_header_looks_like_the_seed(tmp_path):
    hf = Heightfield(np.array([[1.5, -1], [2, 3.75485]], np.float32), np.array([[0, 1], [0, 0]], bool))
    save_heightfield(hf, tmp_path / "p.etxt", source="../Examples/planet.ray")
    lines = (tmp_path / "p.etxt").read_text().splitlines()
    assert lines[:4] == ["# Depth Map for Rayshade output file", '# Input RAY file: "../Examples/planet.ray"',
                         "# Resolution for this rendering is 2x2", "# window from (0,0) to (1,1)"]
    assert lines[4:] == ["0 0 2", "0 1 1.5", "", "1 0 3.75485", "1 1 -1", ""]
    save_heightfield(hf, tmp_path / "p.txt", source="../Examples/planet.ray")
    assert (tmp_path / "p.txt").read_text().splitlines()[4:] == ["2 3.75485", "1.5 -1"]


# ---- bad input --------------------------------------------------------------------------------

def _refused(path, *words):
    with pytest.raises(FormatError) as e:
        load_heightfield(path)
    msg = str(e.value)
    assert str(path) in msg
    for w in words:
        assert w in msg, msg
    return msg


@pytest.mark.parametrize("ext", [".hf", ".txt", ".etxt", ".gif", ".pot"])
def test_missing_and_empty_files(tmp_path, ext):
    _refused(tmp_path / f"none{ext}")
    (tmp_path / f"empty{ext}").write_bytes(b"")
    _refused(tmp_path / f"empty{ext}")


@pytest.mark.parametrize("blob,words", [
    (struct.pack("<i", 3) + b"\0" * 32, ["truncated"]),            # 8 of 9 floats
    (struct.pack("<i", 3) + b"\0" * 40, ["oversized"]),            # 10 floats
    (struct.pack("<i", -3) + b"\0" * 36, ["-3"]),                  # negative size
    (struct.pack(">i", -2) + b"\0" * 16, ["-2"]),
    (struct.pack("<i", 0), ["not a size"]),
    (struct.pack("<i", 2**31 - 1) + b"\0" * 16, [str(2**31 - 1)]),  # absurd size, tiny file
    (b"\x01\x02", ["4-byte size"]),
])
def test_hf_bad_sizes(tmp_path, blob, words):
    p = tmp_path / "bad.hf"
    p.write_bytes(blob)
    _refused(p, *words)


def test_hf_forged_header_allocates_nothing(tmp_path):
    p = tmp_path / "forged.hf"
    p.write_bytes(struct.pack("<i", 46340) + b"\0" * 64)  # claims 8.6 GB of altitudes
    tracemalloc.start()
    try:
        with pytest.raises(FormatError):
            load_heightfield(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_hf_nan_and_inf_refused(tmp_path, value):
    _refused(hf_file(tmp_path / "n.hf", [0.0, 1.0, value, 2.0]), "x=0, y=1")


@pytest.mark.parametrize("rows,words", [
    ([["1", "2", "3"], ["4", "5"]], ["line 5", "ragged"]),
    ([["1", "nan"], ["3", "4"]], ["line 4", "NaN"]),
    ([["1", "NaN"], ["3", "4"]], ["NaN"]),
    ([["1", "2"], ["abc", "4"]], ["line 5", "'abc'"]),
    ([["1", "2"], ["1,5", "4"]], ["'1,5'"]),
    ([["1", "2"], ["inf", "4"]], ["'inf'"]),
    ([["1", "1e999"], ["3", "4"]], ["float32 range"]),
    ([["1", "1e100"], ["3", "4"]], ["float32 range"]),
    ([["1", "1_0"], ["3", "4"]], ["'1_0'"]),
])
def test_txt_bad(tmp_path, rows, words):
    _refused(txt_file(tmp_path / "b.txt", rows), *words)


def test_txt_resolution_mismatch_and_comments_only(tmp_path):
    p = tmp_path / "r.txt"
    p.write_text("# Resolution for this rendering is 3x3\n1 2 3\n4 5 6\n")  # a row missing
    _refused(p, "resolution 3x3", "3x2")
    p.write_text("# just a comment\n\n")
    _refused(p, "no depth")
    p.write_bytes(b"1 2\x00\n3 4\n")
    _refused(p, "binary")


@pytest.mark.parametrize("case,words", [
    ("dup", ["duplicate pixel (1,0)"]),
    ("missing", ["missing pixels", "(1,1)"]),
    ("missing_edge", ["missing pixels"]),
    ("outside", ["outside"]),
    ("float_coord", ["integer"]),
    ("two_values", ["x y depth"]),
    ("nan", ["NaN"]),
    ("huge_window", ["window", "over the limit"]),
])
def test_etxt_bad(tmp_path, case, words):
    full = [(x, y, 1.0 + x + y) for x in range(2) for y in range(2)]
    win = (0, 0, 1, 1)
    if case == "dup":
        tr = full + [(1, 0, 5.0)]
    elif case == "missing":
        tr = full[:-1]
    elif case == "missing_edge":  # column x=1 absent: only the header's window can tell
        tr = full[:2]
    elif case == "outside":
        tr = full + [(2, 0, 1.0)]
    elif case == "float_coord":
        tr = [(0, 0, 1), ("0.5", 1, 1)]
    elif case == "two_values":
        tr, win = [(0, 0, 1), (0, "1", "")], None
    elif case == "nan":
        tr = full[:-1] + [(1, 1, "nan")]
    else:  # a forged window must not allocate its grid
        tr, win = full, (0, 0, 99999999, 99999999)
    p = etxt_file(tmp_path / "b.etxt", tr, win)
    if case == "huge_window":  # the Resolution line would already disagree; drop it
        p.write_text("\n".join(l for l in p.read_text().splitlines() if "Resolution" not in l))
    _refused(p, *words)


def test_gif_not_palette_based(tmp_path):
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "rgb.png")
    (tmp_path / "rgb.gif").write_bytes((tmp_path / "rgb.png").read_bytes())  # a PNG named .gif
    _refused(tmp_path / "rgb.gif", "not a GIF", "PNG")
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "rgb.jpg")
    (tmp_path / "rgb.pot").write_bytes((tmp_path / "rgb.jpg").read_bytes())
    _refused(tmp_path / "rgb.pot", "not a GIF")


def test_gif_truncated_and_pot_odd_width(tmp_path):
    good = gif_file(tmp_path / "g.gif", np.arange(64, dtype=np.uint8).reshape(8, 8) * 3).read_bytes()
    (tmp_path / "t.gif").write_bytes(good[: len(good) // 2])
    _refused(tmp_path / "t.gif", "GIF")
    gif_file(tmp_path / "odd.pot", np.zeros((2, 5), np.uint8))
    _refused(tmp_path / "odd.pot", "width 5 is odd")


@pytest.mark.filterwarnings("error")  # no DecompressionBombWarning either: we judge the header
@pytest.mark.parametrize("side,words", [(2000, ["2000x2000", "bytes can encode"]),
                                        (10000, ["10000x10000", "bytes can encode"]),
                                        (65535, ["65535x65535", "over the limit"])])  # the texel limit, before Pillow
def test_gif_header_claiming_more_pixels_than_bytes(tmp_path, side, words):
    good = bytearray(gif_file(tmp_path / "g.gif", np.zeros((2, 2), np.uint8)).read_bytes())
    good[6:10] = struct.pack("<HH", side, side)  # logical screen side x side
    (tmp_path / "big.gif").write_bytes(bytes(good))
    tracemalloc.start()
    try:
        _refused(tmp_path / "big.gif", *words)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


@pytest.mark.parametrize("ext", [".hf", ".txt", ".gif"])
def test_channel_option_refused(tmp_path, ext):
    path = tmp_path / f"c{ext}"
    save_heightfield(Heightfield(np.zeros((2, 2), np.float32)), path)
    with pytest.raises(FormatError, match="channel"):
        load_heightfield(path, channel="R")
    assert load_heightfield(path, channel=0).shape == (2, 2)


# ---- bad output: refused, nothing half-written, nothing clobbered ---------------------------

@pytest.mark.parametrize("name,hf,words", [
    ("n.hf", Heightfield(np.zeros((2, 3))), ["square", "3x2"]),
    ("v.hf", Heightfield(np.array([[0, -1000.0], [1, 2]])), ["-1000"]),
    ("nan.hf", Heightfield(np.array([[0, np.nan], [1, 2]])), ["NaN"]),
    ("neg.txt", Heightfield(np.array([[0, -1.0]])), ["negative"]),
    ("neg.etxt", Heightfield(np.array([[0, np.inf]])), ["infinite"]),
    ("raw.gif", Heightfield(np.array([[0, 2.0]])), ["[0, 1]", "normalized"]),
    ("raw.pot", Heightfield(np.array([[-0.5, 1.0]])), ["[0, 1]"]),
])
def test_writers_refuse_and_leave_files_alone(tmp_path, name, hf, words):
    path = tmp_path / name
    path.write_bytes(b"precious")
    with pytest.raises(FormatError) as e:
        save_heightfield(hf, path)
    for w in words:
        assert w in str(e.value)
    assert path.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no temporary left behind


def test_hf_bad_byteorder_option(tmp_path):
    with pytest.raises(ValueError, match="byteorder"):
        save_heightfield(Heightfield(np.zeros((2, 2))), tmp_path / "x.hf", byteorder="middle")
    assert not list(tmp_path.iterdir())
