"""``csm-assets verify``: its arguments and how it runs (the CLI module only wires it in).

Exit codes: 0 passed; 1 over budget (or a primitive that cannot be verified);
2 bad arguments; 3 unreadable input; 4 images cannot be written; 5 no OpenGL/EGL.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import verify_shadows_cli
from .verify import MAX_STEPS, RENDER_SIZE, STEPS

SCENE_SUFFIXES = (".gltf", ".glb", ".obj", ".usda", ".usdc", ".usdz", ".usd")
MAX_SIZE = 4096  # render side in pixels: 5 float RGBA targets of 4096² take 1.3 GB
EXIT_OVER_BUDGET = 1


def _number(kind, low, high, what):
    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (low <= v <= high):
            raise argparse.ArgumentTypeError(f"expected {what} in {low:g}..{high:g}, got {text!r}")
        return v
    return parse


def configure(s) -> None:
    """Add verify's arguments to the sub-parser ``s``."""
    from .render import VARIANTS
    from .verify import DEFAULT_VIEWS

    views = " ".join(f"{el:g}/{az:g}" for el, az in DEFAULT_VIEWS)
    s.add_argument("input", metavar="IN",
                   help="a converted scene (.gltf .glb .obj .usda .usdc .usdz), a step map written by "
                        "csm-assets, or a height map")
    s.add_argument("--variant", action="append", choices=(*VARIANTS, "all"), metavar="V",
                   help=f"shader variant, repeatable: {', '.join(VARIANTS)} or all (default: each scene "
                        "material's own, else exact)")
    s.add_argument("--steps", type=_number(int, 1, MAX_STEPS, "a whole number"), metavar="N",
                   help=f"steps of loop and fixed, linear steps of pom and relief, 1..{MAX_STEPS} (default: "
                        "each scene material's own, else 16)")
    s.add_argument("--max-error", type=_number(float, 1e-9, 1e9, "a number"), default=1.0, metavar="E",
                   help="budget: the largest p95 texel error allowed at any view (default 1)")
    s.add_argument("--json", action="store_true", help="print the report as JSON")
    s.add_argument("--images", metavar="DIR", help="write colour, uv, reference, error and iteration PNGs "
                                                   "per view (and, for scenes, contact_sheet.png)")
    s.add_argument("--views", nargs="+", metavar="EL[/AZ]",
                   help=f"views as elevation/azimuth in degrees (90: straight on; default {views}); scenes "
                        "also use their own cameras")
    s.add_argument("--no-cameras", action="store_true", help="scenes: do not draw from the scene's cameras")
    s.add_argument("--depth", type=_number(float, 1e-9, 1e6, "a number"), default=0.1, metavar="D",
                   help="maps: relief depth as a fraction of the texture's width (default 0.1)")
    s.add_argument("--size", type=_number(int, 8, MAX_SIZE, "a whole number of pixels"), default=RENDER_SIZE,
                   metavar="PX", help=f"render size in pixels, 8..{MAX_SIZE} (default {RENDER_SIZE})")
    s.add_argument("--max-iterations", type=_number(int, 1, 1 << 20, "a whole number"), default=4096,
                   metavar="N",
                   help="iteration cap of the exact variant (default 4096); capped pixels count as not converged")
    kind = s.add_mutually_exclusive_group()
    kind.add_argument("--step-map", action="store_true", default=None,
                      help="IN is an RGBA step map made elsewhere (maps from csm-assets are recognized)")
    kind.add_argument("--height-map", dest="step_map", action="store_false",
                      help="IN holds heights even though it has four channels (read as luminance, or --channel)")
    s.add_argument("--invert", action="store_true", help="height-map IN is a depth map (white = deep)")
    s.add_argument("--no-tile", action="store_true", help="the texture does not repeat")
    s.add_argument("--bits", type=int, choices=(8, 16, 32), default=8,
                   help="bits of the step map made from a height map (default 8)")
    s.add_argument("--max-ratio", type=_number(float, 1e-9, 1e9, "a number"), metavar="R",
                   help="cone ratio of G = 1 (default: from the step map, else 1.0)")
    s.add_argument("--channel", metavar="C", help="height-map channel to read (index or name)")
    s.add_argument("--no-bilinear-safe", action="store_true",
                   help="make the step map of a height map exactly as the paper does, without the "
                        "bilinear safety pass that convert applies")
    s.add_argument("--min-step", type=_number(float, 1e-3, 1.0, "a number"), metavar="S",
                   help="the exact variant's minimum step in texels (default 0.25 for bilinear-safe "
                        "maps, else the paper's 1; scenes: their minStep)")
    verify_shadows_cli.configure(s)


def run(args) -> int:
    """Verify IN and print the report; the exit code (GLUnavailable and the library's errors
    propagate to the CLI's mapping)."""
    from .render import VARIANTS
    from .trade import parse_views
    from .verify import DEFAULT_VIEWS, format_report, verify_file

    variants = None
    if args.variant:
        variants = list(VARIANTS) if "all" in args.variant else list(dict.fromkeys(args.variant))
    views = parse_views(args.views) if args.views else list(DEFAULT_VIEWS)
    shadow_lights = verify_shadows_cli.lights(args)  # checks the shadow options before any drawing
    common = dict(size=args.size, max_error=args.max_error, images=args.images, views=views,
                  max_iterations=args.max_iterations)
    if Path(args.input).suffix.lower() in SCENE_SUFFIXES:
        from .verify_scene import format_scene_report, verify_scene

        reports = [verify_scene(Path(args.input), variants=variants, steps=args.steps, min_step=args.min_step,
                                cameras=not args.no_cameras, **common)]
        text = format_scene_report(reports[0])
    else:
        reports = [verify_file(Path(args.input), invert=args.invert, as_step_map=args.step_map,
                               bits=args.bits, max_ratio=args.max_ratio, tile=False if args.no_tile else None,
                               channel=args.channel, depth=args.depth, bilinear_safe=not args.no_bilinear_safe,
                               min_step=args.min_step, variants=variants or ["exact"], steps=args.steps or STEPS,
                               **common)]
        text = format_report(reports[0])
    if shadow_lights:
        from .verify_shadows import format_shadow_report

        scene = Path(args.input).suffix.lower() in SCENE_SUFFIXES
        reports.append(verify_shadows_cli.run(args, scene=scene, views=views, steps=args.steps or (None if scene else STEPS),
                                              variant=(variants or [None if scene else "exact"])[0]))
        text += "\n" + format_shadow_report(reports[-1])
    if args.json:
        data = reports[0].to_dict()
        if shadow_lights:
            data["shadows"] = reports[-1].to_dict()
        sys.stdout.write(json.dumps(data, indent=2) + "\n")
    else:
        sys.stdout.write(text + "\n")
    return 0 if all(r.passed for r in reports) else EXIT_OVER_BUDGET
