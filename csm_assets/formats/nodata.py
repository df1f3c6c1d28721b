"""A height image's nodata value: the texels that are holes, not heights."""

from __future__ import annotations

from pathlib import Path

import numpy as np

GDAL_NODATA = 42113  # the TIFF tag GDAL writes a raster's nodata value in (ASCII)


def file_nodata(path) -> float | None:
    """A TIFF's GDAL_NODATA value (tag 42113, which OpenImageIO does not keep; read with
    Pillow, header only), or None: other formats, no tag, a tag that is no number."""
    if Path(path).suffix.lower() not in (".tif", ".tiff"):
        return None
    from PIL import Image

    try:
        with Image.open(path) as im:
            text = getattr(im, "tag_v2", {}).get(GDAL_NODATA)
    except Exception:  # noqa: BLE001 - Pillow refuses some TIFFs OpenImageIO reads: then no tag is known
        return None
    try:
        return float(str(text).strip().rstrip("\x00")) if text is not None else None
    except ValueError:
        return None


def holes(values: np.ndarray, nodata) -> np.ndarray | None:
    """Texels equal to ``nodata`` (NaN: the NaN ones) in raw ``values`` ``(H, W)`` or
    ``(H, W, C)`` (all channels equal to it), or None without a nodata value."""
    if nodata is None:
        return None
    hit = np.isnan(values) if np.isnan(nodata) else values == nodata
    return hit.all(axis=2) if hit.ndim == 3 else hit
