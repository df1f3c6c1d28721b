"""Rayshade's binary height field (``.hf``), as in the Rayshade User's Guide.

Layout: a 32-bit integer ``size``, then ``size * size`` 32-bit floats; value ``i``
is the altitude at ``x = i % size``, ``y = i // size`` with y up, so the file's
first row is the image's bottom row (the reader flips it into image order).
The byte order is not recorded: the reader tries both and keeps the one whose
``size`` matches the file's length (``4 + 4 * size**2`` bytes), before reading
or allocating anything. Altitudes at or below -1000 are holes (``mask``);
``data`` keeps raw altitudes, holes included, not normalized.
"""

from __future__ import annotations

import os

import numpy as np

from ..atomic import atomic_path
from ..errors import FormatError
from ..heightfield import Heightfield

HOLE = -1000.0  # altitudes <= HOLE are holes
BYTEORDERS = {"<": "<", "little": "<", ">": ">", "big": ">"}


def _size_from_length(length: int) -> int | None:
    """The ``size`` a file of ``length`` bytes holds, or None when none fits."""
    if length < 8 or (length - 4) % 4:
        return None
    n = int(np.sqrt((length - 4) // 4))
    for k in (n - 1, n, n + 1):  # guard against float rounding of the root
        if k > 0 and 4 + 4 * k * k == length:
            return k
    return None


def read(path, *, channel=None) -> Heightfield:
    """Read a ``.hf`` file into raw altitudes in image order (float32 ``(size, size)``).

    ``mask`` is True at holes (altitude <= -1000, -inf included); ``meta`` records
    the byte order found. Raises FormatError for a missing, empty, truncated or
    oversized file, a size that fits neither byte order, NaN or +inf altitudes.
    """
    if channel not in (None, 0, "0"):
        raise FormatError(path, f"a .hf file has one channel, cannot read channel {channel!r}")
    try:
        with open(path, "rb") as f:
            length = os.fstat(f.fileno()).st_size
            head = f.read(4)
            if len(head) < 4:
                raise FormatError(path, f"expected a 4-byte size and altitudes, got a file of {length} bytes")
            le, be = (int.from_bytes(head, o, signed=True) for o in ("little", "big"))
            fits = [o for o, n in (("<", le), (">", be)) if n > 0 and 4 + 4 * n * n == length]
            if not fits:
                raise FormatError(path, _misfit(le, be, length))
            order, size = fits[0], (le if fits[0] == "<" else be)
            raw = f.read(4 * size * size)
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from e
    if len(raw) != 4 * size * size:  # the file changed while we read it
        raise FormatError(path, f"expected {4 * size * size} bytes of altitudes, read {len(raw)}")
    z = np.frombuffer(raw, dtype=f"{order}f4").reshape(size, size)[::-1].astype(np.float32)
    bad = np.isnan(z) | (z == np.inf)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise FormatError(path, f"altitude {z[r, c]} at x={c}, y={size - 1 - r} (NaN and +inf are not altitudes)")
    mask = z <= HOLE
    meta = {"source": str(path), "format": "rayshade-hf", "byteorder": order, "holes": int(mask.sum())}
    return Heightfield(z, mask if mask.any() else None, meta)


def _misfit(le: int, be: int, length: int) -> str:
    fit = _size_from_length(length)
    hint = (f"a file of {length} bytes holds size {fit}" if fit is not None
            else f"{length} bytes is not 4 + 4 * size**2 for any size")
    def reads(n, order):
        return f"{n} ({order}, " + (f"needs {4 + 4 * n * n} bytes)" if n > 0 else "not a size)")
    return (f"size field reads {reads(le, 'little-endian')} or {reads(be, 'big-endian')}, "
            f"but {hint}: truncated, oversized or not a .hf file")


def write(hf: Heightfield, path, *, byteorder="<") -> None:
    """Write a square field as ``.hf``, bottom row first, atomically.

    byteorder: ``'<'``/``'little'`` (default) or ``'>'``/``'big'``.
    Holes (``mask``) are written as their own altitude when it is <= -1000 (so a
    file read and written back is byte-identical), else as -1000. Raises
    FormatError for a field that is not square, valid altitudes at or below -1000
    (they would become holes) or NaN/infinite valid altitudes.
    """
    order = BYTEORDERS.get(byteorder)
    if order is None:
        raise ValueError(f"byteorder must be '<', '>', 'little' or 'big', got {byteorder!r}")
    z = np.asarray(hf.data, dtype=np.float32)
    h, w = z.shape
    if h != w:
        raise FormatError(path, f".hf fields are square (size x size), got {w}x{h}; pad with holes (-1000) first")
    holes = np.zeros(z.shape, bool) if hf.mask is None else np.asarray(hf.mask, bool)
    valid = z[~holes]
    if not np.isfinite(valid).all():
        raise FormatError(path, "cannot write NaN or infinite altitudes outside the holes")
    if valid.size and valid.min() <= HOLE:
        raise FormatError(path, f"valid altitude {valid.min():g} is at or below -1000 and would read back as a hole")
    z = np.where(holes & ~(z <= HOLE), np.float32(HOLE), z)
    body = np.ascontiguousarray(z[::-1], dtype=f"{order}f4").tobytes()
    head = int(h).to_bytes(4, "little" if order == "<" else "big", signed=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(head + body)
