"""What ``bench trade`` reports, as data: one row per (variant, steps), and the table it prints.

:mod:`csm_assets.bench.trade` measures them and re-exports these names.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ..verify.stats import finite_or_none

MIN_STEP_VARIANTS = ("exact", "exact_interp", "quadrant", "relaxed")  # the variants a minimum step changes


@dataclass
class TradeRow:
    """One (variant, steps) over all views.

    Errors are in texels (inf: more than 5% of a view's pixels hit where the reference missed
    or the reverse); shares are in ``[0, 1]``.

    Attributes:
        variant (str): the shader variant.
        steps (int): its step count (0: it takes none).
        pixels (int): pixels compared over all views.
        mean_error (float): over all views' pixels where both hit.
        p95_error (float): the worst view's p95 (what verify's budget judges).
        max_error (float): the largest.
        wrong_share (float): more than a texel off, or hit and miss disagree.
        nonconverged_share (float): stopped by the cap or still moving.
        mean_iterations (float): texture steps per pixel: the hardware-independent cost.
        max_iterations (int): the most at one pixel.
        frame_ms (float): the draw alone, mean over views of the fastest of ``draws``.
        views (list[ViewStats]): per view.
        cones (str): the cones of the map drawn (relaxed: the relaxed variant's own map).
        p99_iterations (float): over all views' pixels.
        block_cost (float): mean over all views' 8x4 pixel blocks of the block's largest
            iteration count.
        min_step (float): texels: the minimum step the row was drawn with
            (:data:`MIN_STEP_VARIANTS` take it).
    """

    variant: str
    steps: int
    pixels: int
    mean_error: float         # over all views' pixels where both hit
    p95_error: float          # the worst view's p95 (what verify's budget judges)
    max_error: float
    wrong_share: float        # more than a texel off, or hit/miss disagree
    nonconverged_share: float
    mean_iterations: float    # texture steps per pixel: the hardware-independent cost
    max_iterations: int
    frame_ms: float           # the draw alone, mean over views of the fastest of `draws`
    views: list = field(default_factory=list)  # ViewStats per view
    cones: str = "conservative"  # the cones of the map drawn (relaxed: the relaxed variant's own map)
    p99_iterations: float = 0.0  # over all views' pixels
    block_cost: float = 0.0   # mean over all views' 8x4 pixel blocks of the block's largest iterations
    min_step: float = 0.0     # texels: the minimum step the row was drawn with (MIN_STEP_VARIANTS take it)

    @property
    def label(self) -> str:
        """``"loop 8"``, ``"exact"``, ``"relaxed 2, relaxed cones"``: the row's name in tables."""
        name = self.variant if self.variant in ("exact", "exact_interp", "parallax", "quadrant") else \
            f"{self.variant} {self.steps}"
        return name + (", relaxed cones" if self.cones == "relaxed" else "")

    @property
    def min_step_text(self) -> str:
        """The minimum step in texels, or "-" for a variant it does not change."""
        return f"{self.min_step:g}" if self.variant in MIN_STEP_VARIANTS else "-"


@dataclass
class TradeReport:
    """What :func:`~csm_assets.bench.trade.measure_trade` measured on one map.

    The map's fields (``source`` to ``size``) mean what they mean in a
    :class:`~csm_assets.verify.reports.VerifyReport`.

    Attributes:
        source (str): the file's name, or ``<array>``.
        shape (tuple): the map's rows and columns.
        dtype (str): uint8, uint16 or float32.
        tile (tuple): whether the map wraps along x and along y.
        max_ratio (float): the cap the map was made with.
        depth (float): the quad's texture-space depth.
        size (int): pixels per side of every render.
        max_iterations (int): exact's cap.
        renderer (str): GL_RENDERER (frame times are this renderer's).
        views (list): ``(elevation, azimuth)`` degrees.
        rows (list[TradeRow]): one per config.
        shadow_light (tuple | None): ``(elevation, azimuth)`` when drawn with self-shadowing
            (its steps then count in the cost).
        distance (DistanceReport | None): the conservative map far away, today's march and its
            level chain's (:func:`csm_assets.verify.distance.verify_distance`); None when not
            measured (``distance_note`` says why, when it was asked for).
        distance_note (str): why the distance columns are missing ("" when measured or not asked).
    """

    source: str
    shape: tuple
    dtype: str
    tile: tuple
    max_ratio: float
    depth: float
    size: int
    max_iterations: int
    renderer: str
    views: list
    rows: list = field(default_factory=list)
    shadow_light: tuple | None = None  # (el, az): drawn with self-shadowing, its steps in the cost
    distance: object = None  # DistanceReport of the conservative map far away, or None
    distance_note: str = ""  # why the distance columns are missing, when asked for

    def cheapest(self, max_error: float) -> TradeRow | None:
        """The row meeting a budget with the fewest mean iterations, then the shortest frame time.

        Args:
            max_error: the budget: p95 texels at every view.

        Returns:
            The row, or None when none meets it.
        """
        ok = [r for r in self.rows if r.p95_error <= max_error]
        return min(ok, key=lambda r: (r.mean_iterations, r.frame_ms), default=None)

    def best(self) -> TradeRow:
        """The row with the smallest p95 error (then the fewest iterations)."""
        return min(self.rows, key=lambda r: (r.p95_error, r.mean_iterations))

    def to_dict(self) -> dict:
        """Plain data for JSON: infinite errors become null."""
        return finite_or_none(asdict(self))

    def table(self) -> str:
        """The text table ``bench trade`` prints: a header line, then a line per row."""
        ty, tx = self.shape
        header = (f"trade {self.source}: {tx}x{ty} {self.dtype}, tile {list(self.tile)}, max_ratio "
                  f"{self.max_ratio:g}, depth {self.depth:g}, {self.size}x{self.size} px, "
                  f"{len(self.views)} views {views_text(self.views)}; frame time on {self.renderer}")
        if self.shadow_light is not None:
            header += f"; self-shadowing, light {views_text([self.shadow_light])}: iterations include its steps"
        columns = (f"{'variant':12} {'steps':>5} {'mean':>7} {'p95':>7} {'max':>7} {'wrong':>6} {'nonconv':>7} "
                   f"{'iters':>6} {'p99_it':>6} {'max_it':>6} {'block':>6} {'ms':>7} {'min_st':>6} cones")
        lines = [header, columns]
        for r in self.rows:
            lines.append(f"{r.variant:12} {r.steps:5d} {r.mean_error:7.3f} {r.p95_error:7.3f} {r.max_error:7.2f} "
                         f"{100 * r.wrong_share:5.1f}% {100 * r.nonconverged_share:6.1f}% "
                         f"{r.mean_iterations:6.1f} {r.p99_iterations:6.0f} {r.max_iterations:6d} {r.block_cost:6.1f} "
                         f"{r.frame_ms:7.3f} {r.min_step_text:>6} {r.cones}")
        if self.distance is not None:
            from ..verify.distance_report import format_distance_columns

            lines += ["", format_distance_columns(self.distance)]
        elif self.distance_note:
            lines += ["", f"distance: not measured: {self.distance_note}"]
        return "\n".join(lines)


def views_text(views) -> str:
    """``"90/0 35/200"``: views as ``EL/AZ`` degrees."""
    return " ".join(f"{el:g}/{az:g}" for el, az in views)
