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

import numpy as np

from ..checks import positive
from ..render.gl_context import check_texture_size
from ..render.renderer import VARIANTS, Renderer
from ..verify.distance import distance_views
from ..verify.maps import DEFAULT_VIEWS, RENDER_SIZE, measure_view, pixel_stats, prepare, quad_view
from .trade_report import MIN_STEP_VARIANTS, TradeReport, TradeRow, views_text  # noqa: F401  (re-exported)

CONE_STEPS = (1, 2, 4, 8, 16, 32, 64)
PEER_STEPS = (4, 8, 16, 32, 64)
RELAXED_STEPS = (1, 2, 4)  # the relaxed variant's search steps (1 already beats exact's error: docs/measurements/shader-trade.md)
DEFAULT_CONFIGS = (("exact", 0), *(("loop", n) for n in CONE_STEPS), *(("fixed", n) for n in CONE_STEPS),
                   ("parallax", 0), *(("pom", n) for n in PEER_STEPS), *(("relief", n) for n in PEER_STEPS),
                   *(("relaxed", n) for n in RELAXED_STEPS))
"""``(variant, steps)`` pairs measured and picked among by default (steps 0 where the variant has
none: exact runs until it hits, parallax is one step)."""
RELAXED_CONFIGS = tuple(c for c in DEFAULT_CONFIGS if c[0] == "relaxed")  # the only ones for relaxed cones
QUADRANT_CONFIGS = (("quadrant", 0),)  # the only one for quadrant maps (two images); not in DEFAULT_CONFIGS
BENCH_CONFIGS = (*DEFAULT_CONFIGS, ("exact_interp", 0), *QUADRANT_CONFIGS)
"""``bench trade``'s: every default setting, exact with the new end of the march, and the quadrant map."""


DISTANCE_VIEWS = tuple(distance_views(texels=(1.0, 8.0, 16.0), elevations=(45.0, 20.0)))
"""``bench trade``'s distance views, ``(texels_per_pixel, elevation, azimuth)``: where the level
chain's targets are set (8 and 16 texels a pixel at 45 and 20 degrees) and one texel a pixel."""

# the auto-pick's views: straight down, middle and grazing (the errors grow towards grazing)
PICK_VIEWS = ((90.0, 0.0), (50.0, 120.0), (20.0, 290.0), (10.0, 45.0))
PICK_SIZE = 48


def check_configs(configs) -> list[tuple[str, int]]:
    """``configs`` as ``(variant, int steps)`` pairs; ValueError for an unknown variant or a
    stepped variant's steps outside 1..127."""
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
    """Every (variant, steps) of ``configs`` on a packed map at every view, against the exact tracer.

    Args:
        packed (numpy.ndarray): ``(H, W, 4)`` uint8, uint16 or float32.
        max_ratio (float): the ratio G = 1 stands for.
        tile (bool | tuple[bool, bool]): as the map was made.
        configs: ``(variant, steps)`` pairs (steps 0 for a variant that takes none).
        views: ``(elevation, azimuth)`` degrees.
        size (int): render width and height in pixels.
        depth (float): world depth of the height range under a 1 x 1 quad (texture-space
            depth), measurable on the map (:func:`csm_assets.depth.check_depth`).
        max_iterations (int): the cap of exact.
        draws (int): draws per view whose fastest gives the frame time.
        source (str): the map's name, for the report.
        min_step (float): the minimum step in texels (the paper's 1; 0.25 for bilinear-safe
            maps; at most :data:`~csm_assets.render.renderer.MAX_MIN_STEP`).
        cones (str): the map's cones, recorded on each row; ``"relaxed"`` cones take only the
            relaxed variant.
        shadow_light (tuple | None): ``(elevation, azimuth)`` degrees of a directional light
            to draw with self-shadowing (the shadow ray's steps then count in the iterations,
            the cost the pick weighs).
        second (numpy.ndarray | None): a quadrant map's second image (cones ``"quadrant"``: the
            quadrant variant only, and it only).
        progress: ``progress("measuring", done, total)`` by config.
        depth_name (str): how a refusal of ``depth`` names it (``--depth``).

    Returns:
        The TradeReport, a row per config.

    Raises:
        OptionError: a depth nothing can be measured at, naming ``depth_name``.
        ValueError: an unknown variant, a bad step count, or configs the map's cones cannot
            draw.
        GLUnavailable: no OpenGL context.
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
    """:func:`measure_trade` on the step map of ``heights``.

    Args:
        heights (numpy.ndarray | Heightfield): float ``(H, W)`` in ``[0, 1]``, uint8/uint16,
            or a Heightfield.
        settings (StepMapSettings | None): how the map is made (None:
            :data:`csm_assets.stepmap.DEFAULTS`, as convert makes them).
        **kwargs: fields of the settings (``bits=16``, ``bilinear_safe=False``, ``tile``,
            ``max_ratio``, ``cones``: a relaxed map is measured with :data:`RELAXED_CONFIGS`
            unless ``configs`` says otherwise), and :func:`measure_trade`'s arguments (exact's
            ``min_step`` is the map's unless given).

    Returns:
        The TradeReport.
    """
    from ..stepmap import DEFAULTS, make_step_map

    fields = {k: kwargs.pop(k) for k in ("bits", "tile", "max_ratio", "bilinear_safe", "cones") if k in kwargs}
    sm = make_step_map(heights, (settings or DEFAULTS).replace(levels="none", **fields))  # level 0 is measured
    kwargs.setdefault("min_step", sm.min_step)
    if sm.settings.cones in ("relaxed", "quadrant"):
        kwargs.setdefault("configs", RELAXED_CONFIGS if sm.settings.cones == "relaxed" else QUADRANT_CONFIGS)
    return measure_trade(sm.pixels, max_ratio=sm.settings.max_ratio, tile=sm.settings.tile, cones=sm.settings.cones,
                         second=sm.second, **kwargs)


def measure_file(path, *, bits=8, invert=False, tile=None, bilinear_safe=True, as_step_map=None, channel=None,
                 max_ratio=None, min_step=None, distance=None, **kwargs) -> TradeReport:
    """:func:`measure_trade` on a file as ``bench trade`` reads it (one read:
    :func:`csm_assets.map_file.load_step_maps`).

    A csm-assets step map is measured as it is (one of relaxed cones with
    :data:`RELAXED_CONFIGS` only). A height map is made into its conservative step map (every
    config of ``configs``, default :data:`DEFAULT_CONFIGS`) and, when ``configs`` has relaxed
    ones, into its map of relaxed cones (rows with ``cones`` "relaxed"), so the relaxed
    variant is measured on its own cones too; likewise a quadrant map
    (:data:`QUADRANT_CONFIGS`) when ``configs`` has the quadrant variant.

    Args:
        path (str | os.PathLike): a step map or a height map.
        bits (int): a height map's step map bits.
        invert (bool): a height map holds depths (white = deep).
        tile (bool | None): tiling (None: the file's, else True).
        bilinear_safe (bool): a height map's step map gets the safety pass.
        as_step_map (bool | None): as for :func:`csm_assets.verify.maps.verify_file`.
        channel (int | str | None): a height map's channel.
        max_ratio (float | None): the cap (None: the file's, else 1.0).
        min_step (float | list[float] | None): replaces each map's minimum step; several (a
            sequence) measure every config at the first and the :data:`MIN_STEP_VARIANTS`
            again at each other.
        distance (list | None): ``(texels_per_pixel, elevation, azimuth)`` views at which to
            measure the conservative map far away, with its level chain (a step map's own, else
            made ``"average"`` from level 0): :attr:`TradeReport.distance`. None: not measured.
        **kwargs: :func:`measure_trade`'s other arguments (``configs``, ``views``, ...).

    Returns:
        One TradeReport holding the rows of every map.

    Raises:
        FormatError: an unreadable file, or an RGBA map without settings.
        ValueError: bad arguments, as :func:`measure_trade`.
    """
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
    if distance is not None:
        far_away(reports[0], next(iter(maps.values())), distance, None if min_step is None else steps[0])
    return reports[0]


def far_away(report: TradeReport, sm, views, min_step=None) -> None:
    """Fill ``report.distance`` with :func:`~csm_assets.verify.distance.verify_distance` of the
    step map ``sm`` at ``views`` with its levels (a map without them: the ``"average"`` chain of
    its level 0, as a height map's is made), or ``report.distance_note`` with why not (it marches
    only conservative cones, repeated)."""
    from ..step_levels import level_chain
    from ..verify.distance import verify_distance

    s = sm.settings
    if s.cones != "conservative" or not all(s.tile):
        report.distance_note = (f"the map holds {s.cones} cones (the distance views march conservative ones)"
                                if s.cones != "conservative" else f"the map does not tile (tile {list(s.tile)})")
        return
    report.distance = verify_distance(sm.pixels, max_ratio=s.max_ratio, depth=report.depth, views=views,
                                      min_step=float(sm.min_step if min_step is None else min_step),
                                      source=report.source, levels=sm.levels or level_chain(
                                          sm.pixels, ("conservative",), mode="average", tile=s.tile,
                                          max_ratio=s.max_ratio, bilinear_safe=s.bilinear_safe)["conservative"])


def pick_settings(packed, max_error, *, configs=DEFAULT_CONFIGS, views=PICK_VIEWS, size=PICK_SIZE,
                  **kwargs) -> tuple[TradeRow, bool, TradeReport]:
    """The cheapest (variant, steps) of ``configs`` meeting a budget on ``packed`` (what
    ``convert --max-error`` picks).

    Args:
        packed (numpy.ndarray): ``(H, W, 4)``, as for :func:`measure_trade`.
        max_error (float): the budget: p95 texels at every view (> 0).
        configs: the ``(variant, steps)`` pairs to pick among.
        views: ``(elevation, azimuth)`` degrees (fewer than the bench's, for speed).
        size (int): render side in pixels (smaller than the bench's).
        **kwargs: :func:`measure_trade`'s other arguments; ``shadow_light=(el, az)`` picks
            with self-shadowing on (its steps in the cost).

    Returns:
        ``(row, met, report)``: the cheapest row meeting ``max_error`` and True; when none
        does, the most accurate row and False.

    Raises:
        ValueError: ``max_error`` not > 0, or bad arguments as :func:`measure_trade`.
    """
    positive(max_error, "max_error")
    report = measure_trade(packed, configs=configs, views=views, size=size, draws=1, **kwargs)
    row = report.cheapest(max_error)
    return (row, True, report) if row is not None else (report.best(), False, report)
