"""``csm-assets verify IN``: render a converted scene (:func:`csm_assets.verify.scene.verify_scene`)
or a map (:func:`csm_assets.verify.maps.load_packed`, then :func:`csm_assets.verify.maps.verify_step_map`)
headless and check it against the exact tracer.

Exit codes: 0 passed; 1 over budget (or a primitive that cannot be verified);
2 bad arguments; 3 unreadable input; 4 images cannot be written; 5 no OpenGL/EGL.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..formats.registry import scene_format
from ..render.renderer import VARIANTS
from ..verify.maps import DEFAULT_VIEWS, MAX_STEPS, RELAXED_DEFAULT_STEPS, STEPS, verify_file, verify_step_map
from ..verify.variants import map_variants
from . import shadows
from .common import (BIT_DEPTHS, EXIT_OK, EXIT_OVER_BUDGET, add_map_kind, add_map_settings, add_views,
                     default, number, stage_line)

MAX_SIZE = 4096  # render side in pixels: 5 float RGBA targets of 4096² take 1.3 GB (7, 1.9 GB, with --shadows)
SIZE = default(verify_step_map, "size")
MAX_ERROR = default(verify_step_map, "max_error")
DEPTH = default(verify_step_map, "depth")
MAX_ITERATIONS = default(verify_step_map, "max_iterations")
BITS = default(verify_file, "bits")
DISTANCE_SIZE = 64  # --distance: its reference traces ceil(texels per pixel)² rays a pixel


def add(sub) -> None:
    s = sub.add_parser("verify", help="render a converted scene or a map headless and check it against the "
                                      "exact tracer",
                       description="Render IN with the shipped GLSL (headless OpenGL): every primitive of a "
                                   "converted scene with its material's variant and steps, from automatic "
                                   "views (straight on to grazing) and the scene's cameras, or a map on a "
                                   "quad; trace each pixel's shader ray exactly on the CPU and report the "
                                   "texel error (mean, p95, max), the share of pixels on a wrong surface "
                                   "point (> 1 texel) and not converged, and the iterations. Exit 1 when a "
                                   "view's p95 error exceeds --max-error or a primitive cannot be verified, "
                                   "5 when no OpenGL/EGL context can be made.")
    s.add_argument("input", metavar="IN",
                   help="a converted scene (.gltf .glb .obj .usda .usdc .usdz), a step map written by "
                        "csm-assets, or a height map")
    s.add_argument("--variant", action="append", choices=(*VARIANTS, "all"), metavar="V",
                   help=f"shader variant, repeatable: {', '.join(VARIANTS)} or all (default: each scene "
                        "material's own, else exact)")
    s.add_argument("--steps", type=number(int, 1, MAX_STEPS), metavar="N",
                   help=f"steps of loop and fixed, linear steps of pom and relief, search steps of relaxed, "
                        f"1..{MAX_STEPS} (default: each scene material's own, else {STEPS}; relaxed "
                        f"{RELAXED_DEFAULT_STEPS}, as convert writes it)")
    s.add_argument("--max-error", type=number(float, 1e-9, 1e9), default=MAX_ERROR, metavar="E",
                   help=f"budget: the largest p95 texel error allowed at any view (default {MAX_ERROR:g})")
    s.add_argument("--json", action="store_true", help="print the report as JSON")
    s.add_argument("--images", metavar="DIR", help="write colour, uv, reference, error and iteration PNGs "
                                                   "per view, and contact_sheet.png of every view")
    add_views(s, DEFAULT_VIEWS, "90: straight on; scenes also use their own cameras")
    s.add_argument("--no-cameras", action="store_true", help="scenes: do not draw from the scene's cameras")
    s.add_argument("--depth", type=number(float, 1e-9, 1e6), default=DEPTH, metavar="D",
                   help=f"maps: relief depth as a fraction of the texture's width (default {DEPTH:g}; also 2^-24 "
                        "to 2^24 texels deep: D x the map's longer side)")
    s.add_argument("--size", type=number(int, 8, MAX_SIZE, what="a whole number of pixels"),
                   metavar="PX", help=f"render size in pixels, 8..{MAX_SIZE} (default {SIZE}; {DISTANCE_SIZE} "
                                      "with --distance)")
    s.add_argument("--distance", action="store_true",
                   help="maps: draw the map repeated far away, at 1, 4, 8 and 16 texels per pixel from "
                        "elevations 90, 45 and 20 (or each of --views), and compare today's march with a "
                        "supersampled exact reference: image RMSE, p95, flicker, fetches, cache tiles and rays "
                        "through the surface (exit 1 when any)")
    s.add_argument("--max-iterations", type=number(int, 1, 1 << 20), default=MAX_ITERATIONS, metavar="N",
                   help=f"iteration cap of the exact variant (default {MAX_ITERATIONS}); capped pixels count "
                        "as not converged")
    add_map_kind(s)
    s.add_argument("--invert", action="store_true", help="height-map IN is a depth map (white = deep)")
    s.add_argument("--no-tile", action="store_true", help="the texture does not repeat")
    s.add_argument("--bits", type=int, choices=BIT_DEPTHS, default=BITS,
                   help="bits of the step map made from a height map (default: the fewest whose rounding of "
                        "the heights cannot be seen at --depth and --views, as stepmap chooses them)")
    s.add_argument("--nodata", type=float, metavar="V",
                   help="height-map IN: texels of this stored value hold no height (as for stepmap)")
    s.add_argument("--no-bilinear-safe", action="store_true",
                   help="make the step map of a height map exactly as the paper does, without the "
                        "bilinear safety pass that convert applies")
    add_map_settings(s, "; scenes: their minStep")
    shadows.add(s)
    s.set_defaults(run=run)


def run(args) -> int:
    """Verify IN and print the report; the exit code (GLUnavailable and the library's errors
    propagate to the CLI's mapping)."""
    variants = None
    if args.variant:
        # "all": every variant that draws the map (a map of relaxed or quadrant cones: its own;
        # verify.variants.map_variants, verify.scene.primitive_variants)
        variants = "all" if "all" in args.variant else list(dict.fromkeys(args.variant))
    if args.distance:
        return _distance(args)
    args.size = args.size or SIZE
    views = args.views or list(DEFAULT_VIEWS)
    shadow_lights = shadows.lights(args)  # the shadow options are checked before any drawing
    line = stage_line(False, Path(args.input).name)  # on a terminal: reading, drawing, shadows
    try:
        return _verify(args, variants, views, shadow_lights, line)
    finally:
        if line is not None:
            line.close()


def _verify(args, variants, views, shadow_lights, line) -> int:
    from ..verify.maps import format_report

    if line is not None:
        line("reading")
    common = dict(size=args.size, max_error=args.max_error, images=args.images, views=views,
                  max_iterations=args.max_iterations, progress=line)
    scene = scene_format(args.input) is not None
    chosen = []  # the bits chosen for a step map made here from a height map
    if scene:
        from ..verify.hints import scene_fix
        from ..verify.scene import format_scene_report, load_primitives, verify_scene

        loaded = load_primitives(Path(args.input))  # read once, for verify and --shadows
        report = verify_scene(Path(args.input), variants=variants, steps=args.steps, min_step=args.min_step,
                              cameras=not args.no_cameras, loaded=loaded, **common)
        report.fix = scene_fix(report, step_map_settings(loaded[0]), scene_choices(loaded[0], views))
        text = format_scene_report(report)
    else:
        from ..depth import check_depth
        from ..map_file import load_step_maps
        from ..verify.bits import chooser
        from ..verify.hints import map_fix, stored_choice

        (sm,) = load_step_maps(Path(args.input), invert=args.invert, as_step_map=args.step_map,
                               bits=chooser(args.depth, views=views, given=args.bits, log=chosen),
                               max_ratio=args.max_ratio, tile=False if args.no_tile else None, channel=args.channel,
                               bilinear_safe=not args.no_bilinear_safe, nodata=args.nodata).values()
        check_depth(args.depth, sm.pixels.shape, "--depth")  # before anything is traced or drawn
        for choice in chosen:
            if choice.warning:
                sys.stderr.write(f"csm-assets: warning: {args.input}: {choice.warning}\n")
        s = sm.settings
        variants = map_variants(s.cones, variants)  # "all": every variant that draws it
        loaded = (sm.pixels, s.max_ratio, s.tile, float(s.min_step if args.min_step is None else args.min_step),
                  sm.second)  # made once, for verify and --shadows
        packed, max_ratio, tile, min_step, second = loaded
        report = verify_step_map(packed, max_ratio=max_ratio, tile=tile, source=Path(args.input).name,
                                 min_step=min_step, depth=args.depth, variants=variants, second=second,
                                 steps=args.steps, **common)
        report.fix = map_fix(report, s, min_step, given_bits=args.bits is not None, made_here=bool(chosen),
                             choice_of=lambda: chosen[0] if chosen and args.bits is None else
                             stored_choice(packed, second, s, args.depth, views, min_step))
        text = format_report(report)
    data, passed = report.to_dict(), report.passed
    if chosen:
        data["bits"] = chosen[0].to_dict()
    if shadow_lights:
        from ..verify.shadows import format_shadow_report

        if line is not None:
            line("shadows")
        shadow = shadows.run(args, scene=scene, views=views, variant=None if variants in (None, "all") else variants[0],
                             steps=args.steps, loaded=loaded)
        data["shadows"], passed = shadow.to_dict(), passed and shadow.passed
        text += "\n" + format_shadow_report(shadow)
    if line is not None:
        line.hold()
    sys.stdout.write((json.dumps(data, indent=2) if args.json else text) + "\n")
    return EXIT_OK if passed else EXIT_OVER_BUDGET


def _distance(args) -> int:
    """``verify --distance``: :func:`csm_assets.verify.distance.verify_distance` of a map IN."""
    from ..depth import check_depth
    from ..errors import OptionError
    from ..map_file import load_step_maps
    from ..verify.bits import chooser
    from ..verify.distance import TEXELS_PER_PIXEL, distance_views, verify_distance
    from ..verify.distance_report import format_distance

    if scene_format(args.input) is not None:
        raise OptionError(f"--distance: {args.input} is a scene; --distance draws a step map or a height map")
    if args.shadows or args.variant:
        raise OptionError("--distance measures the exact variant's march without shadows: leave out "
                          "--variant and --shadows")
    (sm,) = load_step_maps(Path(args.input), invert=args.invert, as_step_map=args.step_map,
                           bits=chooser(args.depth, given=args.bits), max_ratio=args.max_ratio, channel=args.channel,
                           bilinear_safe=not args.no_bilinear_safe, nodata=args.nodata,
                           levels="average").values()
    s = sm.settings
    if s.cones != "conservative":
        raise OptionError(f"--distance: {args.input} holds {s.cones} cones; --distance marches conservative "
                          f"cones (the exact variant)")
    if args.no_tile or not all(s.tile):
        raise OptionError(f"--distance draws the map repeated: {args.input} does not tile (tile {list(s.tile)})")
    check_depth(args.depth, sm.pixels.shape, "--depth")
    views = (distance_views() if not args.views else
             [(t, el, az) for el, az in args.views for t in TEXELS_PER_PIXEL])
    report = verify_distance(sm.pixels, max_ratio=s.max_ratio, depth=args.depth, views=views,
                             min_step=float(s.min_step if args.min_step is None else args.min_step),
                             size=args.size or DISTANCE_SIZE, source=Path(args.input).name, levels=sm.levels)
    sys.stdout.write((json.dumps(report.to_list(), indent=2) if args.json else format_distance(report)) + "\n")
    return EXIT_OK if report.passed else EXIT_OVER_BUDGET


def step_map_settings(prims):
    """``settings_of(name)``: the StepMapSettings stored in the step map of that name among the
    primitives ``prims`` draw (None when it holds none), each read once, only when asked."""
    from ..formats import read_step_map_meta
    from ..stepmap import BITS, StepMapSettings

    textures = {p.stored.step_map.name: (p.stored.step_map, p.packed) for p in prims}
    known = {}

    def settings_of(name):
        if name not in known and name in textures:
            texture, packed = textures[name]
            with texture.as_file() as file:
                meta = read_step_map_meta(file)
            known[name] = StepMapSettings.from_meta(meta, BITS.get(packed.dtype, 32)) if meta else None
        return known.get(name)

    return settings_of


def scene_choices(prims, views):
    """``choice_of(report)``: the BitsChoice of a failed primitive's 8-bit step map
    (:func:`csm_assets.verify.hints.stored_choice` at its depth and ``views``)."""
    from ..verify.hints import stored_choice

    by_name = {p.name: p for p in prims}

    def choice_of(report):
        p = by_name.get(report.name)
        return None if p is None else stored_choice(p.packed, p.packed2, p.stored, report.depth_scale, views,
                                                     report.min_step)

    return choice_of
