"""Decompression bombs made by hand (zlib and struct): small files declaring huge images.

``png_bomb`` and ``tiff_bomb`` hold the real compressed zeros of a ``side`` x ``side`` grey
image (30000² in under 1 MB); ``gif_bomb`` declares ``side`` x ``side`` in its logical screen
and image descriptor with a short LZW stream (a decoder allocates before it finds out).
Files are cached per session by the caller's tmp_path_factory.
"""

from __future__ import annotations

import struct
import zlib


def _zeros_deflated(rows: int, row_bytes: int) -> bytes:
    co = zlib.compressobj(9)
    block = bytes(row_bytes) * 1000
    parts = [co.compress(block) for _ in range(rows // 1000)]
    parts.append(co.compress(bytes(row_bytes) * (rows % 1000)))
    return b"".join(parts) + co.flush()


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_bomb(path, side: int = 30000):
    """An 8-bit grey PNG of side x side zeros (filter byte 0 on each row)."""
    idat = _zeros_deflated(side, side + 1)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0))
                     + _png_chunk(b"IDAT", idat) + _png_chunk(b"IEND", b""))
    return path


def tiff_bomb(path, side: int = 30000):
    """A little-endian 8-bit grey TIFF of side x side zeros in one Deflate strip."""
    strip = _zeros_deflated(side, side)
    entries = [(256, 4, side), (257, 4, side), (258, 3, 8), (259, 3, 8), (262, 3, 1),
               (273, 4, 0), (277, 3, 1), (278, 4, side), (279, 4, len(strip))]
    ifd_at = 8
    data_at = ifd_at + 2 + 12 * len(entries) + 4
    ifd = struct.pack("<H", len(entries))
    for tag, kind, value in entries:
        value = data_at if tag == 273 else value
        packed = struct.pack("<H", value) + b"\0\0" if kind == 3 else struct.pack("<I", value)
        ifd += struct.pack("<HHI", tag, kind, 1) + packed
    path.write_bytes(b"II*\0" + struct.pack("<I", ifd_at) + ifd + b"\0\0\0\0" + strip)
    return path


def gif_bomb(path, side: int = 30000):
    """A GIF89a declaring side x side (screen and frame) with a two-colour palette."""
    screen = struct.pack("<HHBBB", side, side, 0x80, 0, 0) + b"\0\0\0\xff\xff\xff"
    frame = b"\x2c" + struct.pack("<HHHHB", 0, 0, side, side, 0)
    lzw = b"\x02\x02\x44\x01\x00"  # min code size 2, one sub-block: clear, 0, end
    path.write_bytes(b"GIF89a" + screen + frame + lzw + b"\x3b")
    return path
