"""The heightfield model and the rules that turn arrays into unit heights.

Conventions (DESIGN.md): float32 ``(H, W)`` in image order (row 0 on top), heights
in ``[0, 1]`` with 1 the top; uint8 input is divided by 255 and uint16 by 65535.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .checks import positive


@dataclass
class Heightfield:
    """A height (or depth) field read from a file or made in memory.

    Attributes:
        data (numpy.ndarray): float32 ``(H, W)``, image order (row 0 on top). Images are
            normalized to ``[0, 1]``; formats that store raw altitudes (Rayshade .hf) keep them.
        mask (numpy.ndarray | None): bool ``(H, W)``, True where the field has a hole, or None.
        meta (dict): free-form facts about the source (path, bit depth, scale and offset used).

    Raises:
        ValueError: ``data`` not a non-empty 2-D array, or ``mask`` of another shape.
    """

    data: np.ndarray
    mask: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.data = np.asarray(self.data, dtype=np.float32)
        if self.data.ndim != 2 or self.data.size == 0:
            raise ValueError(f"heightfield data must be a non-empty 2-D array, got shape {self.data.shape}")
        if self.mask is not None:
            self.mask = np.asarray(self.mask, dtype=bool)
            if self.mask.shape != self.data.shape:
                raise ValueError(f"mask shape {self.mask.shape} differs from data shape {self.data.shape}")

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of ``data``."""
        return self.data.shape

    def exact_heights(self) -> np.ndarray:
        """The heights ``data`` stands for, without float32's rounding of k/255.

        Returns:
            For data read from an 8- or 16-bit image (``meta["bits"]``) whose values all sit
            on that grid (inverted ones too), the uint8/uint16 ``(H, W)`` levels; else ``data``.
        """
        bits = self.meta.get("bits")
        if bits not in (8, 16):
            return self.data
        top = (1 << bits) - 1
        out = np.empty(self.shape, np.uint8 if bits == 8 else np.uint16)
        step = max(1, (1 << 18) // self.shape[1])  # a band of rows at a time: small float64 temporaries
        for r0 in range(0, self.shape[0], step):
            data = self.data[r0:r0 + step]
            levels = np.rint(data.astype(np.float64) * top)
            if np.abs(levels / top - data).max(initial=0.0) > 1e-2 / top:  # float32 rounding only
                return self.data
            out[r0:r0 + step] = levels
        return out

    def normalized(self) -> Heightfield:
        """A new field with unit heights, for step maps and image writers.

        Heights are rescaled over the valid texels (those not in ``mask``) to
        ``[0, 1]``; data already in ``[0, 1]`` is kept as it is. Holes become 0,
        the lowest height (the mask is kept). ``meta`` gains ``height_scale`` and
        ``height_offset`` with ``raw = height_offset + height_scale * normalized``,
        composed with the height_scale and height_offset the field already carried (an
        image reader's rescaling of float data), so calling it twice changes nothing.
        A field of holes only becomes all 0.

        Returns:
            A new Heightfield (float32 ``(H, W)`` in ``[0, 1]``; the same data, not a copy,
            when it was in ``[0, 1]`` with no holes).

        Raises:
            ValueError: NaN or infinite valid texels.
        """
        meta = dict(self.meta)
        base_scale = float(meta.get("height_scale", 1.0))
        base_offset = float(meta.get("height_offset", 0.0))
        if self.mask is None and np.isfinite(self.data).all() and self.data.min() >= 0.0 and self.data.max() <= 1.0:
            meta.update(height_scale=base_scale, height_offset=base_offset + base_scale * 0.0)
            return Heightfield(self.data, None, meta)  # unit heights already: shared, not copied
        valid = np.ones(self.shape, bool) if self.mask is None else ~self.mask
        raw = self.data.astype(np.float64)
        vals = raw[valid]
        if not np.isfinite(vals).all():
            raise ValueError("heightfield has NaN or infinite heights outside its holes")
        scale, offset = 1.0, 0.0
        if vals.size and (vals.min() < 0.0 or vals.max() > 1.0):
            lo, hi = float(vals.min()), float(vals.max())
            scale, offset = (hi - lo if hi > lo else 1.0), lo
        out = np.where(valid, (raw - offset) / scale, 0.0)
        meta.update(height_scale=base_scale * scale, height_offset=base_offset + base_scale * offset)
        mask = None if self.mask is None else self.mask.copy()
        return Heightfield(np.clip(out, 0.0, 1.0).astype(np.float32), mask, meta)


def unit_heights(height) -> np.ndarray:
    """Validate ``height`` and return it as float64 ``(H, W)`` in ``[0, 1]``.

    uint8 is divided by 255, uint16 by 65535, floats are taken as they are. A
    :class:`Heightfield` gives its ``.data``. Raises ValueError for anything else:
    not 2-D, empty, another dtype, NaN or infinite values, floats outside ``[0, 1]``.
    """
    if isinstance(height, Heightfield):
        height = height.data
    a = np.asarray(height)
    if a.ndim != 2:
        raise ValueError(f"height must be a 2-D array (H, W), got {a.ndim}-D shape {a.shape}")
    if a.size == 0:
        raise ValueError(f"height must not be empty, got shape {a.shape}")
    levels = height_levels(a)
    if levels:
        h = a.astype(np.float64)
        h /= levels  # in place: one float64 copy of the map, not two
        return h
    if not np.issubdtype(a.dtype, np.floating):
        raise ValueError(f"height must be uint8, uint16 or float in [0, 1], got dtype {a.dtype}")
    h = a.astype(np.float64)
    if not np.isfinite(h).all():
        raise ValueError("height contains NaN or infinite values")
    lo, hi = float(h.min()), float(h.max())
    if lo < 0.0 or hi > 1.0:
        raise ValueError(f"float height must lie in [0, 1], got values in [{lo:g}, {hi:g}]")
    return h


LEVELS = {np.dtype(np.uint8): 255, np.dtype(np.uint16): 65535}  # integer heights: unit height = code / levels


def height_levels(height) -> int:
    """The integer code range of ``height``: 255 (uint8), 65535 (uint16), else 0 (floats;
    a :class:`Heightfield` by its ``.data``). Unit heights are ``code / levels``."""
    a = height.data if isinstance(height, Heightfield) else np.asarray(height)
    return LEVELS.get(a.dtype, 0)


def tile_pair(tile) -> tuple[bool, bool]:
    """Return ``(tile_x, tile_y)`` from a bool or a pair of bools."""
    if isinstance(tile, (bool, np.bool_)):
        return bool(tile), bool(tile)
    try:
        tx, ty = tile
    except (TypeError, ValueError):
        raise ValueError(f"tile must be a bool or a pair (tile_x, tile_y), got {tile!r}") from None
    return bool(tx), bool(ty)


def check_max_ratio(max_ratio) -> float:
    """Return ``max_ratio`` as a float, raising ValueError unless it is finite and > 0."""
    return positive(max_ratio, "max_ratio")
