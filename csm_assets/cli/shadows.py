"""``csm-assets verify --shadows``: the self-shadowing arguments of verify and how they run.

With ``--shadows``, verify also draws each view with self-shadowing under every light of
``--light-elevation`` x ``--light-azimuth`` and compares the hard answer with the exact
shadows (:func:`csm_assets.verify.shadows.verify_shadows`, scenes:
:func:`csm_assets.verify.shadows_scene.verify_scene_shadows`); over ``--max-disagreement``
percent of relief pixels outside the edge band at any view and light, verify exits 1.
"""

from __future__ import annotations

from pathlib import Path

from ..verify.shadows import LIGHT_AZIMUTHS, LIGHT_ELEVATIONS, LIGHT_SIZE, verify_shadows
from .common import UsageError, default, number

MAX_DISAGREEMENT = 100 * default(verify_shadows, "max_disagreement")  # percent


def add(s) -> None:
    """Add the self-shadowing arguments to verify's sub-parser ``s``."""
    g = s.add_argument_group("self-shadowing (--shadows)")
    g.add_argument("--shadows", action="store_true",
                   help="also verify self-shadows: the shader's hard answer against exact shadows per view and "
                        "light (relief pixels outside a one-texel band at shadow edges), and its soft term")
    g.add_argument("--light-elevation", nargs="+", type=number(float, -90.0, 90.0), metavar="DEG",
                   help="light elevations above the surface in degrees, -90..90 (90: straight above; default "
                        f"{' '.join(f'{e:g}' for e in LIGHT_ELEVATIONS)})")
    g.add_argument("--light-azimuth", nargs="+", type=number(float), metavar="DEG",
                   help="light azimuths in degrees, on a map 0 is +u (default "
                        f"{' '.join(f'{a:g}' for a in LIGHT_AZIMUTHS)})")
    g.add_argument("--light-size", type=number(float, 0.0, 0.5), metavar="RAD",
                   help="the light's angular radius in radians, 0..0.5, for the soft term (default: a scene "
                        f"material's lightSize, else {LIGHT_SIZE:g}); 0: hard")
    g.add_argument("--max-disagreement", type=number(float, 0.0, 100.0), metavar="PCT",
                   help="budget: the largest share of relief pixels, in percent, whose lit/shadowed state may "
                        f"differ from the exact one at any view and light (default {MAX_DISAGREEMENT:g})")


def lights(args) -> list[tuple[float, float]]:
    """The (elevation, azimuth) pairs asked for, [] without ``--shadows``; UsageError for
    light options without it (checked before anything is drawn)."""
    given = [a for a in ("light_elevation", "light_azimuth", "light_size", "max_disagreement")
             if getattr(args, a) is not None]
    if not args.shadows:
        if given:
            raise UsageError(f"--{given[0].replace('_', '-')} needs --shadows")
        return []
    return [(float(e), float(a)) for e in args.light_elevation or LIGHT_ELEVATIONS
            for a in args.light_azimuth or LIGHT_AZIMUTHS]


def run(args, *, scene: bool, views, variant, steps, loaded):
    """The :class:`~csm_assets.verify.shadows.ShadowReport` of ``args.input`` with ``variant``
    (scenes: None for each material's own); ``loaded``: what verify read, a scene's
    :func:`~csm_assets.verify.scene.load_primitives` or a map's ``(pixels, max_ratio, tile,
    min_step, second image or None)``."""
    budget = MAX_DISAGREEMENT if args.max_disagreement is None else args.max_disagreement
    common = dict(lights=lights(args), size=args.size, views=views, max_iterations=args.max_iterations,
                  max_disagreement=budget / 100.0, images=args.images, variant=variant, steps=steps)
    if scene:
        from ..verify.shadows_scene import verify_scene_shadows

        return verify_scene_shadows(Path(args.input), light_size=args.light_size, cameras=not args.no_cameras,
                                    min_step=args.min_step, loaded=loaded, **common)
    pixels, max_ratio, tile, min_step, second = loaded
    return verify_shadows(pixels, max_ratio=max_ratio, tile=tile, min_step=min_step, depth=args.depth, second=second,
                          source=Path(args.input).name,
                          light_size=LIGHT_SIZE if args.light_size is None else args.light_size, **common)
