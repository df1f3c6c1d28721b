"""Heightfield file formats, chosen by extension from a plain registry.

Each format module has ``read(path, **options) -> Heightfield`` and
``write(hf, path)``; heavy imports stay inside the modules.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..heightfield import Heightfield

# extension -> module in this package
FORMATS: dict[str, str] = {
    ".png": "image", ".tga": "image", ".tif": "image", ".tiff": "image",
    ".exr": "image", ".jpg": "image", ".jpeg": "image",
}


def format_module(path):
    """The module that handles ``path``'s extension; FormatError if none does."""
    ext = Path(path).suffix.lower()
    name = FORMATS.get(ext)
    if name is None:
        known = " ".join(sorted(FORMATS))
        raise FormatError(path, f"unknown heightfield format {ext or '(no extension)'!r}; known: {known}")
    return importlib.import_module(f".{name}", __name__)


def load_heightfield(path, *, channel=None, invert=False) -> Heightfield:
    """Read a heightfield file (format by extension).

    channel: for images, None (first channel of a grey image, luminance of a colour
        one), an index or a channel name.
    invert: turn a depth map (white = deep) into a height map: ``1 - d`` on
        normalized data.

    Raises :class:`~csm_assets.FormatError` (a ValueError naming the file) when the
    file is missing, unreadable or malformed.
    """
    options = {} if channel is None else {"channel": channel}
    hf = format_module(path).read(path, **options)
    if invert:
        hf.data = (1.0 - hf.data).astype(np.float32)
    return hf


def save_heightfield(hf: Heightfield, path) -> None:
    """Write ``hf`` to ``path`` (format by extension), atomically."""
    format_module(path).write(hf, path)


def read_step_map(path) -> np.ndarray:
    """A packed ``(H, W, 4)`` step map from an image, in its stored type."""
    from . import image
    return image.read_rgba(path)


def write_step_map(packed: np.ndarray, path) -> None:
    """Write a packed ``(H, W, 4)`` map bit-exactly (PNG, TGA, TIFF, EXR), atomically."""
    from . import image
    image.write_rgba(packed, path)
