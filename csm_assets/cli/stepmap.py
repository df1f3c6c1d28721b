"""``csm-assets stepmap IN -o OUT``: the packed step map of a height map
(:func:`csm_assets.stepmap.make_step_map`, saved by a :class:`~csm_assets.step_files.StepMapSaver`: level 0
is written while its levels are made)."""

from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from ..packing import MAP_CONES, SAFE_MIN_STEP
from ..step_levels import LEVEL_MODES
from ..stepmap import DEFAULTS
from .common import BIT_DEPTHS, EXIT_OK, POSITIVE, UsageError, add_quiet, number, progress
from ..printable import printable


def add(sub) -> None:
    s = sub.add_parser("stepmap", help="write the packed RGBA step map of a height map",
                       description="Write the packed RGBA step map (R height, G sqrt(cone ratio / max "
                                   "ratio), B/A slopes) of a height map. The format follows OUT's "
                                   "extension: .png (8/16-bit), .tga (8-bit), .tif (8/16/32), .exr (32).")
    s.add_argument("input", metavar="IN", help="height map: PNG, TGA, TIFF, EXR, JPEG, Rayshade .hf, "
                                                "z-buffer .txt/.etxt, POV-Ray .gif, Fractint .pot")
    s.add_argument("-o", "--output", metavar="OUT", required=True, help="packed map to write (never IN)")
    s.add_argument("--invert", action="store_true", help="IN is a depth map (white = deep): use 1 - value")
    s.add_argument("--no-tile", action="store_true",
                   help="the texture does not repeat: no wrap-around in distances and slopes")
    s.add_argument("--bits", type=int, choices=BIT_DEPTHS,
                   help="8 or 16-bit integers, or 32-bit float (default: 32 for .exr, else the fewest bits whose "
                        "rounding of the heights verify cannot see at its defaults: 8 for most maps, 16 for "
                        "deep relief on a large texture whose heights are finer than 8 bits)")
    s.add_argument("--max-ratio", type=POSITIVE, default=DEFAULTS.max_ratio, metavar="R",
                   help=f"cone ratio stored as G = 1 (default {DEFAULTS.max_ratio:g}, as in the paper)")
    s.add_argument("--channel", metavar="C",
                   help="channel to read: index or name (default: grey, or luminance of colour)")
    s.add_argument("--bilinear-safe", dest="bilinear_safe", action="store_true", default=DEFAULTS.bilinear_safe,
                   help="safety pass for bilinear sampling: G becomes each texel's 3x3 minimum (render "
                        f"with a {SAFE_MIN_STEP:g}-texel minimum step); "
                        f"{'the default' if DEFAULTS.bilinear_safe else 'off by default'}, as in convert and verify")
    s.add_argument("--no-bilinear-safe", dest="bilinear_safe", action="store_false",
                   help="the paper's cones, exact at texel centres (render with a 1-texel minimum step)")
    s.add_argument("--cones", choices=MAP_CONES, default=DEFAULTS.cones,
                   help=f"conservative cones (every variant), relaxed cones (the relaxed variant only: rays "
                        f"may enter the surface once) or quadrant cones (the quadrant variant only: four cones "
                        f"per texel in two images, OUT and OUT with '_q' before the extension); stored as the "
                        f"map's 'cones' (default {DEFAULTS.cones})")
    s.add_argument("--levels", choices=LEVEL_MODES, default=DEFAULTS.levels,
                   help="also write levels 1..n below the map (GL mip sizes, down to 1x1), each with exact cones "
                        "of its own heights, in one more image: OUT with '_levels' before the extension (and "
                        "its second image's, for quadrant cones): 'average' (2x2-averaged heights), 'max' "
                        "(max-filtered heights, never below the map's surface) or 'none' (the map alone; default "
                        f"{DEFAULTS.levels}); see docs/reference/levels.md")
    s.add_argument("--waterlevel", type=number(float, 0.0, 1.0, what="a height"), metavar="W",
                   help="POV-Ray's waterlevel: raise heights below W (in [0, 1], after --invert) to W")
    s.add_argument("--nodata", type=float, metavar="V",
                   help="image IN: texels of this stored value hold no height (holes, filled with the lowest "
                        "height); default: a TIFF's GDAL_NODATA tag, if any")
    s.add_argument("--json", action="store_true",
                   help="print what was written as JSON: size, settings, the bits and why they were chosen")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="search the cones in bands of rows on the Dask cluster at ADDRESS (tcp://HOST:PORT; "
                        "needs csm-assets[dask]): the same bytes as a local run")
    add_quiet(s, "no progress, even on a terminal")
    s.set_defaults(run=run)


def same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    return a.exists() and b.exists() and os.path.samefile(a, b)


def screen(src: Path, pixels) -> None:
    """The height-source detector (:mod:`csm_assets.height_source`), as convert runs it: a
    tangent-space normal map is refused (FormatError, exit 3: its step map would be nonsense);
    a colour image is one warning line (its luminance is used)."""
    from ..errors import FormatError
    from ..height_source import classify_stored

    verdict = classify_stored(pixels, src.stem)
    if verdict.kind == "normal":
        raise FormatError(src, f"is a tangent-space normal map ({verdict.reason}), not heights; name a --channel "
                               "to make a step map of one of its channels anyway")
    if verdict.kind == "photo":
        sys.stderr.write(f"csm-assets: warning: CSM107 {printable(src)}: is a colour image ({verdict.reason}), not a grey height "
                         "map; its luminance is used as heights (--channel picks one channel)\n")


def refuse_step_map(src: Path, description: str) -> None:
    """FormatError (exit 3) when ``src`` is a step map csm-assets wrote (its settings are in its
    description): its channels are no heights, and its height map is what to give."""
    from ..errors import FormatError
    from ..formats import step_map_meta

    meta = step_map_meta(description or "")
    if meta:
        source = f" ({meta['source']})" if meta.get("source") else ""
        raise FormatError(src, f"is a step map made by csm-assets (its settings are stored in it), not a height "
                               f"map; give the height map it was made from{source}")


def output_bits(dst: Path) -> tuple[int, ...]:
    """The step map bits ``dst``'s format holds (PNG 8 and 16, TGA 8, TIFF 8, 16 and 32, EXR 32);
    (8, 16) for a name no step map can take (its writer then refuses it)."""
    from ..formats.image import RGBA_DTYPES
    from ..stepmap import BITS

    return tuple(BITS[np.dtype(d)] for d in RGBA_DTYPES.get(dst.suffix.lower(), (np.uint8, np.uint16)))


def chooser(dst: Path, args):
    """How the bits are chosen (:func:`csm_assets.verify.bits.chooser`) once the cones are made: at
    verify's default depth and views, ``--bits`` kept (a warning when verify may fail with it), else
    the fewest bits ``dst`` holds whose cost verify cannot see (32 in an .exr, which holds only floats)."""
    from ..verify.bits import chooser as bits_chooser
    from ..verify.maps import verify_step_map
    from .common import default

    return bits_chooser(default(verify_step_map, "depth"), allowed=output_bits(dst), given=args.bits)


def written(dst: Path, cones: str, levels: str) -> list[Path]:
    """The files a map saved at ``dst`` with ``cones`` and ``levels`` takes: itself, a quadrant
    map's second image, and each image's levels (:func:`~csm_assets.stepmap.levels_path`)."""
    from ..stepmap import levels_path, second_path

    images = [dst, *([second_path(dst)] if cones == "quadrant" else [])]
    return images + ([levels_path(p) for p in images] if levels != "none" else [])


def run(args) -> int:
    from ..formats import FORMATS, load_heightfield
    from ..formats.image import read_pixels
    from ..dask_client import dask_executor
    from ..step_files import StepMapSaver
    from ..stepmap import levels_path, make_step_map, second_path, step_map_heights

    src, dst = Path(args.input), Path(args.output)
    if any(same_file(src, out) for out in written(dst, args.cones, args.levels)):
        raise UsageError(f"output {dst} (or its second image or levels) is the input; choose another path "
                         "(inputs are never overwritten)")
    image = read_pixels(src, describe=True) if FORMATS.get(src.suffix.lower()) == "image" else None  # one open
    if image is not None:
        refuse_step_map(src, image[2])
    hf = load_heightfield(src, channel=args.channel, invert=args.invert, waterlevel=args.waterlevel, image=image,
                          nodata=args.nodata)
    if image is not None and args.channel is None:
        screen(src, image[0])
    image = None  # the decoded file: its heights are in hf now
    # raw altitudes (.hf, depth text) and holes -> unit heights; scale/offset travel with the map
    settings = DEFAULTS.replace(max_ratio=args.max_ratio, tile=False if args.no_tile else None,
                                bilinear_safe=args.bilinear_safe, cones=args.cones, source=src.name,
                                levels=args.levels)
    heights, settings = step_map_heights(hf, settings)
    hf = None  # its float32 heights: the codes are what the cones are made from
    with StepMapSaver(dst) as saver:  # level 0 is written while its levels are made; all published at the end
        with dask_executor(args.scheduler) if args.scheduler else contextlib.nullcontext() as executor:
            sm = make_step_map(heights, settings, progress=progress(f"cones {src.name}", args.quiet),
                               choose=chooser(dst, args), executor=executor, level0=saver.start)
        heights = None
        choice, bits = sm.choice, sm.settings.bits
        if choice.warning:
            sys.stderr.write(f"csm-assets: warning: CSM304 {printable(dst)}: {choice.warning}\n")
        saver.finish(sm)
    h, w = sm.shape
    extra = written(dst, sm.settings.cones, sm.settings.levels if sm.levels else "none")[1:]
    also = "".join(f" and {p}" for p in extra)
    if args.json:
        second = second_path(dst) if sm.second is not None else None
        print(json.dumps({"input": str(src), "output": str(dst), "width": w, "height": h,
                          **({"second": str(second)} if second else {}),
                          **({"levels": str(levels_path(dst)), "level_count": len(sm.levels)} if sm.levels else {}),
                          **({"second_levels": str(levels_path(second))} if second and sm.levels else {}),
                          "settings": sm.settings.to_meta(), "bits": choice.to_dict()}, indent=2))
    elif not args.quiet and sys.stderr.isatty():
        why = "given" if choice.given else choice.reason
        sys.stderr.write(f"wrote {dst}{also} ({w}x{h}, {bits}-bit: {why}; max_ratio {sm.settings.max_ratio:g})\n")
    return EXIT_OK
