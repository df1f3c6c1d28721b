"""``csm-assets verify --shadows``: its arguments and how it runs beside verify's hit check.

With ``--shadows``, verify also draws each view with self-shadowing under every light of
``--light-elevation`` x ``--light-azimuth`` (default: elevations 10, 30, 50, 80 x
azimuths 0, 120, 240 degrees) and compares the hard answer with the exact shadows
(:mod:`csm_assets.verify_shadows`, scenes: :mod:`csm_assets.verify_shadows_scene`); over
``--max-disagreement`` percent of relief pixels outside the edge band at any view and
light, verify exits 1. Bad values raise ValueError (the CLI's exit 2).
"""

from __future__ import annotations

import math
from pathlib import Path

from .verify_shadows import LIGHT_AZIMUTHS, LIGHT_ELEVATIONS, LIGHT_SIZE, MAX_DISAGREEMENT


def configure(s) -> None:
    """Add the self-shadowing arguments to verify's sub-parser ``s``."""
    g = s.add_argument_group("self-shadowing")
    g.add_argument("--shadows", action="store_true",
                   help="also verify self-shadows: the shader's hard answer against exact shadows per view and "
                        "light (relief pixels outside a one-texel band at shadow edges), and its soft term")
    g.add_argument("--light-elevation", nargs="+", type=float, metavar="DEG",
                   help="light elevations above the surface in degrees, -90..90 (default "
                        f"{' '.join(f'{e:g}' for e in LIGHT_ELEVATIONS)}); 90: straight above")
    g.add_argument("--light-azimuth", nargs="+", type=float, metavar="DEG",
                   help=f"light azimuths in degrees (default {' '.join(f'{a:g}' for a in LIGHT_AZIMUTHS)}); "
                        "on a map 0 is +u")
    g.add_argument("--light-size", type=float, metavar="RAD",
                   help=f"the light's angular radius in radians, 0..0.5, for the soft term (default: a scene "
                        f"material's lightSize, else {LIGHT_SIZE:g}); 0: hard")
    g.add_argument("--max-disagreement", type=float, default=100 * MAX_DISAGREEMENT, metavar="PCT",
                   help="budget: the largest share of relief pixels, in percent, whose lit/shadowed state may "
                        f"differ from the exact one at any view and light (default {100 * MAX_DISAGREEMENT:g})")


def lights(args) -> list[tuple[float, float]]:
    """The (elevation, azimuth) pairs the arguments ask for; ValueError for values out of range
    or light options without ``--shadows``."""
    given = [a for a in ("light_elevation", "light_azimuth", "light_size") if getattr(args, a) is not None]
    if not args.shadows:
        if given or args.max_disagreement != 100 * MAX_DISAGREEMENT:
            raise ValueError("--light-elevation, --light-azimuth, --light-size and --max-disagreement need "
                             "--shadows")
        return []
    els = args.light_elevation or LIGHT_ELEVATIONS
    azs = args.light_azimuth or LIGHT_AZIMUTHS
    if not all(math.isfinite(e) and -90.0 <= e <= 90.0 for e in els):
        raise ValueError(f"--light-elevation takes degrees in -90..90, got {' '.join(map(str, els))}")
    if not all(math.isfinite(a) for a in azs):
        raise ValueError(f"--light-azimuth takes finite degrees, got {' '.join(map(str, azs))}")
    if args.light_size is not None and not (0.0 <= args.light_size <= 0.5):
        raise ValueError(f"--light-size takes radians in 0..0.5, got {args.light_size!r}")
    if not (0.0 <= args.max_disagreement <= 100.0):
        raise ValueError(f"--max-disagreement takes a percentage in 0..100, got {args.max_disagreement!r}")
    return [(float(e), float(a)) for e in els for a in azs]


def run(args, *, scene: bool, views, variant, steps):
    """The :class:`~csm_assets.verify_shadows.ShadowReport` of ``args.input`` (a scene, or a map
    read as verify reads it) with ``variant`` (scenes: None for each material's own)."""
    common = dict(lights=lights(args), size=args.size, views=views, max_iterations=args.max_iterations,
                  max_disagreement=args.max_disagreement / 100.0, images=args.images)
    if scene:
        from .verify_shadows_scene import verify_scene_shadows

        return verify_scene_shadows(Path(args.input), light_size=args.light_size, variant=variant, steps=steps,
                                    cameras=not args.no_cameras, min_step=args.min_step, **common)
    from .verify import load_packed
    from .verify_shadows import verify_shadows

    pixels, max_ratio, tile, min_step = load_packed(
        Path(args.input), invert=args.invert, as_step_map=args.step_map, bits=args.bits, max_ratio=args.max_ratio,
        tile=False if args.no_tile else None, channel=args.channel, bilinear_safe=not args.no_bilinear_safe,
        min_step=args.min_step)
    return verify_shadows(pixels, max_ratio=max_ratio, tile=tile, min_step=min_step, variant=variant, steps=steps,
                          depth=args.depth, source=Path(args.input).name,
                          light_size=LIGHT_SIZE if args.light_size is None else args.light_size, **common)
