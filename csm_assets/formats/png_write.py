"""PNG files whose one zlib stream is compressed on every core, as pigz compresses gzip.

libpng (through OpenImageIO) deflates a PNG on one thread; a 4096² 16-bit step map takes it
about 4 s, which the other cores of a run sit out. Here the filtered rows are cut into bands of
about :data:`BAND_BYTES` bytes (256 KiB), each deflated on its own (primed with the last 32 KiB of the
band before it, as a dictionary, so nothing is lost at the cuts) on
:func:`~csm_assets.polling.thread_count` threads, and joined in order into one zlib stream. The
bands do not depend on the thread count: one thread and many write the same file. Bands are
written as they are done, in order: a write holds a few bands a thread, not the file.

The pixels are PNG's as the specification stores them (samples big-endian, rows filtered by
:func:`~.png_filter.filter_rows`: libpng's default choice); the file holds IHDR, the description
as a ``Description`` text chunk (which OpenImageIO reads as ``ImageDescription``), IDAT chunks and
IEND. Readers see the same pixels as in libpng's file; the bytes differ (about the same size).
"""

from __future__ import annotations

import collections
import functools
import itertools
import struct
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..bands import bands
from ..polling import thread_count
from .png_filter import filter_rows

BAND_BYTES = 1 << 18  # filtered bytes deflated as one piece (fixed: the file is the same on any core count)
WINDOW = 1 << 15  # deflate's window: the dictionary each band is primed with
LEVEL = 6  # zlib's default, and libpng's
SIGNATURE = b"\x89PNG\r\n\x1a\n"
COLOUR_TYPES = {1: 0, 2: 4, 3: 2, 4: 6}  # channels: grey, grey and alpha, RGB, RGBA
ZLIB_HEADER = b"\x78\x9c"  # deflate, 32 KiB window, default level


def write_png(pixels: np.ndarray, path, description: str = "", stop=None, band_bytes: int = BAND_BYTES) -> bool:
    """Write ``pixels`` as a PNG file at ``path`` (not atomically: the caller names a temporary file).

    Args:
        pixels: ``(H, W, C)`` uint8 or uint16, C from 1 (grey) to 4 (RGBA), H and W at least 1.
        path: the file to write (replaced).
        description: text kept in a ``Description`` chunk ('' for none; ASCII as ``tEXt``,
            other text as UTF-8 ``iTXt``).
        stop: called between bands; when it returns true the file is abandoned, unfinished.
        band_bytes: about how many filtered bytes are deflated as one piece (the file depends on it).

    Returns:
        False when ``stop`` abandoned it, else True.

    Raises:
        ValueError: another dtype or channel count, or an empty image.
        OSError: the file cannot be written.
    """
    h, w, c = pixels.shape
    if pixels.dtype not in (np.uint8, np.uint16) or c not in COLOUR_TYPES or h < 1 or w < 1:
        raise ValueError(f"{path}: a PNG holds (H, W, 1 to 4) uint8 or uint16 pixels, not {pixels.shape} "
                         f"{pixels.dtype}")
    bpp = c * pixels.dtype.itemsize
    cuts = list(bands(h, w * bpp + 1, band_bytes))  # each filtered row: w * bpp bytes and its filter's
    with open(path, "wb") as f:
        f.write(SIGNATURE)
        _chunk(f, b"IHDR", struct.pack(">IIBBBBB", w, h, 8 * pixels.dtype.itemsize, COLOUR_TYPES[c], 0, 0, 0))
        if description:
            _chunk(f, *_text(description))
        check = 1  # adler32 of nothing
        for i, piece in enumerate(_deflated(pixels, cuts, bpp, stop)):
            if piece is None:
                return False
            data, adler, size = piece
            check = _adler_join(check, adler, size)
            head = ZLIB_HEADER if i == 0 else b""
            tail = struct.pack(">I", check) if i == len(cuts) - 1 else b""
            _chunk(f, b"IDAT", head + data + tail)
        _chunk(f, b"IEND", b"")
    return True


def _deflated(pixels: np.ndarray, cuts: list, bpp: int, stop):
    """Each band's :func:`_deflate_band`, in order, deflated up to two a thread ahead on
    :func:`~csm_assets.polling.thread_count` threads (one thread or one band: here, in turn); None,
    and no more, once ``stop()`` is true."""
    threads = min(thread_count(), len(cuts))
    bands = (functools.partial(_deflate_band, pixels, y0, y1, bpp, final=i == len(cuts) - 1)
             for i, (y0, y1) in enumerate(cuts))
    if threads == 1:
        for band in bands:
            yield None if stop is not None and stop() else band()
        return
    with ThreadPoolExecutor(threads, "csm-png") as pool:
        ahead = collections.deque(pool.submit(b) for b in itertools.islice(bands, 2 * threads))
        while ahead:
            if stop is not None and stop():
                for f in ahead:
                    f.cancel()
                yield None
                return
            piece = ahead.popleft().result()
            band = next(bands, None)
            if band is not None:
                ahead.append(pool.submit(band))
            yield piece


def _deflate_band(pixels: np.ndarray, y0: int, y1: int, bpp: int, final: bool):
    """Rows ``y0..y1`` filtered and deflated: (raw deflate bytes, adler32 of the filtered bytes,
    their count). Primed with the filtered rows before ``y0`` (up to 32 KiB); ends on a byte
    boundary (a sync flush), or the stream's last block when ``final``."""
    n = pixels.shape[1] * bpp
    prime = min(y0, -(-WINDOW // (n + 1)))  # rows before the band that fill the window
    raw = _raw_rows(pixels, y0 - prime, y1, n)
    above = _raw_rows(pixels, y0 - prime - 1, y0 - prime, n)[0] if y0 > prime else np.zeros(n, np.uint8)
    out = np.empty((len(raw), n + 1), np.uint8)
    filter_rows(raw, above, bpp, out)
    window = out[:prime].reshape(-1)[-WINDOW:].tobytes()
    data = out[prime:].reshape(-1)
    deflater = zlib.compressobj(LEVEL, zlib.DEFLATED, -15, 8, zlib.Z_DEFAULT_STRATEGY,
                                **({"zdict": window} if window else {}))
    packed = deflater.compress(data) + deflater.flush(zlib.Z_FINISH if final else zlib.Z_SYNC_FLUSH)
    return packed, zlib.adler32(data), data.size


def _raw_rows(pixels: np.ndarray, y0: int, y1: int, n: int) -> np.ndarray:
    """Rows ``y0..y1``'s bytes as PNG stores them: ``(y1 - y0, n)`` uint8, a copy (samples big-endian)."""
    rows = pixels[y0:y1]
    rows = rows.astype(">u2") if rows.dtype == np.uint16 else np.ascontiguousarray(rows)
    return rows.view(np.uint8).reshape(y1 - y0, n)


def _adler_join(first: int, second: int, second_size: int) -> int:
    """The adler32 of two byte strings joined, from each one's adler32 and the second's length.

    Adler-32 keeps A = 1 + the sum of the bytes and B = the sum of A after each byte (both mod
    65521): joined, A = A1 + A2 - 1, and each of the second's bytes adds A1 - 1 more to B.
    """
    m = 65521
    a1, b1, a2, b2 = first & 0xFFFF, first >> 16, second & 0xFFFF, second >> 16
    return ((b1 + b2 + second_size * (a1 - 1)) % m) << 16 | (a1 + a2 - 1) % m


def _text(description: str) -> tuple[bytes, bytes]:
    """The chunk that holds ``description``: tEXt for ASCII text, else iTXt (UTF-8)."""
    try:
        text = description.encode("ascii")
    except UnicodeEncodeError:
        return b"iTXt", b"Description\0\0\0\0\0" + description.encode("utf-8")
    return b"tEXt", b"Description\0" + text


def _chunk(f, kind: bytes, data: bytes) -> None:
    """One PNG chunk: length, type, data, CRC of type and data."""
    f.write(struct.pack(">I", len(data)) + kind)
    f.write(data)
    f.write(struct.pack(">I", zlib.crc32(data, zlib.crc32(kind))))
