"""How a step map is made: :class:`StepMapSettings` and the one set of defaults (:data:`DEFAULTS`).

The settings travel with a map (JSON in its image description, :meth:`StepMapSettings.to_meta`)
and decide what the shader needs: the cone ratio scale, tiling, bits, the minimum step.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .heightfield import tile_pair
from .packing import SAFE_MIN_STEP
from .step_levels import LEVEL_MODES

BITS = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16, np.dtype(np.float32): 32}


@dataclass(frozen=True)
class StepMapSettings:
    """How a step map was made; what the shader needs travels with it (frozen).

    Attributes:
        max_ratio (float): the cone ratio that G = 1 stands for (> 0).
        tile (tuple[bool, bool]): ``(tile_x, tile_y)``: the texture repeats along that axis
            (a bool given is used for both).
        bits (int): 8, 16 (integers) or 32 (float).
        bilinear_safe (bool): G holds each texel's 3x3 minimum (see
            :func:`csm_assets.step_map`), and ``_exact`` then steps at least 0.25 texel
            (:attr:`min_step`), else the paper's one texel.
        cone (str): ``"exact"`` (made here) or ``"external"`` (a map made elsewhere).
        cones (str): ``"conservative"`` (every variant), ``"relaxed"`` (the ``relaxed``
            variant only) or ``"quadrant"`` (two images, the ``quadrant`` variant only).
        height_scale (float): with ``height_offset``, ``raw = offset + scale * R``.
        height_offset (float): see ``height_scale``.
        source (str): the height map's name.
        levels (str): ``"none"``, or the level chain below the map
            (:mod:`csm_assets.step_levels`): ``"average"`` (2x2-averaged heights) or ``"max"``
            (max-filtered heights, never below the map's surface), each level with exact cones
            of its own kind. The default is ``"average"`` (docs/reference/levels.md); a map read
            without the key (made before levels, or with ``"none"``) has ``"none"``.
    """

    max_ratio: float = 1.0
    tile: tuple[bool, bool] = (True, True)
    bits: int = 8
    bilinear_safe: bool = True
    cone: str = "exact"
    cones: str = "conservative"
    height_scale: float = 1.0
    height_offset: float = 0.0
    source: str = ""
    levels: str = "average"

    def __post_init__(self):
        object.__setattr__(self, "tile", tile_pair(self.tile))
        if self.levels not in LEVEL_MODES:
            raise ValueError(f"levels must be one of {', '.join(LEVEL_MODES)}, got {self.levels!r}")

    @property
    def min_step(self) -> float:
        """``_exact``'s minimum step in texels: 0.25 with bilinear-safe maps, else 1 (the paper's);
        half that for quadrant maps, whose variant measures it across the texture (longer along
        steep rays: a quarter texel skipped white-noise peaks at 10-20 degree views)."""
        step = SAFE_MIN_STEP if self.bilinear_safe else 1.0
        return step / 2 if self.cones == "quadrant" else step

    def replace(self, **changes) -> StepMapSettings:
        """A copy with ``changes``.

        Args:
            **changes: field values by name; None leaves a field as it is.

        Returns:
            The new settings.
        """
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_meta(self) -> dict:
        """The JSON object stored in the map's image description."""
        return {"max_ratio": self.max_ratio, "tile": list(self.tile), "bits": self.bits,
                "bilinear_safe": self.bilinear_safe, "cones": self.cones, "height_scale": self.height_scale,
                "height_offset": self.height_offset, "source": self.source,
                **({"levels": self.levels} if self.levels != "none" else {})}

    @classmethod
    def from_meta(cls, meta: dict, bits: int) -> StepMapSettings:
        """Settings stored by :meth:`to_meta` (older maps lack some: bilinear_safe then False).

        Args:
            meta: the stored JSON object.
            bits: the image's bits (8, 16 or 32), which the file's type says.

        Returns:
            The settings, ``cone="exact"``.
        """
        return cls(max_ratio=float(meta.get("max_ratio", 1.0)), tile=tuple(meta.get("tile", (True, True))),
                   bits=bits, bilinear_safe=bool(meta.get("bilinear_safe", False)), cone="exact",
                   cones=str(meta.get("cones", "conservative")),
                   height_scale=float(meta.get("height_scale", 1.0)),
                   height_offset=float(meta.get("height_offset", 0.0)), source=str(meta.get("source", "")),
                   levels=str(meta.get("levels", "none")))


DEFAULTS = StepMapSettings()
"""The one set of defaults ``stepmap``, ``convert``, ``verify`` and ``bench trade`` start from."""
