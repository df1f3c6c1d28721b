"""The flags that decide a conversion's outputs and which warnings fail it (shared by
``convert``, ``check``, ``hook`` and ``config show``), and the
:class:`~csm_assets.convert.pipeline.ConvertOptions` each scene gets from them and its project
configuration (:mod:`csm_assets.config`; flags given win): a configuration's values are
checked as their flags are.

Every flag that decides a setting defaults to None ("not given"), so that the configuration
decides what the command line leaves open; its dest is the ConvertOptions field it sets."""

from __future__ import annotations

import functools
import os

from ..convert.options import PICK_COSTS, TEXTURES, ConvertOptions
from ..errors import FormatError, no_file
from ..height_source import DEFAULT_DEPTH
from ..packing import MAP_CONES
from ..step_levels import LEVEL_MODES
from ..render.renderer import VARIANTS
from ..verify.maps import MAX_STEPS, RELAXED_DEFAULT_STEPS, STEPS
from ..warning_codes import checked_codes
from .common import BIT_DEPTHS, POSITIVE, Parser, UsageError, number

DEFAULTS = ConvertOptions()


def add_scene_flags(c) -> None:
    """The flags that decide a conversion's outputs (shared by convert, check and hook)."""
    c.add_argument("--height", action="append", metavar="MATERIAL=PATH",
                   help="use PATH as MATERIAL's height texture, white = high (repeatable); the depth comes "
                        "from the material's own displacement factor if the scene states one, else --depth; "
                        "=PATH (or \"\"=PATH) names a material whose name is empty (OBJ's bare newmtl); "
                        "PATH name.<UDIM>.png: a UDIM set, a step map per tile (USD scenes)")
    c.add_argument("--depth-map", action="append", metavar="MATERIAL=PATH",
                   help="as --height, for a depth map (white = deep): heights are 1 - value")
    c.add_argument("--channel", metavar="C",
                   help="the channel to read of the --height/--depth-map textures: index or name (default: grey, "
                        "or the luminance of colour); a tangent-space normal map named there is refused without it")
    c.add_argument("--config", metavar="FILE",
                   help="the project configuration for every scene (default: each scene's nearest csm-assets.toml, "
                        "or pyproject.toml with [tool.csm-assets]); its folder is the project root")
    c.add_argument("--bits", type=int, choices=BIT_DEPTHS,
                   help="step maps: 8 or 16-bit PNG, or 32-bit float EXR (OBJ and USD only) (default: per map, the "
                        "fewest whose rounding of the heights verify cannot see at the material's depth: 8 for "
                        "most, 16 for deep relief on a large texture with heights finer than 8 bits)")
    c.add_argument("--max-ratio", type=POSITIVE, metavar="R",
                   help=f"as for stepmap (default {DEFAULTS.max_ratio:g})")
    c.add_argument("--depth", action="append", metavar="D|MATERIAL=D",
                   help="texture-space depth (uv units per unit of height) for every material, or with "
                        "MATERIAL= for one (repeatable; default: the displacement factor over the mesh's size "
                        f"per uv unit, or {DEFAULT_DEPTH:g} where the scene states no factor; =D names a material "
                        "whose name is empty); 2^-24 to 2^24 texels deep on its texture (D x its longer side)")
    tile = c.add_mutually_exclusive_group()
    tile.add_argument("--tile", dest="tile", action="store_true", default=None,
                      help="treat every height texture as repeating")
    tile.add_argument("--no-tile", dest="tile", action="store_false",
                      help="treat none as repeating (default: each texture's own wrap mode)")
    c.add_argument("--max-error", type=POSITIVE, metavar="E",
                   help="per material, the cheapest shader variant and step count whose p95 error is at "
                        "most E texels at every view, measured on its own step map (see bench trade)")
    c.add_argument("--variant", choices=tuple(VARIANTS), metavar="V",
                   help=f"shader variant written into the materials: {', '.join(VARIANTS)} (default "
                        f"{DEFAULTS.variant}; with --max-error: pick only among V's step counts)")
    c.add_argument("--steps", type=number(int, 1, MAX_STEPS), metavar="N",
                   help=f"steps of loop/fixed, linear steps of pom/relief, search steps of relaxed (default "
                        f"{STEPS}, relaxed {RELAXED_DEFAULT_STEPS}, as verify; none for exact and parallax; with "
                        "--max-error: pick only among variants at N steps)")
    c.add_argument("--cones", choices=MAP_CONES,
                   help="conservative cones (every variant; default), relaxed cones (drawn by the relaxed "
                        "variant only, which becomes the default; --max-error picks among its step counts) or "
                        "quadrant cones (two images per step map, drawn by the quadrant variant only, which "
                        "becomes the default)")
    c.add_argument("--levels", choices=LEVEL_MODES,
                   help="also write each step map's level chain (GL mip sizes, exact cones per level) in one more "
                        "image beside it, named in the material: average (2x2-averaged heights; default), max "
                        "(max-filtered: never below the map's surface) or none; UDIM sets get none; see "
                        "docs/reference/levels.md")
    c.add_argument("--pick-cost", choices=PICK_COSTS,
                   help="what --max-error's pick minimises among the settings that meet E: fetches (mean texture "
                        "fetches per pixel; default) or block (the mean over 8x4 pixel blocks of the block's "
                        "largest count: a GPU waits for a block's slowest ray)")
    c.add_argument("--textures", choices=TEXTURES,
                   help="reference: the output names the scene's textures where they are, by a relative path "
                        "(lean outputs; a texture outside the project root or in an output folder is copied); "
                        "copy: copies them into the output folder, self-contained (default: reference for "
                        "outputs beside the scene, <stem>_<ext>_csm/, as hook writes them; copy for any other "
                        "output folder)")
    c.add_argument("--regenerate-tangents", action="store_true", default=None, help="replace tangents the file has")
    c.add_argument("--allow-outside-paths", dest="allow_outside", action="store_true", default=None,
                   help="let scenes use files outside their project root (refused by default; the root is the "
                        "configuration's folder, else the git repository's, else the scene's folder)")
    c.add_argument("--no-bilinear-safe", dest="bilinear_safe", action="store_false", default=None,
                   help="exact step maps as the paper makes them, and its one-texel minimum step "
                        "(default: G is each texel's 3x3 minimum and the minimum step 0.25 texel, "
                        "which holds on noise-like maps at grazing views)")
    c.add_argument("--self-shadow", action="store_true", default=None,
                   help="materials shade themselves: a shadow ray from each hit toward the light, stepped with "
                        "the same cones (selfShadow in the material; off by default)")
    c.add_argument("--light-size", type=number(float, low=0, what="an angle in radians"), metavar="R",
                   help=f"with --self-shadow, the light's angular radius in radians: 0 = hard shadows, > 0 = a "
                        f"soft penumbra (default {DEFAULTS.light_size:g})")


def add_warning_flags(c, strict: str) -> None:
    """``--strict``, ``--error-on CODE``, ``--ignore CODE`` (codes: docs/reference/warnings.md)."""
    c.add_argument("--strict", action="store_true", default=None, help=strict)
    c.add_argument("--error-on", action="append", metavar="CODE",
                   help="warnings of CODE are errors as under --strict, whatever their severity (repeatable; "
                        "codes such as CSM205 are listed in docs/reference/warnings.md)")
    c.add_argument("--ignore", action="append", metavar="CODE",
                   help="warnings of CODE are neither shown nor errors (repeatable)")


def resolver(args):
    """The :class:`~csm_assets.config.settings.Resolver` of the parsed flags: what each
    scene's configuration says, with the flags given on top."""
    from ..config.load import option_fields
    from ..config.settings import Resolver, command_line_values

    heights, depth, depths = height_flags(args)
    given = {f.name: getattr(args, f.name) for f in option_fields().values()
             if f.name != "depth" and getattr(args, f.name, None) is not None}
    for name, flag in (("error_on", "--error-on"), ("ignore", "--ignore")):  # codes, upper case
        if name in given:
            try:
                given[name] = checked_codes(given[name], flag)
            except ValueError as e:
                raise UsageError(str(e)) from None
    if args.config is not None and not os.path.lexists(args.config):  # a FIFO, a link to nothing: load says
        raise UsageError(f"--config {args.config}: no such file")
    return Resolver(command_line_values(given, heights, depth, depths), args.config, check_value)


def job_options(jobs, args, **extra) -> None:
    """Give each job its options: its scene's settings (:func:`resolver`) and ``extra``. A
    configuration entry that fails for one scene only (a texture it names is gone) gives that
    job an ``error``: it fails (exit 2), the others go on."""
    from ..config.files import ConfigError

    r = resolver(args)
    for job in jobs:
        try:
            job.options = r.options(job.scene, **extra)
        except ConfigError as e:
            if not any(p for sec in _sections(r, job.scene) for p in sec.problems if p is e):
                raise  # the file itself cannot be used: every scene, one error
            job.error = str(e)


def _sections(r, scene) -> list:
    project = r.project(scene)
    return project.applying(scene) if project else []


@functools.cache
def _scene_flags() -> Parser:
    p = Parser(prog="csm-assets", add_help=False)
    add_scene_flags(p)
    add_warning_flags(p, "")
    return p


def check_value(key: str, value):
    """A configuration's ``key = value`` checked as its option ``--key`` would check it on
    the command line (choices, ranges); values of flags without a value (true/false) and
    keys without an option pass as they are. ValueError with argparse's words otherwise."""
    if isinstance(value, bool):
        return value
    if key in ("error-on", "ignore"):  # warning codes, as --error-on/--ignore take them
        try:
            return checked_codes(value, key)
        except ValueError as e:
            raise ValueError(str(e).removeprefix(f"{key}: ")) from None
    items = value if isinstance(value, (list, tuple)) else [value]
    argv = [a for item in items for a in (f"--{key}", str(item))]
    try:
        parsed, extra = _scene_flags().parse_known_args(argv)
    except UsageError as e:
        raise ValueError(str(e).replace(f"argument --{key}: ", "")) from None
    if extra:  # not an option of these commands: the library checks it
        return value
    dest = next(iter(k for k, v in vars(parsed).items() if v is not None), None)
    return value if dest is None or isinstance(value, (list, tuple)) else getattr(parsed, dest)


def height_flags(args):
    """``--height``/``--depth-map`` MATERIAL=PATH and ``--depth`` D or MATERIAL=D, as
    (heights, depth for all, depths by material)."""
    from ..formats import format_module
    from ..height_source import HeightSpec, depth_option, height_option
    from ..udim import is_pattern, tile_files, tile_name

    heights = {}
    for flag, items, depth_map in (("--height", args.height, False), ("--depth-map", args.depth_map, True)):
        for item in items or []:
            name, path = height_option(flag, item)
            if name in heights:
                raise UsageError(f"material {name!r} is given two height textures")
            if is_pattern(path):  # a UDIM set: one tile at least
                if not tile_files(path):
                    raise FormatError(path, f"is a UDIM set with no tile (no file {tile_name(path.name, 1001)} ... "
                                            f"{tile_name(path.name, 1999)} beside it; named by {flag} {item})")
            elif path.is_dir():
                raise FormatError(path, f"is a folder, not a height texture (named by {flag} {item}); name the "
                                        "image file in it")
            elif not path.is_file():
                raise FormatError(path, f"{no_file(path)} (named by {flag} {item})")
            try:
                format_module(path)
            except FormatError as e:  # before any scene is read, not a warning per scene
                raise FormatError(path, f"{str(e)[len(e.path) + 2:]} (named by {flag} {item})") from None
            heights[name] = HeightSpec(path.absolute(), depth_map, getattr(args, "channel", None))  # recorded
            # relative to the project root
    if getattr(args, "channel", None) is not None and not heights:
        raise UsageError("--channel says which channel of the --height/--depth-map textures to read: name one")
    depth, depths = None, {}
    for item in args.depth or []:
        name, d = depth_option(item)
        if (name in depths) if name is not None else depth is not None:
            raise UsageError(f"--depth {item}: the depth of {'every material' if name is None else repr(name)} "
                             "is given twice")
        if name is None:
            depth = d
        else:
            depths[name] = d
    return heights, depth, depths
