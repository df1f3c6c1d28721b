"""The speed/accuracy trade of the shader variants on one map, and the cheapest that meets a budget.

:func:`measure_trade` draws a step map with every variant and step count
(:data:`DEFAULT_CONFIGS`) at each view and compares each pixel with the exact
tracer, with :mod:`csm_assets.verify.maps`'s machinery (one reference per view,
shared by all variants; one statistics function). Per setting it reports texel
error (mean over pixels, p95 of the worst view as ``verify`` judges a budget,
max), the wrong-surface and non-converged shares, iterations (texture steps
per pixel: the cost that does not depend on the hardware) and the frame time
of the draw alone on this machine's renderer (``ctx.finish()`` around the
draw, the fastest of a few). :func:`cheapest` picks the setting that meets a
p95 budget with the fewest mean iterations, then the shortest frame time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..checks import positive
from ..render.gl_context import check_texture_size
from ..render.renderer import VARIANTS, Renderer
from ..verify.maps import (DEFAULT_VIEWS, RENDER_SIZE, finite_or_none, measure_view, pixel_stats, prepare,
                           quad_view)

CONE_STEPS = (1, 2, 4, 8, 16, 32, 64)
PEER_STEPS = (4, 8, 16, 32, 64)
RELAXED_STEPS = (1, 2, 4)  # the relaxed variant's search steps (1 already beats exact's error: docs/measurements/shader-trade.md)
# (variant, steps): steps 0 where the variant has none (exact runs until it hits, parallax is one step)
DEFAULT_CONFIGS = (("exact", 0), *(("loop", n) for n in CONE_STEPS), *(("fixed", n) for n in CONE_STEPS),
                   ("parallax", 0), *(("pom", n) for n in PEER_STEPS), *(("relief", n) for n in PEER_STEPS),
                   *(("relaxed", n) for n in RELAXED_STEPS))
RELAXED_CONFIGS = tuple(c for c in DEFAULT_CONFIGS if c[0] == "relaxed")  # the only ones for relaxed cones
QUADRANT_CONFIGS = (("quadrant", 0),)  # the only one for quadrant maps (two images); not in DEFAULT_CONFIGS
# bench trade's: every default setting, exact with the new end of the march, and the quadrant map
BENCH_CONFIGS = (*DEFAULT_CONFIGS, ("exact_interp", 0), *QUADRANT_CONFIGS)
MIN_STEP_VARIANTS = ("exact", "exact_interp", "quadrant", "relaxed")  # the variants a minimum step changes


# the auto-pick's views: straight down, middle and grazing (the errors grow towards grazing)
PICK_VIEWS = ((90.0, 0.0), (50.0, 120.0), (20.0, 290.0), (10.0, 45.0))
PICK_SIZE = 48


@dataclass
class TradeRow:
    """One (variant, steps) over all views. Errors in texels (inf: more than 5% of a view's
    pixels hit where the reference missed or the reverse); shares in [0, 1]."""

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
        name = self.variant if self.variant in ("exact", "exact_interp", "parallax", "quadrant") else \
            f"{self.variant} {self.steps}"
        return name + (", relaxed cones" if self.cones == "relaxed" else "")

    @property
    def min_step_text(self) -> str:
        """The minimum step in texels, or "-" for a variant it does not change."""
        return f"{self.min_step:g}" if self.variant in MIN_STEP_VARIANTS else "-"


@dataclass
class TradeReport:
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

    def cheapest(self, max_error: float) -> TradeRow | None:
        """The row meeting ``max_error`` (p95 texels, every view) with the fewest mean
        iterations, then the shortest frame time; None when none meets it."""
        ok = [r for r in self.rows if r.p95_error <= max_error]
        return min(ok, key=lambda r: (r.mean_iterations, r.frame_ms), default=None)

    def best(self) -> TradeRow:
        """The row with the smallest p95 error (then the fewest iterations)."""
        return min(self.rows, key=lambda r: (r.p95_error, r.mean_iterations))

    def to_dict(self) -> dict:
        """Plain data for JSON: infinite errors become null."""
        return finite_or_none(asdict(self))

    def table(self) -> str:
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
        return "\n".join(lines)


def views_text(views) -> str:
    return " ".join(f"{el:g}/{az:g}" for el, az in views)


def check_configs(configs) -> list[tuple[str, int]]:
    out = []
    for variant, steps in configs:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
        if variant in ("loop", "fixed", "pom", "relief", "relaxed") and not 1 <= int(steps) <= 127:
            raise ValueError(f"{variant} needs steps in 1..127, got {steps!r}")
        out.append((variant, int(steps)))
    return out


def measure_trade(packed, *, max_ratio=1.0, tile=True, configs=DEFAULT_CONFIGS, views=DEFAULT_VIEWS, size=RENDER_SIZE,
                  depth=0.1, max_iterations=4096, draws=3, source="<array>", min_step=1.0,
                  cones="conservative", shadow_light=None, second=None, progress=None,
                  depth_name="depth") -> TradeReport:
    """Every (variant, steps) of ``configs`` on ``packed`` (``(H, W, 4)`` uint8, uint16 or
    float32) at every (elevation, azimuth) of ``views``, against the exact tracer.

    depth: world depth of the height range under a 1 x 1 quad (texture-space depth), measurable
    on the map (:func:`csm_assets.depth.check_depth`: an OptionError naming ``depth_name``).
    size: render width and height in pixels. max_iterations: the cap of exact.
    draws: draws per view whose fastest gives the frame time. min_step: the minimum
    step in texels (the paper's 1; 0.25 for bilinear-safe maps; at most
    :data:`~csm_assets.render.renderer.MAX_MIN_STEP`). cones: the map's cones,
    recorded on each row; "relaxed" cones take only the relaxed variant (ValueError).
    shadow_light: (elevation, azimuth) degrees of a directional light to draw with
    self-shadowing (the shadow ray's steps then count in the iterations, the cost the pick
    weighs), or None. second: a quadrant map's second image (cones "quadrant": the quadrant
    variant only, and it only). progress: ``progress("measuring", done, total)`` by config.
    """
    configs = check_configs(configs)
    if cones == "relaxed" and any(v != "relaxed" for v, _ in configs):
        raise ValueError("a map of relaxed cones is drawn only by the relaxed variant")
    if (cones == "quadrant") != (second is not None) or any((v == "quadrant") != (cones == "quadrant")
                                                            for v, _ in configs):
        raise ValueError("a quadrant map (two images) is drawn by the quadrant variant, and only it")
    p, height, mat = prepare(packed, max_ratio, tile, depth, min_step=min_step, second=second, depth_name=depth_name)
    if shadow_light is not None:
        from ..verify.shadows import light_vector

        shadow_light = (float(shadow_light[0]), float(shadow_light[1]))
        mat.self_shadow, mat.light_direction = True, tuple(light_vector(*shadow_light))
    with Renderer((size, size)) as r:
        check_texture_size(r.ctx, p.shape, source)  # before any upload
        report = TradeReport(source=str(source), shape=tuple(p.shape[:2]), dtype=str(p.dtype), tile=mat.tile,
                             max_ratio=mat.max_ratio, depth=float(depth), size=int(size),
                             max_iterations=int(max_iterations), renderer=r.info.get("GL_RENDERER", "?"),
                             views=[(float(el), float(az)) for el, az in views], shadow_light=shadow_light)
        cases = [quad_view(height, el, az, mat.tile) for el, az in views]
        for done, (variant, steps) in enumerate(configs):
            if progress:
                progress(f"measuring {variant} {steps}", done, len(configs))
            errs, status, its, per_view, ms = [], [], [], [], []
            for case in cases:
                res, stats, err, sel = measure_view(r, mat, case, variant, max(steps, 1), max_iterations, draws)
                errs.append(err.ravel()[sel])
                status.append(res.status.ravel()[sel])
                its.append(res.iterations.ravel()[sel])
                per_view.append(stats)
                ms.append(1e3 * res.draw_s)
            pooled = pixel_stats(np.concatenate(errs), np.concatenate(status), np.concatenate(its))
            pooled["p95_error"] = max((v.p95_error for v in per_view), default=0.0)
            pooled["block_cost"] = (sum(v.block_cost * v.blocks for v in per_view)
                                    / max(sum(v.blocks for v in per_view), 1))
            report.rows.append(TradeRow(variant, steps, **pooled, frame_ms=float(np.mean(ms)), views=per_view,
                                        cones=str(cones), min_step=float(mat.min_step)))
    return report


def trade_heights(heights, settings=None, **kwargs) -> TradeReport:
    """:func:`measure_trade` on the step map of ``heights`` (float ``(H, W)`` in [0, 1], or
    uint8/uint16, or a Heightfield) made with :class:`~csm_assets.stepmap.StepMapSettings`
    ``settings`` (default :data:`csm_assets.stepmap.DEFAULTS`, as convert makes them); exact's
    minimum step is the map's unless ``min_step`` is given. Fields of the settings may also
    come by keyword (``bits=16``, ``bilinear_safe=False``, ``tile``, ``max_ratio``, ``cones``: a
    relaxed map is measured with :data:`RELAXED_CONFIGS` unless ``configs`` says otherwise)."""
    from ..stepmap import DEFAULTS, make_step_map

    fields = {k: kwargs.pop(k) for k in ("bits", "tile", "max_ratio", "bilinear_safe", "cones") if k in kwargs}
    sm = make_step_map(heights, (settings or DEFAULTS).replace(**fields))
    kwargs.setdefault("min_step", sm.min_step)
    if sm.settings.cones in ("relaxed", "quadrant"):
        kwargs.setdefault("configs", RELAXED_CONFIGS if sm.settings.cones == "relaxed" else QUADRANT_CONFIGS)
    return measure_trade(sm.pixels, max_ratio=sm.settings.max_ratio, tile=sm.settings.tile, cones=sm.settings.cones,
                         second=sm.second, **kwargs)


def measure_file(path, *, bits=8, invert=False, tile=None, bilinear_safe=True, as_step_map=None, channel=None,
                 max_ratio=None, min_step=None, **kwargs) -> TradeReport:
    """:func:`measure_trade` on a file as ``bench trade`` reads it (:func:`csm_assets.map_file.load_step_maps`,
    one read, which takes ``as_step_map``, ``channel``, ``max_ratio`` as verify does; ``min_step``, when
    given, replaces each map's; several minimum steps (a sequence) measure every config at the
    first and the :data:`MIN_STEP_VARIANTS` again at each other): a csm-assets step map as it is (one of relaxed cones with
    :data:`RELAXED_CONFIGS` only); a height map made into its conservative step map (every config
    of ``configs``, default :data:`DEFAULT_CONFIGS`) and, when ``configs`` has relaxed ones, into its
    map of relaxed cones (:data:`RELAXED_CONFIGS`, rows with ``cones`` "relaxed"; from the same
    heights and conservative cones), so the relaxed variant is measured on its own cones too; likewise a
    quadrant map (:data:`QUADRANT_CONFIGS`) when ``configs`` has the quadrant variant."""
    from pathlib import Path

    from ..map_file import load_step_maps

    path = Path(path)
    kwargs.setdefault("source", path.name)
    configs = kwargs.pop("configs", DEFAULT_CONFIGS)
    own = {"conservative": [c for c in configs if c[0] != "quadrant"],
           "relaxed": [c for c in configs if c[0] == "relaxed"] or list(RELAXED_CONFIGS),
           "quadrant": [c for c in configs if c[0] == "quadrant"] or list(QUADRANT_CONFIGS)}
    maps = load_step_maps(path, invert=invert, bits=bits, tile=tile, bilinear_safe=bilinear_safe,
                          as_step_map=as_step_map, channel=channel, max_ratio=max_ratio,
                          cones=("conservative", *(k for k in ("relaxed", "quadrant") if any(c[0] == k for c in configs))))
    steps = [None] if min_step is None else [min_step] if np.ndim(min_step) == 0 else list(dict.fromkeys(min_step))
    reports = [measure_trade(sm.pixels, max_ratio=sm.settings.max_ratio, tile=sm.settings.tile,
                             min_step=sm.min_step if w is None else float(w),
                             configs=[c for c in own[cones] if k == 0 or c[0] in MIN_STEP_VARIANTS],
                             cones=cones, second=sm.second, **kwargs)
               for k, w in enumerate(steps) for cones, sm in maps.items()
               if k == 0 or any(c[0] in MIN_STEP_VARIANTS for c in own[cones])]  # conservative first
    for more in reports[1:]:
        reports[0].rows += more.rows
    return reports[0]


def pick_settings(packed, max_error, *, configs=DEFAULT_CONFIGS, views=PICK_VIEWS, size=PICK_SIZE,
                  **kwargs) -> tuple[TradeRow, bool, TradeReport]:
    """The cheapest (variant, steps) of ``configs`` meeting ``max_error`` (p95 texels at every
    view) on ``packed``: (row, met, report). When none meets it, the most accurate row and
    met = False. Measured at ``views`` and ``size`` (fewer and smaller than the bench's, for speed);
    ``shadow_light=(el, az)`` picks with self-shadowing on (its steps in the cost)."""
    positive(max_error, "max_error")
    report = measure_trade(packed, configs=configs, views=views, size=size, draws=1, **kwargs)
    row = report.cheapest(max_error)
    return (row, True, report) if row is not None else (report.best(), False, report)
