"""A Blender image's heights, read by the library's own readers.

A file image is read from its file (every bit of a 16-bit PNG or a float EXR, as ``convert``
reads it), a packed one from its packed bytes, a generated or painted-but-unsaved one from the
pixels Blender holds (written to a float EXR first, so one reader serves all). What cannot be read
is a :class:`~csm_assets.errors.FormatError` naming the image.
"""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..formats import load_heightfield, save_heightfield
from ..heightfield import Heightfield
from ..scene import safe_name

# Blender's file_format -> a suffix the library reads
SUFFIXES = {"PNG": ".png", "JPEG": ".jpg", "OPEN_EXR": ".exr", "OPEN_EXR_MULTILAYER": ".exr", "TIFF": ".tif",
            "TARGA": ".tga", "TARGA_RAW": ".tga", "BMP": ".bmp", "HDR": ".hdr"}
DATA_SPACES = ("Non-Color", "Raw", "Generic Data")


def read_heights(image, channel=None, invert: bool = False) -> Heightfield:
    """The heights of bpy Image ``image``: ``channel`` (None: the first of a grey image, the
    luminance of a colour one; 0..3), ``invert`` for ``1 - value`` (see
    :func:`csm_assets.load_heightfield`)."""
    with image_file(image, channel) as (path, channel):
        try:
            return load_heightfield(path, channel=channel, invert=invert)
        except FormatError as e:
            why = str(e)[len(e.path) + 2:] if str(e).startswith(f"{e.path}: ") else str(e)
            raise FormatError(_label(image), f"cannot be read: {why}") from None


def is_data(image) -> bool:
    """Whether Blender uses the image's values as stored (Non-Color, or a linear colour space),
    not linearised from sRGB or another display encoding."""
    settings = image.colorspace_settings
    return bool(getattr(settings, "is_data", False)) or settings.name in DATA_SPACES or \
        settings.name.lower().startswith("linear")


@contextlib.contextmanager
def image_file(image, channel):
    """(path, channel) of a file holding ``image``'s texels: its own file, or a temporary one."""
    if image.source not in ("FILE", "GENERATED"):
        raise FormatError(_label(image), f"is a {image.source.lower()} image; only single images are converted "
                                         "(UDIM tiles, sequences and movies are not)")
    if image.source == "FILE" and not image.is_dirty:
        if image.packed_file is not None:
            suffix = Path(image.filepath).suffix.lower() or SUFFIXES.get(image.file_format, ".png")
            with tempfile.TemporaryDirectory(prefix="csm-blender-") as tmp:
                path = Path(tmp) / f"{safe_name(Path(image.name).stem)}{suffix}"
                path.write_bytes(bytes(image.packed_file.data))
                yield path, channel
            return
        import bpy

        path = Path(bpy.path.abspath(image.filepath, library=image.library))
        if not path.is_file():
            raise FormatError(path, f"(image {image.name!r}) does not exist")
        yield path, channel
        return
    pixels = blender_pixels(image)
    if pixels is None:
        raise FormatError(_label(image), "has no pixels Blender can give")
    if channel is None:
        rgb = pixels[..., :3]
        grey = pixels.shape[2] < 3 or (np.ptp(rgb, axis=2) == 0).all()
        plane = pixels[..., 0] if grey else rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    else:
        plane = pixels[..., min(channel, pixels.shape[2] - 1)]
    with tempfile.TemporaryDirectory(prefix="csm-blender-") as tmp:
        path = Path(tmp) / f"{safe_name(Path(image.name).stem)}.exr"
        save_heightfield(Heightfield(np.ascontiguousarray(plane, np.float32)), path)
        yield path, None


def blender_pixels(image) -> np.ndarray | None:
    """The image's float pixels ``(H, W, C)`` in image order (Blender stores the bottom row first)."""
    w, h = image.size
    c = image.channels
    if not (w and h and c):
        return None
    flat = np.empty(w * h * c, np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(h, w, c)[::-1]


def _label(image) -> str:
    return f"image {image.name!r}" + (f" ({image.filepath})" if image.filepath else "")
