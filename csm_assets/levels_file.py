"""A step map's levels image (docs/reference/levels.md) read back, as verify and view do: its header
checked against its step map's before any pixel is decoded (a small file can declare a huge image),
then its pixels; any problem is one :class:`FormatError` naming the image and what was expected."""

from __future__ import annotations

import numpy as np

from .errors import FormatError
from .step_levels import atlas_shape, split_atlas


def expected(shape, dtype) -> str:
    """The levels image of a step map of ``shape`` ``(H, W, ...)`` and ``dtype``, in words."""
    h, w = atlas_shape(shape[:2])
    return f"{w}x{h} RGBA {np.dtype(dtype)} (levels 1..n of its {shape[1]}x{shape[0]} step map side by side)"


def read_levels(texture, shape, dtype, what: str, scene_path) -> list[np.ndarray]:
    """Levels 1..n (views, ``[(h_k, w_k, 4)]``) of a step map of ``shape`` ``(H, W, ...)`` and
    ``dtype``, cut from its levels image ``texture`` (a :class:`~csm_assets.scene.Texture`).
    FormatError naming the image (``scene_path`` for an embedded one) with ``what`` (which
    material's) when it cannot be read or is not :func:`expected`."""
    from .formats import image

    want = expected(shape, dtype)
    h, w = atlas_shape(shape[:2])
    where = texture.path or scene_path
    try:
        with texture.as_file() as file:
            found = image.read_layout(file)
            if found == (w, h, 4, str(np.dtype(dtype))):
                pixels = image.read_rgba(file)
    except FormatError as e:
        raise FormatError(where, f"{what}: the levels image cannot be read ({str(e).removeprefix(e.path + ': ')}); "
                                 f"expected {want}") from None
    if found != (w, h, 4, str(np.dtype(dtype))):
        fw, fh, channels, kind = found
        raise FormatError(where, f"{what}: the levels image is {fw}x{fh}, {channels} channel(s) {kind}; expected {want}")
    return [np.ascontiguousarray(lv) for lv in split_atlas(pixels, shape[:2])]
