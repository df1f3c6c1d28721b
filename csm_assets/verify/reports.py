"""What ``verify`` reports, as data: per view, per variant, per map and per converted scene.

Errors are texture-space distances in texels between a render's hit and the exact tracer's
(:mod:`csm_assets.verify.maps`); the CLI only prints these reports (text or ``--json``).
:mod:`csm_assets.verify.maps` and :mod:`csm_assets.verify.scene` re-export them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from .stats import finite_or_none


@dataclass
class ViewStats:
    """One variant at one view.

    Errors are texture-space distances in texels between the render's hit and the
    reference's, over pixels where either hits (inf where only one of them hits; a shared
    miss counts as agreement, not as an error).

    Attributes:
        elevation (float): degrees above the surface (NaN for a scene camera).
        azimuth (float): degrees around its normal (NaN for a scene camera).
        pixels (int): pixels compared (front-facing, the ray starts inside the map).
        mean_error (float): over pixels where both hit.
        p95_error (float): the 95th percentile; what ``max_error`` is checked against.
        max_error (float): the largest.
        wrong_share (float): share of pixels more than one texel away, or where hit and miss
            disagree.
        nonconverged_share (float): share stopped by the iteration cap or still moving.
        mean_iterations (float): texture fetches per pixel.
        max_iterations (int): the most at one pixel.
        camera (str): the scene camera's name, "" for an automatic view.
        p99_iterations (float): the 99th percentile of iterations.
        block_cost (float): mean over 8x4 pixel blocks of the block's largest iteration count
            (a warp waits for its slowest ray).
        blocks (int): the blocks counted.
    """

    elevation: float
    azimuth: float
    pixels: int               # pixels compared (front-facing, the ray starts inside the map)
    mean_error: float         # over pixels where both hit
    p95_error: float
    max_error: float
    wrong_share: float        # more than one texel away, or hit/miss disagree
    nonconverged_share: float  # stopped by the iteration cap / still moving
    mean_iterations: float
    max_iterations: int
    camera: str = ""          # the scene camera's name, "" for an automatic view
    p99_iterations: float = 0.0
    block_cost: float = 0.0   # mean over 8x4 pixel blocks of the block's largest iterations (verify.stats.BLOCK)
    blocks: int = 0


@dataclass
class VariantReport:
    """One shader variant at every view.

    Attributes:
        variant (str): the variant's name.
        steps (int): its step count (0: it takes none).
        views (list[ViewStats]): one per view.
    """

    variant: str
    steps: int
    views: list = field(default_factory=list)

    @property
    def worst_p95(self) -> float:
        """The largest p95 error over the views (0 with no view)."""
        return max((v.p95_error for v in self.views), default=0.0)


@dataclass
class VerifyReport:
    """The outcome of :func:`~csm_assets.verify.maps.verify_step_map`.

    Attributes:
        source (str): the map's name.
        shape (tuple): ``(H, W)``.
        dtype (str): its stored type.
        tile (tuple): ``(tile_x, tile_y)``.
        max_ratio (float): the ratio G = 1 stands for.
        depth (float): texture-space depth drawn.
        size (int): render side in pixels.
        max_error (float): the budget in texels (p95 at every view).
        renderer (str): GL_RENDERER.
        variants (list[VariantReport]): one per variant drawn.
        fix (str): when failed, what would fix it (set by the CLI).
    """

    source: str
    shape: tuple
    dtype: str
    tile: tuple
    max_ratio: float
    depth: float
    size: int
    max_error: float
    renderer: str
    variants: list = field(default_factory=list)
    fix: str = ""  # when failed: what would fix it (set by the CLI, :mod:`csm_assets.verify.hints`)

    @property
    def passed(self) -> bool:
        """Every view's p95 error of every variant is at most ``max_error`` texels."""
        return all(v.worst_p95 <= self.max_error for v in self.variants)

    def to_dict(self) -> dict:
        """Plain data for JSON: infinite errors (a pixel hit where the other missed) become null."""
        d = asdict(self)
        d["passed"] = self.passed
        for v, rep in zip(d["variants"], self.variants):
            v["worst_p95"] = rep.worst_p95
        return finite_or_none(d)


@dataclass
class PrimitiveReport:
    """One primitive (a glTF primitive, an OBJ material group, a USD mesh or subset).

    Attributes:
        name (str): the primitive's name.
        material (str): its CSM material.
        step_map (str): the step map's name.
        shape (tuple): the step map's ``(H, W)``.
        dtype (str): its stored type.
        depth_scale (float): the material's texture-space depth.
        max_ratio (float): the material's max ratio.
        tile (tuple): ``(tile_u, tile_v)``.
        min_step (float): the minimum step drawn with, in texels.
        variants (list[VariantReport]): one per variant drawn.
        problem (str): why it could not be drawn ("" when it was).
    """

    name: str
    material: str
    step_map: str = ""
    shape: tuple = ()
    dtype: str = ""
    depth_scale: float = 0.0
    max_ratio: float = 1.0
    tile: tuple = (True, True)
    min_step: float = 1.0
    variants: list = field(default_factory=list)
    problem: str = ""

    @property
    def worst_p95(self) -> float:
        """The largest p95 error of its variants (inf when none was drawn)."""
        return max((v.worst_p95 for v in self.variants), default=math.inf)

    def passed(self, max_error: float) -> bool:
        """Drawn, and every variant's p95 error at most ``max_error``.

        Args:
            max_error: the budget in texels.
        """
        return not self.problem and bool(self.variants) and self.worst_p95 <= max_error


@dataclass
class SceneReport:
    """The outcome of :func:`~csm_assets.verify.scene.verify_scene`.

    Attributes:
        source (str): the scene's name.
        size (int): render side in pixels.
        max_error (float): the budget in texels (p95 at every view).
        renderer (str): GL_RENDERER.
        views (list): ``"EL/AZ"`` of the automatic views, then the cameras' names.
        primitives (list[PrimitiveReport]): one per primitive with a CSM material.
        fix (str): when failed, what would fix it (set by the CLI).
    """

    source: str
    size: int
    max_error: float
    renderer: str
    views: list
    primitives: list = field(default_factory=list)
    fix: str = ""  # when failed: what would fix it (set by the CLI, :mod:`csm_assets.verify.hints`)

    @property
    def passed(self) -> bool:
        """Every primitive was drawn and each variant's p95 error is at most ``max_error``
        texels at every view."""
        return bool(self.primitives) and all(p.passed(self.max_error) for p in self.primitives)

    def to_dict(self) -> dict:
        """Plain data for JSON (``--json``): infinite errors become null."""
        d = asdict(self)
        d["passed"] = self.passed
        for pd, p in zip(d["primitives"], self.primitives):
            pd["passed"] = p.passed(self.max_error)
            pd["worst_p95"] = p.worst_p95 if p.variants else None
            for vd, v in zip(pd["variants"], p.variants):
                vd["worst_p95"] = v.worst_p95
        return finite_or_none(d)
