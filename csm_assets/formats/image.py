"""Raster images through OpenImageIO: PNG, TGA, TIFF, EXR, JPEG.

Heights: 8-bit /255, 16-bit /65535, float as stored; other integers (int16, int32, uint32:
elevation models) as their values. Values outside [0, 1] are rescaled over the valid texels
to [0, 1], with the scale and offset kept in ``meta`` (the real range travels with the map).
A nodata value (``nodata``, else a TIFF's GDAL_NODATA tag 42113) marks holes, never heights:
they go in the mask, and a step map takes them as the lowest valid height. Packed RGBA maps
are read and written with ``oiio:UnassociatedAlpha`` so alpha is never multiplied
into the colour channels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import cstderr, limits
from ..atomic import atomic_path
from ..bands import bands
from ..errors import FormatError, OutputError, no_file
from ..heightfield import Heightfield
from . import png_write
from .nodata import file_nodata, holes
from .registry import HEIGHTFIELD_FORMATS

_DTYPES = {8: np.uint8, 16: np.uint16, 32: np.float32}
_IMAGES = [f for f in HEIGHTFIELD_FORMATS if f.module == "image"]
# the pixel type heights are written in, and the packed step maps each format stores exactly (registry)
HEIGHT_TYPES = {f.extension: {8: "uint8", 16: "uint16", 32: "float"}[f.height_bits] for f in _IMAGES}
RGBA_DTYPES = {f.extension: tuple(_DTYPES[b] for b in f.step_map_bits) for f in _IMAGES if f.step_map_bits}
MAX_CHANNELS = 16  # more is no height map (and multiplies the memory a header can ask for)
LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709


def _oiio():
    try:
        import OpenImageIO
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ImportError("reading images needs OpenImageIO: pip install OpenImageIO") from e
    return OpenImageIO


def _open(path):
    """An open ``ImageInput`` for ``path`` that keeps alpha unassociated."""
    oiio = _oiio()
    if not Path(path).is_file():
        raise FormatError(path, no_file(path))
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    with cstderr.captured():
        inp = oiio.ImageInput.open(str(path), config)
    if inp is None:
        raise FormatError(path, f"not a readable image ({_one_line(oiio.geterror()) or 'unknown format'})")
    return inp


def read_size(path) -> tuple[int, int]:
    """``(width, height)`` of ``path``'s first image from its header, nothing decoded
    (FormatError for a file that is no readable image)."""
    return read_layout(path)[:2]


def read_layout(path) -> tuple[int, int, int, str]:
    """``(width, height, channels, type)`` of ``path``'s first image from its header, nothing
    decoded; type as :func:`read_rgba` gives it ("uint8", "uint16", "float32" for half floats too)."""
    inp = _open(path)
    try:
        spec = inp.spec()
        kind = str(spec.format)
        return int(spec.width), int(spec.height), int(spec.nchannels), {"half": "float32", "float": "float32",
                                                                          "double": "float64"}.get(kind, kind)
    finally:
        inp.close()


def read_pixels(path, describe: bool = False):
    """Native-typed ``(H, W, C)`` pixels of subimage 0 and the channel names (and, with
    ``describe``, the ``ImageDescription`` text), from one open of the file."""
    oiio = _oiio()
    inp = _open(path)
    try:
        spec = inp.spec()
        if spec.width <= 0 or spec.height <= 0 or spec.depth > 1:
            raise FormatError(path, f"expected a 2-D image, got {spec.width}x{spec.height}x{spec.depth}")
        # before decoding: a small file can declare a huge image
        limits.check(path, "TEXELS", spec.width * spec.height, f"a {spec.width}x{spec.height}-pixel image")
        if not 1 <= spec.nchannels <= MAX_CHANNELS:
            raise FormatError(path, f"expected 1 to {MAX_CHANNELS} channels, the header declares {spec.nchannels}")
        with cstderr.captured():
            pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.UNKNOWN)
        if pixels is None:
            raise FormatError(path, f"truncated or corrupt image ({_one_line(inp.geterror() or oiio.geterror())})")
        names = tuple(spec.channelnames)
        text = description_of(path, spec) if describe else None
    finally:
        inp.close()
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    return (pixels, names, text) if describe else (pixels, names)


def _unit(path, pixels: np.ndarray) -> np.ndarray:
    """8/16-bit codes as unit heights; floats and wider or signed integers as their values."""
    if pixels.dtype == np.uint8:
        return pixels.astype(np.float64) / 255.0
    if pixels.dtype == np.uint16:
        return pixels.astype(np.float64) / 65535.0
    if np.issubdtype(pixels.dtype, np.floating) or np.issubdtype(pixels.dtype, np.integer):
        return pixels.astype(np.float64)
    raise FormatError(path, f"expected integer or float pixels, got {pixels.dtype}")


def read_unit_pixels(path) -> tuple[np.ndarray, tuple[str, ...], int]:
    """All channels of ``path`` as float64 ``(H, W, C)`` in [0, 1] (float images as
    stored), the channel names and the stored bits (8, 16 or 32)."""
    pixels, names = read_pixels(path)
    bits = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}.get(pixels.dtype, 32)
    return _unit(path, pixels), names, bits


def _pick_channel(path, pixels: np.ndarray, names: tuple[str, ...], channel) -> np.ndarray:
    nch = pixels.shape[2]
    if channel is None:
        return pixels[..., 0] if nch <= 2 else pixels[..., :3] @ LUMA
    if isinstance(channel, str) and not channel.isdigit():
        if channel not in names:
            raise FormatError(path, f"no channel {channel!r}; it has {', '.join(names)}")
        return pixels[..., names.index(channel)]
    i = int(channel)
    if not 0 <= i < nch:
        raise FormatError(path, f"channel {i} out of range: it has {nch} channel(s)")
    return pixels[..., i]


def read(path, *, channel=None, image=None, nodata=None) -> Heightfield:
    """Read one height channel of an image.

    channel: None (the first channel of a grey image, grey+alpha included, or the
    Rec. 709 luminance of an RGB/RGBA one), a channel index, or a name ('R', 'A', ...).
    image: what :func:`read_pixels` already read of ``path`` (pixels, names[, text]), so
    that the file is opened once. nodata: the value (as stored: a code, an elevation, NaN)
    of texels that hold no height; None: the file's own (:func:`file_nodata`), if any. Those
    texels become the mask's holes, and the range is taken over the others.
    """
    pixels, names = (image or read_pixels(path))[:2]
    bits = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}.get(pixels.dtype, 32)
    nodata = file_nodata(path) if nodata is None else float(nodata)
    raw = pixels if channel is None and pixels.shape[2] > 2 else _pick_channel(path, pixels, names, channel)
    mask = holes(raw, nodata)
    h = _pick_channel(path, _unit(path, pixels), names, channel)
    valid = h if mask is None else h[~mask]
    if not np.isfinite(valid).all():
        raise FormatError(path, "image holds NaN or infinite values" + ("" if nodata is None else
                                                                        f" besides its nodata value {nodata:g}"))
    if mask is not None and mask.all():
        raise FormatError(path, f"every texel holds the nodata value {nodata:g}: no heights")
    meta = {"source": str(path), "bits": bits, "height_scale": 1.0, "height_offset": 0.0}
    if nodata is not None:
        meta["nodata"] = nodata
    lo, hi = (float(valid.min()), float(valid.max())) if valid.size else (0.0, 0.0)
    if lo < 0.0 or hi > 1.0 or mask is not None and mask.any():  # rescale over the heights, and say how
        span = hi - lo if hi > lo else 1.0
        h = np.where(mask, 0.0, (h - lo) / span) if mask is not None else (h - lo) / span
        meta.update(height_scale=span, height_offset=lo)
    return Heightfield(h.astype(np.float32), mask if mask is not None and mask.any() else None, meta)


def write(hf: Heightfield, path) -> None:
    """Write ``hf.data`` (in [0, 1]) as a grey image, in the most exact type the format
    has (PNG 16-bit, TIFF and EXR float, TGA and JPEG 8-bit). Holes are written as 0."""
    data = np.asarray(hf.data, dtype=np.float64)
    if hf.mask is not None:
        data = np.where(hf.mask, 0.0, data)
    if not np.isfinite(data).all() or data.min() < 0.0 or data.max() > 1.0:
        raise ValueError(f"{path}: image heights must lie in [0, 1]")
    kind = HEIGHT_TYPES[Path(path).suffix.lower()]
    if kind == "float":
        pixels = data.astype(np.float32)
    else:
        dtype = np.uint8 if kind == "uint8" else np.uint16
        pixels = np.rint(data * np.iinfo(dtype).max).astype(dtype)
    _write_pixels(pixels[:, :, None], path)


def read_rgba(path) -> np.ndarray:
    """A packed ``(H, W, 4)`` map in its stored type (uint8, uint16 or float32)."""
    return read_rgba_described(path)[0]


def read_rgba_described(path) -> tuple[np.ndarray, str]:
    """(packed ``(H, W, 4)`` map in its stored type, ``ImageDescription`` text), one open."""
    pixels, _, text = read_pixels(path, describe=True)
    if pixels.shape[2] != 4:
        raise FormatError(path, f"expected an RGBA step map (4 channels), got {pixels.shape[2]}")
    if pixels.dtype == np.float16:
        pixels = pixels.astype(np.float32)
    return pixels, text


def read_description(path) -> str:
    """The image's ``ImageDescription`` text ('' when it has none)."""
    inp = _open(path)
    try:
        return description_of(path, inp.spec())
    finally:
        inp.close()


TGA_DESCRIPTION_CHARS = 323  # a TGA's comment: 4 lines (OpenImageIO 2.5+ keeps 323 characters in all)


def description_of(path, spec) -> str:
    """``spec``'s ``ImageDescription`` as written: OpenImageIO splits a TGA's comment into its
    81-character lines joined by newlines, which are taken out again (descriptions written
    here, JSON, hold none)."""
    text = str(spec.getattribute("ImageDescription") or "")
    return text.replace("\n", "") if Path(path).suffix.lower() == ".tga" else text


def write_rgba(packed: np.ndarray, path, description: str = "", into=None, stop=None) -> None:
    """Write a packed ``(H, W, 4)`` map bit-exactly, atomically (``into``, ``stop``: see :func:`_write_pixels`).

    PNG holds uint8/uint16, TGA uint8, TIFF uint8/uint16/float32, EXR float32.
    Any other pairing (or JPEG, which is lossy) raises ValueError. ``description``
    goes into the ``ImageDescription`` field, which all four formats keep.
    """
    check_rgba(packed, path, description)
    _write_pixels(packed, path, description, into, stop)


def check_rgba(packed: np.ndarray, path, description: str = "") -> None:
    """ValueError when :func:`write_rgba` would refuse ``packed`` at ``path`` with ``description``
    (before anything is written)."""
    ext = Path(path).suffix.lower()
    if ext not in RGBA_DTYPES:
        got = f"not {ext}" if ext else "and this name has no extension (name a file, e.g. height_csm.png)"
        raise ValueError(f"{path}: step maps are written as PNG, TGA, TIFF or EXR, {got}")
    if packed.dtype.type not in RGBA_DTYPES[ext]:
        kinds = ", ".join(np.dtype(d).name for d in RGBA_DTYPES[ext])
        raise ValueError(f"{path}: {ext} stores {kinds} step maps, not {packed.dtype}")
    if ext == ".tga" and len(description) > TGA_DESCRIPTION_CHARS:
        raise ValueError(f"{path}: a .tga holds {TGA_DESCRIPTION_CHARS} characters of settings, these take "
                         f"{len(description)}; write .png or .tif")


def _write_pixels(pixels: np.ndarray, path, description: str = "", into=None, stop=None) -> None:
    """Write ``pixels`` to ``path`` atomically, or (``into``: a temporary path for ``path``) into
    ``into`` and read it back, unpublished; ``stop()`` true between bands of rows abandons it."""
    if into is None:
        with atomic_path(path) as tmp:
            return _write_pixels(pixels, path, description, tmp, stop)
    if Path(path).suffix.lower() == ".png":  # deflated on every core (the same pixels as libpng's)
        try:
            written = png_write.write_png(pixels, into, description, stop)
        except OSError as e:
            raise OutputError(path, f"cannot write image ({e.strerror or e})") from e
        if not written:
            raise OutputError(path, "cannot write image (stopped)")
        return _read_back(path, into, pixels, description)
    oiio = _oiio()
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, pixels.dtype.name if pixels.dtype != np.float32 else "float")
    spec.attribute("oiio:UnassociatedAlpha", 1)
    if description:
        spec.attribute("ImageDescription", description)
    if Path(path).suffix.lower() == ".exr":
        spec.attribute("compression", "zip")  # lossless
    out = oiio.ImageOutput.create(str(into))
    if out is None:
        raise OutputError(path, f"no writer for this format ({oiio.geterror()})")
    ok = out.open(str(into), spec) and all(  # a band of rows at a time: no contiguous copy of a view
        not (stop and stop()) and out.write_scanlines(y0, y1, 0, np.ascontiguousarray(pixels[y0:y1]))
        for y0, y1 in _bands(h, w * c))
    err = out.geterror()
    closed = out.close()
    if not ok or not closed:
        raise OutputError(path, f"cannot write image ({_one_line(err or out.geterror() or oiio.geterror())})")
    _read_back(path, into, pixels, description)


def _read_back(path, tmp, pixels: np.ndarray, description: str = "") -> None:
    """OutputError unless ``tmp`` decodes to exactly ``pixels`` (JPEG: to an image of their
    shape) and its description to ``description``; a library that hit a full disk may report
    success and leave a truncated file."""
    oiio = _oiio()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    same, text = False, None
    lossy = Path(path).suffix.lower() in (".jpg", ".jpeg")  # decodes whole, not to the same values
    with cstderr.captured():
        inp = oiio.ImageInput.open(str(tmp), config)
        if inp is not None:
            try:
                spec = inp.spec()
                same = (spec.height, spec.width, spec.nchannels) == pixels.shape and all(
                    _same_rows(inp.read_scanlines(0, 0, y0, y1, 0, 0, spec.nchannels, oiio.UNKNOWN),
                               pixels[y0:y1], lossy) for y0, y1 in _bands(*pixels.shape[:2]))
                text = description_of(path, inp.spec())
            finally:
                inp.close()
    oiio.geterror()  # clear the library's error state
    if not same:
        raise OutputError(path, "the written image does not read back as written (disk full or failing?); "
                                "the old file, if any, is kept")
    if description and text != description:
        raise OutputError(path, "the settings written into the image's description do not read back; "
                                "the old file, if any, is kept")


def _bands(rows: int, cols: int):
    """Rows ``(y0, y1)`` of an image in bands of about 2**20 values: the file is written and read
    back a band at a time, not as one more copy of the map."""
    return list(bands(rows, cols, 1 << 20))


def _same_rows(back, rows: np.ndarray, lossy: bool) -> bool:
    """Whether scanlines read back are ``rows`` (of their dtype; any values when ``lossy``)."""
    if back is None:
        return False
    back = np.asarray(back)
    return (back.dtype == rows.dtype and back.size == rows.size
            and (lossy or np.array_equal(back.reshape(rows.shape), rows)))


def _one_line(text) -> str:
    """A library's multi-line message as one line, repeated lines dropped."""
    lines = [" ".join(t.split()) for t in str(text or "").splitlines()]
    return "; ".join(dict.fromkeys(t for t in lines if t))
