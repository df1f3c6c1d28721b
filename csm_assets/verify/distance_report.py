"""The report of ``verify --distance`` (:func:`csm_assets.verify.distance.verify_distance`): data,
and the text table the CLI prints."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from .stats import finite_or_none


@dataclass
class MarchStats:
    """One march at one view, against the supersampled reference (see :mod:`csm_assets.verify.distance`).

    Attributes:
        rmse (float): RMS difference of the shaded image from the reference (N·L, 0..1).
        p95 (float): the 95th percentile of the absolute difference.
        flicker (float): the image's RMS change under a half-pixel camera shift over the
            reference's (1: it moves as the true picture does).
        fetches (float): texture fetches per pixel of the march (its iterations + the first).
        tiles (float): mean distinct 4x4-texel tiles the fetches of an 8x4-pixel block touch.
        through (float): share of pixels whose hit lies more than a texel beyond the exact
            first hit, the ray having been under the surface for at least the minimum step on
            the way (:func:`~csm_assets.verify.march.under_run`).
        pixels (int): pixels measured.
        same_steps (float): share of pixels where the CPU emulation of the march (which the
            tiles come from) takes the render's step count.
        seam (float): how much more the image jumps, against the reference, across the pixel
            pairs where the march changes level than within a level
            (:func:`~csm_assets.verify.distance_seams.seam_contrast`: 1, no more; NaN, null in
            JSON, where no pair changes level, as today's level-0 march).
        seam_pairs (float): share of neighbouring pixel pairs across a level change.
    """

    rmse: float
    p95: float
    flicker: float
    fetches: float
    tiles: float
    through: float
    pixels: int
    same_steps: float
    seam: float = math.nan
    seam_pairs: float = 0.0


@dataclass
class DistanceRecord:
    """One view of ``verify --distance``.

    Attributes:
        texels_per_pixel (float): texels one pixel spans at the image centre, across the screen.
        elevation (float): degrees above the surface (90: straight on).
        azimuth (float): degrees around its normal.
        today (MarchStats): today's march (the ``exact`` variant on level 0).
        levels (MarchStats | None): the level chain's march (csm.glsl's level a pixel, its image
            shaded from the chain with the pixel's uv footprint); None for a map without levels.
            It stops on the footprint-filtered surface by design, so its ``through`` (against the
            fine surface) is reported, not failed.
    """

    texels_per_pixel: float
    elevation: float
    azimuth: float
    today: MarchStats
    levels: MarchStats | None = None


@dataclass
class DistanceReport:
    """The outcome of ``verify --distance``: passed when no ray of today's march went through.

    Attributes:
        source (str): the map's name.
        shape (tuple): the map's ``(rows, cols)``.
        depth (float): relief depth as a fraction of the texture's width.
        size (int): render side in pixels.
        renderer (str): the GL renderer that drew it (``GL_RENDERER``).
        views (list): a :class:`DistanceRecord` per view.
    """

    source: str
    shape: tuple
    depth: float
    size: int
    renderer: str
    views: list = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """No ray of today's level-0 march went through the surface."""
        return all(r.today.through == 0.0 for r in self.views)

    def to_list(self) -> list:
        """One plain record per view, for JSON (``levels``: null for a map without levels)."""
        return [finite_or_none(asdict(r)) for r in self.views]


def format_distance(report: DistanceReport) -> str:
    """The report as a text table: a row per view and march (``today``, then ``levels`` when measured)."""
    rows, cols = report.shape
    chain = any(v.levels is not None for v in report.views)
    lines = [f"verify --distance {report.source}: {cols}x{rows}, depth {report.depth:g}, {report.size}x{report.size} "
             f"px on {report.renderer}; today's march (level 0){' and the level chain' if chain else ''} against a "
             f"supersampled exact reference",
             f"{'tex/px':>6} {'elev':>5} {'azim':>5} {'march':>6} {'rmse':>7} {'p95':>7} {'flicker':>7} {'fetches':>7} "
             f"{'tiles':>6} {'through':>7} {'same':>6} {'seam':>5}"]
    for v in report.views:
        for name, s in (("today", v.today), ("levels", v.levels)):
            if s is not None:
                lines.append(f"{v.texels_per_pixel:6g} {v.elevation:5g} {v.azimuth:5g} {name:>6} {s.rmse:7.4f} "
                             f"{s.p95:7.4f} {s.flicker:7.2f} {s.fetches:7.2f} {s.tiles:6.1f} "
                             f"{100 * s.through:6.2f}% {100 * s.same_steps:5.1f}% "
                             f"{'-' if math.isnan(s.seam) else f'{s.seam:5.2f}':>5}")
    bad = [v for v in report.views if v.today.through > 0]
    lines.append("PASS: no ray went through the surface" if not bad else
                 f"FAIL: rays went through the surface at {len(bad)} view(s) (a level-0 march must never)")
    return "\n".join(lines)


def format_distance_columns(report: DistanceReport) -> str:
    """The report side by side, a row per view: today's march, the level chain's and their ratio
    for RMSE, fetches and tiles; flicker of both (x the reference's); the chain's ``through``.
    What ``bench trade`` prints below its table (a map without levels: today's columns only)."""
    def pair(a, b, fmt, ratio=True):
        if b is None:
            return f"{a:{fmt}} {'-':>7}" + (f" {'-':>6}" if ratio else "")
        return f"{a:{fmt}} {b:{fmt}}" + (f" {b / a if a else float('nan'):5.2f}x" if ratio else "")

    lines = [f"distance ({report.size}x{report.size} px, against a supersampled exact reference; "
             f"today: the level-0 march, levels: the level chain's):",
             f"{'tex/px':>6} {'elev':>5} {'azim':>5} {'rmse today/levels':>22} {'flicker t/l':>15} "
             f"{'fetches today/levels':>22} {'tiles today/levels':>22} {'through':>7}"]
    for v in report.views:
        t, c = v.today, v.levels
        through = "-" if c is None else f"{100 * c.through:6.2f}%"
        lines.append(f"{v.texels_per_pixel:6g} {v.elevation:5g} {v.azimuth:5g} "
                     f"{pair(t.rmse, c and c.rmse, '7.4f')} {pair(t.flicker, c and c.flicker, '7.2f', False)} "
                     f"{pair(t.fetches, c and c.fetches, '7.2f')} {pair(t.tiles, c and c.tiles, '7.1f')} "
                     f"{through:>7}")
    return "\n".join(lines)
