"""POV-Ray height field inputs: palette GIF (``.gif``) and Fractint ``.pot``.

GIF: the height of a pixel is its **palette index**, not its colour, divided by
255 (a shuffled palette changes the colours, never the heights). ``.pot``: a GIF
whose rows are twice the field's width; the left half holds the high byte and the
right half the low byte of each 16-bit height, ``(hi * 256 + lo) / 65535``.
Both are images: row 0 is the top row, as Pillow reads it. No holes.
Indices are read with Pillow (OpenImageIO would give colours). POV-Ray's
``waterlevel`` is applied by :func:`csm_assets.load_heightfield`, not here.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from .. import limits
from ..atomic import atomic_path
from ..errors import FormatError
from ..heightfield import Heightfield

MAX_PIXELS_PER_BYTE = 4096  # GIF's LZW strings are at most 4096 long: a cap on honest headers
GIF_MAX_SIDE = 65535


def _pillow():
    try:
        from PIL import Image
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ImportError("reading GIF/POT height fields needs Pillow: pip install Pillow") from e
    return Image


def read_indices(path) -> np.ndarray:
    """The palette indices of frame 0 of a GIF, uint8 ``(H, W)`` in image order.

    Raises FormatError for a missing file, one that is not a GIF, a header that
    claims more pixels than the file could encode, a corrupt or truncated image,
    or one that Pillow does not read as palette-based (mode P, or L for a GIF
    whose palette is the identity grey ramp, where value = index).
    """
    Image = _pillow()
    try:
        size = Path(path).stat().st_size
        with open(path, "rb") as f:
            head = f.read(10)
        magic = head[:6]
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from e
    if magic not in (b"GIF87a", b"GIF89a"):
        kind = "a PNG" if magic.startswith(b"\x89PNG") else f"starts with {magic!r}"
        raise FormatError(path, f"not a GIF (expected GIF87a/GIF89a, {kind}); POV-Ray heights are palette indices")
    if len(head) == 10:  # the logical screen's size, before Pillow allocates anything
        screen_w, screen_h = struct.unpack("<HH", head[6:10])
        if screen_w * screen_h:
            limits.check(path, "TEXELS", screen_w * screen_h, f"a {screen_w}x{screen_h}-pixel GIF")
    try:
        with warnings.catch_warnings():  # the size check below judges big headers itself
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(path, formats=["GIF"])
        with im:
            w, h = im.size
            if w * h == 0:
                raise FormatError(path, f"empty image ({w}x{h})")
            limits.check(path, "TEXELS", w * h, f"a {w}x{h}-pixel GIF")
            if w * h > MAX_PIXELS_PER_BYTE * size:
                raise FormatError(path, f"header claims {w}x{h} pixels, more than {size} bytes can encode")
            im.load()
            if im.mode not in ("P", "L"):
                raise FormatError(path, f"not a palette-based GIF (Pillow reads mode {im.mode}); "
                                        "POV-Ray heights are palette indices")
            idx = np.array(im, dtype=np.uint8)
    except FormatError:
        raise
    except Image.DecompressionBombError as e:
        raise FormatError(path, f"image too large for Pillow ({e})") from e
    except (OSError, ValueError, EOFError, SyntaxError, struct.error, IndexError, KeyError) as e:
        raise FormatError(path, f"corrupt or truncated GIF ({type(e).__name__}: {e})") from e
    if idx.shape != (h, w):
        raise FormatError(path, f"decoded {idx.shape} indices for a {w}x{h} image")
    return idx


def read(path, *, channel=None) -> Heightfield:
    """Read a POV-Ray ``.gif`` (index / 255) or Fractint ``.pot`` ((hi*256+lo) / 65535).

    Returns float32 ``(H, W)`` heights in ``[0, 1]``, image order, no mask. A
    ``.pot`` of odd width raises FormatError, as does any unreadable GIF.
    """
    if channel not in (None, 0, "0"):
        raise FormatError(path, f"GIF/POT heights are palette indices, there is no channel {channel!r}")
    idx = read_indices(path)
    if Path(path).suffix.lower() == ".pot":
        h, w2 = idx.shape
        if w2 % 2:
            raise FormatError(path, f".pot rows hold a high-byte half and a low-byte half, width {w2} is odd")
        w = w2 // 2
        value = idx[:, :w].astype(np.uint32) * 256 + idx[:, w:]
        data, bits, fmt = value / 65535.0, 16, "fractint-pot"
    else:
        data, bits, fmt = idx / 255.0, 8, "povray-gif"
    meta = {"source": str(path), "format": fmt, "bits": bits, "height_scale": 1.0, "height_offset": 0.0}
    return Heightfield(data.astype(np.float32), None, meta)


def write(hf: Heightfield, path) -> None:
    """Write heights in ``[0, 1]`` as a grey-palette GIF (index = round(h * 255)) or a
    ``.pot`` (16-bit round(h * 65535) split into high and low halves), atomically.

    Holes are written as 0. Raises FormatError for heights outside ``[0, 1]`` (use
    :meth:`Heightfield.normalized`) or an image wider than GIF allows.
    """
    Image = _pillow()
    d = np.asarray(hf.data, dtype=np.float64)
    if hf.mask is not None:
        d = np.where(hf.mask, 0.0, d)
    if not np.isfinite(d).all() or d.min() < 0.0 or d.max() > 1.0:
        raise FormatError(path, "GIF/POT heights must lie in [0, 1]; normalize first (Heightfield.normalized())")
    pot = Path(path).suffix.lower() == ".pot"
    if pot:
        v = np.rint(d * 65535.0).astype(np.uint16)
        idx = np.concatenate([(v >> 8).astype(np.uint8), (v & 0xFF).astype(np.uint8)], axis=1)
    else:
        idx = np.rint(d * 255.0).astype(np.uint8)
    if max(idx.shape) > GIF_MAX_SIDE:
        raise FormatError(path, f"a GIF is at most {GIF_MAX_SIDE} pixels wide and high, this one would be "
                                f"{idx.shape[1]}x{idx.shape[0]}")
    im = Image.fromarray(np.ascontiguousarray(idx))  # mode L: identity grey palette, index = value
    with atomic_path(path) as tmp:
        im.save(tmp, format="GIF", optimize=False)
