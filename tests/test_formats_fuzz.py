"""Fuzzing the seeds' format readers: any bytes give a Heightfield or a FormatError.

Random bytes, random text and mutated valid files (bytes flipped, cut, inserted)
are read through ``load_heightfield``; any other exception is a bug. Cases that
once failed are kept below as explicit regression tests.
"""

from __future__ import annotations

import os
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csm_assets import FormatError, Heightfield, load_heightfield, save_heightfield

EXTS = [".hf", ".txt", ".etxt", ".gif", ".pot"]
# modest by default (shared CPUs); CSM_FUZZ_EXAMPLES=5000 for a longer campaign
N = int(os.environ.get("CSM_FUZZ_EXAMPLES", "40"))
FUZZ = settings(max_examples=N, deadline=None)


def _check(blob: bytes, ext: str):
    """Read ``blob`` as a file of type ``ext``: a sane Heightfield or a FormatError."""
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"f{ext}"
        path.write_bytes(blob)
        try:
            hf = load_heightfield(path)
        except FormatError as e:
            assert str(path) in str(e)
            return None
    assert isinstance(hf, Heightfield) and hf.data.ndim == 2 and hf.data.dtype == np.float32
    assert hf.mask is None or hf.mask.shape == hf.data.shape
    valid = hf.data if hf.mask is None else hf.data[~hf.mask]
    assert np.isfinite(valid).all()
    if ext in (".gif", ".pot"):
        assert 0.0 <= hf.data.min() and hf.data.max() <= 1.0
    return hf


def _valid_files() -> dict[str, bytes]:
    """Small valid files of every format, written by our writers (what mutations start from)."""
    rng = np.random.default_rng(0)
    out = {}
    with tempfile.TemporaryDirectory() as d:
        sq = rng.random((4, 4)).astype(np.float32)
        mask = np.zeros((4, 4), bool)
        mask[0, 1] = True
        fields = {".hf": Heightfield(np.where(mask, -1000, sq * 50), mask),
                  ".txt": Heightfield(np.where(mask, -1, sq * 9), mask),
                  ".etxt": Heightfield(np.where(mask, -1, sq * 9)[:3], mask[:3]),
                  ".gif": Heightfield(rng.integers(0, 256, (5, 3)) / 255.0),
                  ".pot": Heightfield(rng.integers(0, 65536, (3, 4)) / 65535.0)}
        for ext, hf in fields.items():
            save_heightfield(hf, Path(d) / f"v{ext}")
            out[ext] = (Path(d) / f"v{ext}").read_bytes()
    return out


VALID = _valid_files()


@pytest.mark.parametrize("ext", EXTS)
def test_valid_seed_files_read(ext):
    assert _check(VALID[ext], ext) is not None


@FUZZ
@given(blob=st.binary(max_size=300), ext=st.sampled_from(EXTS))
def test_random_bytes(blob, ext):
    _check(blob, ext)


@FUZZ
@given(blob=st.binary(max_size=200), ext=st.sampled_from(EXTS))
def test_random_bytes_behind_a_magic(blob, ext):
    """Past the first check: a GIF signature, or a .hf size that fits the length."""
    if ext in (".gif", ".pot"):
        blob = b"GIF89a" + blob
    elif ext == ".hf":
        n = int(np.sqrt(len(blob) // 4)) or 1
        blob = struct.pack("<i", n) + (blob * (4 * n * n))[: 4 * n * n]
    _check(blob, ext)


@FUZZ
@given(text=st.text(alphabet="0123456789 -+.eE#\n\tnaifx,()", max_size=200),
       ext=st.sampled_from([".txt", ".etxt"]))
def test_random_text(text, ext):
    _check(text.encode(), ext)


@st.composite
def mutated(draw):
    ext = draw(st.sampled_from(EXTS))
    blob = bytearray(VALID[ext])
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "set", "cut", "insert", "truncate"]))
        i = draw(st.integers(0, max(len(blob) - 1, 0)))
        if kind == "flip" and blob:
            blob[i] ^= 1 << draw(st.integers(0, 7))
        elif kind == "set" and blob:
            blob[i] = draw(st.sampled_from([0, 0xFF, 0x7F, 0x80, ord("-"), ord("n"), ord(" "), ord("\n")]))
        elif kind == "cut":
            del blob[i: i + draw(st.integers(1, 8))]
        elif kind == "insert":
            blob[i:i] = draw(st.binary(min_size=1, max_size=8))
        else:
            del blob[i:]
    return bytes(blob), ext


@settings(max_examples=3 * N, deadline=None)
@given(case=mutated())
def test_mutated_valid_files(case):
    _check(*case)


# ---- cases that once failed (kept as regression tests) -------------------------------------

@pytest.mark.parametrize("text,ext", [("1E100", ".txt"), ("0 0 -1e39", ".etxt")])
def test_regression_depth_beyond_float32(text, ext):
    """Finite as a Python float, infinite as float32: refused, never an inf depth."""
    with pytest.raises(FormatError, match="float32 range"):
        _read(text.encode(), ext)


def test_regression_float32_max_reads_back():
    """float32's largest value prints as 3.4028235e+38, a hair above it as a float64:
    still a finite float32 depth (a round trip once refused it)."""
    assert _read(b"3.4028235e+38 -3.4028235e+38\n", ".txt").data.tolist() == [
        [float(np.finfo(np.float32).max), -float(np.finfo(np.float32).max)]]


def _read(blob: bytes, ext: str):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"f{ext}"
        path.write_bytes(blob)
        return load_heightfield(path)
