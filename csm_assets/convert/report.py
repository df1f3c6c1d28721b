"""What a conversion did: :class:`ConvertReport`, the report :func:`csm_assets.convert.pipeline.convert`
returns, and what each converted material got (:func:`picked`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..warning_codes import Notice


@dataclass
class ConvertReport:
    """What a conversion did.

    Attributes:
        input (pathlib.Path): the scene.
        skipped (str | None): why nothing was done (outputs fresh, no relief), else None.
        written (list[pathlib.Path]): the files written.
        removed (list[pathlib.Path]): the files removed (a scene that lost its relief, see
            :mod:`csm_assets.convert.lost_relief`).
        step_maps (dict[str, pathlib.Path]): height texture -> its step map.
        tangent_meshes (list[str]): meshes that got generated tangents.
        warnings (list[Notice]): the warnings not ignored (:mod:`csm_assets.warning_codes`).
        picks (dict): material -> ``{"variant", "steps", "bits", "bits_reason"}`` written.
        seconds (float): wall time.
    """

    input: Path
    skipped: str | None = None  # why nothing was done (outputs fresh, NO_RELIEF), else None
    written: list[Path] = field(default_factory=list)
    removed: list[Path] = field(default_factory=list)
    step_maps: dict[str, Path] = field(default_factory=dict)
    tangent_meshes: list[str] = field(default_factory=list)
    warnings: list[Notice] = field(default_factory=list)  # not ignored; see csm_assets.warning_codes
    picks: dict = field(default_factory=dict)  # material -> {"variant", "steps"} written
    seconds: float = 0.0

    @property
    def unchanged(self) -> bool:
        """Converted, but no material had a height texture: the scene was copied as it was."""
        return self.skipped is None and not self.step_maps


def picked(mat) -> dict:
    """What a converted material got, for the report: variant, steps, bits and why those bits."""
    c = mat.csm
    choice = getattr(c.map, "choice", None)  # None: made again at more bits by --max-error's confirmation
    why = f"made again at {c.bits} bits to meet --max-error" if choice is None else \
        "given" if choice.given else choice.reason
    return {"variant": c.variant, "steps": c.steps, "bits": c.bits, "bits_reason": why,
            **({"min_step": c.min_step} if c.picked_min_step is not None else {})}  # picked: quadrant maps
