"""The ``csm-assets`` command line: parse, call the library, map errors to exit codes.

Exit codes: 0 done; 1 verify over budget / check stale / hook wrote; 2 bad arguments (usage);
3 input missing, unreadable, malformed or unsupported (and, with --strict, any warning);
4 output cannot be written (disk full, a clash, an output that would overwrite an input);
5 no OpenGL/EGL context; 130 interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
from pathlib import Path

from . import __version__
from .atomic import atomic_path
from .bench import add_bench_parser
from .errors import FormatError, OutputError
from .formats import load_heightfield
from .kernels import notice_compiling
from .render import GLError, GLUnavailable
from .stepmap import DEFAULTS
from .view import add_view_parser

EXIT_OK, EXIT_USAGE, EXIT_INPUT, EXIT_OUTPUT, EXIT_INTERRUPTED = 0, 2, 3, 4, 130
EXIT_STALE = 1  # check: outputs missing or stale; hook: outputs were (re)written
EXIT_NO_GL = 5  # no OpenGL/EGL context (verify, convert --max-error)


class UsageError(Exception):
    """Arguments that parse but make no sense together (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one clear line, not usage plus message
        raise UsageError(message)


def _progress(label: str, quiet: bool):
    """A progress callback drawing one line on a terminal; None in scripts."""
    if quiet or not sys.stderr.isatty():
        return None
    start = time.perf_counter()

    def show(done: int, total: int) -> None:
        end = "\n" if done >= total else ""
        elapsed = time.perf_counter() - start
        sys.stderr.write(f"\r{label}: {100 * done // total:3d}% ({done}/{total} rows, {elapsed:.1f} s){end}")
        sys.stderr.flush()

    return show


def _same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    return a.exists() and b.exists() and os.path.samefile(a, b)


def cmd_stepmap(args) -> int:
    from .stepmap import make_step_map, save_step_map

    src, dst = Path(args.input), Path(args.output)
    if _same_file(src, dst):
        raise UsageError(f"output {dst} is the input; choose another path (inputs are never overwritten)")
    bits = args.bits if args.bits is not None else (32 if dst.suffix.lower() == ".exr" else DEFAULTS.bits)
    hf = load_heightfield(src, channel=args.channel, invert=args.invert, waterlevel=args.waterlevel)
    # raw altitudes (.hf, depth text) and holes -> unit heights; scale/offset travel with the map
    settings = DEFAULTS.replace(max_ratio=args.max_ratio, tile=False if args.no_tile else None, bits=bits,
                                bilinear_safe=args.bilinear_safe, source=src.name)
    sm = make_step_map(hf, settings, progress=_progress(f"cones {src.name}", args.quiet))
    save_step_map(sm, dst)
    if not args.quiet and sys.stderr.isatty():
        h, w = sm.shape
        sys.stderr.write(f"wrote {dst} ({w}x{h}, {bits}-bit, max_ratio {sm.settings.max_ratio:g})\n")
    return EXIT_OK


def _convert_options(args):
    from .convert import ConvertOptions

    heights, depth, depths = _height_flags(args)
    if args.variant is None:
        args.variant = "auto" if args.max_error is not None else "exact"
    return ConvertOptions(heights=heights, max_ratio=args.max_ratio, bits=args.bits, tile=args.tile,
                          depth=depth, depths=depths, regenerate_tangents=args.regenerate_tangents,
                          allow_outside=args.allow_outside_paths, variant=args.variant,
                          steps=args.steps or 0, max_error=args.max_error, bilinear_safe=args.bilinear_safe,
                          strict=getattr(args, "strict", False))


def _height_flags(args):
    """``--height``/``--depth-map`` MATERIAL=PATH and ``--depth`` D or MATERIAL=D, as
    (heights, depth for all, depths by material)."""
    from .height_source import HeightSpec

    heights = {}
    for flag, items, depth_map in (("--height", args.height, False), ("--depth-map", args.depth_map, True)):
        for item in items or []:
            name, sep, path = item.partition("=")
            if not sep or not name or not path:
                raise UsageError(f"{flag} takes MATERIAL=PATH, got {item!r}")
            if name in heights:
                raise UsageError(f"material {name!r} is given two height textures")
            if not Path(path).is_file():
                raise FormatError(path, f"no such file (named by {flag} {item})")
            heights[name] = HeightSpec(Path(path), depth_map)
    depth, depths = None, {}
    for item in args.depth or []:
        name, _, value = item.rpartition("=")
        try:
            d = _positive(value)
        except argparse.ArgumentTypeError as e:
            raise UsageError(f"--depth takes D or MATERIAL=D: {e}") from None
        if (name in depths) if name else depth is not None:
            raise UsageError(f"--depth {item}: the depth of {name or 'every material'} is given twice")
        if name:
            depths[name] = d
        else:
            depth = d
    return heights, depth, depths


def _batch_exit(report) -> int:
    kinds = {r.error_kind for r in report.results if r.status == "failed"}
    return (EXIT_OUTPUT if "output" in kinds else EXIT_NO_GL if "gl" in kinds else EXIT_USAGE if "usage" in kinds
            else EXIT_INPUT if kinds else EXIT_OK)


def _finish(report, args) -> None:
    """Warnings and errors to stderr, the report to --report / --json, the summary line."""
    for r in report.results:
        for warning in r.warnings:
            sys.stderr.write(f"csm-assets: warning: {warning}\n")
        if r.error:
            sys.stderr.write(f"csm-assets: error: {r.error}\n")
    if getattr(args, "report", None):
        _check_report_path(Path(args.report), report)
        with atomic_path(args.report) as tmp:
            tmp.write_text(json.dumps(report.to_dict(), indent=2) + "\n")
    if getattr(args, "json", False):
        print(json.dumps(report.to_dict(), indent=2))
    elif not args.quiet:
        sys.stdout.write(f"{report.summary()}\n")


def _check_report_path(path: Path, report) -> None:
    """OutputError when the report would overwrite a scene, an input or an output."""
    from .output_folder import check_not_input

    taken = [Path(r.scene) for r in report.results] + [Path(f) for r in report.results for f in r.written]
    check_not_input(path, [f for f in taken if f.exists()])
    for r in report.results:
        if r.status == "failed":
            continue
        from . import manifest

        try:
            known = manifest.load(r.out_dir)
        except manifest.ManifestError:
            continue
        e = known["scenes"].get(Path(r.scene).name, {})
        scene_dir = Path(r.scene).resolve().parent
        check_not_input(path, [scene_dir / k for k in e.get("inputs", {}) if (scene_dir / k).exists()])
        check_not_input(path, [Path(r.out_dir) / manifest.NAME])


def _early_report_check(args, jobs) -> None:
    """Refuse a --report that names a scene or a manifest before converting anything."""
    if getattr(args, "report", None):
        from .output_folder import check_not_input

        check_not_input(Path(args.report), [j.scene for j in jobs])
        if Path(args.report).name == "csm-manifest.json":
            raise OutputError(args.report, "the report would take the manifest's name; choose another file")


def cmd_convert(args) -> int:
    from . import batch

    opts = _convert_options(args)
    opts.force = args.force
    jobs = batch.plan(args.input, args.output)
    if not jobs:
        raise UsageError(f"no scene files ({', '.join(sorted(batch.SCENE_FORMATS))}) in {' '.join(args.input)}")
    _early_report_check(args, jobs)
    if len(jobs) > 1:
        opts.cache_dir = Path(args.output) / ".csm-cache"
    progress = None if args.quiet or args.json else batch.progress_printer()
    with batch.dask_executor(args.scheduler) if args.scheduler else contextlib.nullcontext() as executor:
        report = batch.run(jobs, opts, executor=executor, jobs_at_once=args.jobs, progress=progress)
    _finish(report, args)
    return _batch_exit(report)


def cmd_check(args) -> int:
    from . import batch

    jobs = batch.plan(args.paths, args.output)
    stale = batch.stale(jobs, _convert_options(args))
    for job, reason in stale:
        sys.stdout.write(f"stale: {job.scene} -> {job.out_dir}: {reason}\n")
    if not args.quiet:
        sys.stderr.write(f"csm-assets: {len(jobs) - len(stale)} of {len(jobs)} scene(s) up to date\n")
    return EXIT_STALE if stale else EXIT_OK


def cmd_hook(args) -> int:
    """pre-commit: regenerate stale outputs beside each scene; fail (1) when anything was written."""
    from . import batch

    jobs = batch.plan(args.paths, None)
    report = batch.run(jobs, _convert_options(args), jobs_at_once=args.jobs)
    _finish(report, args)
    for r in report.results:
        if r.written:
            sys.stderr.write(f"csm-assets: wrote {len(r.written)} file(s) for {r.scene} into {r.out_dir}; "
                             f"add them to the commit\n")
    code = _batch_exit(report)
    return code if code else (EXIT_STALE if report.wrote else EXIT_OK)


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def _count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return v


# --- verify: csm_assets.verify_cli ------------------------------------------------------------

def _add_verify(sub) -> None:
    from . import verify_cli

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
    verify_cli.configure(s)
    s.set_defaults(run=verify_cli.run)


def _unit(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a height in [0, 1], got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="csm-assets", description=(
        "Turn height maps and scenes into exact Cone Step Mapping assets. Exit codes: "
        "0 done, 1 verify over budget / check stale / hook wrote, 2 bad arguments, 3 unreadable input "
        "(or a warning under --strict), 4 unwritable output (disk full, a clash, an input in the way), "
        "5 no OpenGL context, 130 interrupted."))
    p.add_argument("--version", action="version", version=f"csm-assets {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
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
    s.add_argument("--bits", type=int, choices=(8, 16, 32),
                   help="8 or 16-bit integers, or 32-bit float (default: 32 for .exr, else 8)")
    s.add_argument("--max-ratio", type=_positive, default=DEFAULTS.max_ratio, metavar="R",
                   help=f"cone ratio stored as G = 1 (default {DEFAULTS.max_ratio:g}, as in the paper)")
    s.add_argument("--channel", metavar="C",
                   help="channel to read: index or name (default: grey, or luminance of colour)")
    s.add_argument("--bilinear-safe", dest="bilinear_safe", action="store_true", default=DEFAULTS.bilinear_safe,
                   help="safety pass for bilinear sampling: G becomes each texel's 3x3 minimum (render "
                        "with a 0.25-texel minimum step); the default, as in convert and verify")
    s.add_argument("--no-bilinear-safe", dest="bilinear_safe", action="store_false",
                   help="the paper's cones, exact at texel centres (render with a 1-texel minimum step)")
    s.add_argument("--waterlevel", type=_unit, metavar="W",
                   help="POV-Ray's waterlevel: raise heights below W (in [0, 1], after --invert) to W")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress, even on a terminal")
    s.set_defaults(run=cmd_stepmap)
    _add_verify(sub)

    c = sub.add_parser("convert", help="convert scenes: step maps, tangents and a CSM material",
                       description="Find every material's height texture in glTF/GLB, OBJ or USD scenes, "
                                   "write a packed step map per distinct texture, MikkTSpace tangents for "
                                   "the meshes that use them, and the scene with a CSM material into OUTDIR "
                                   "(never the input's folder). Several scenes or folders (searched "
                                   "recursively) go to OUTDIR/<folder>/<stem>_<ext>/, in parallel; scenes "
                                   "whose outputs are fresh (csm-manifest.json) are skipped.")
    c.add_argument("input", metavar="IN", nargs="+",
                   help="scene files (.gltf, .glb, .obj with its .mtl, .usda, .usdc, .usdz) or folders")
    c.add_argument("-o", "--output", metavar="OUTDIR", required=True, help="folder for the outputs")
    _scene_flags(c)
    c.add_argument("--force", action="store_true", help="convert even scenes whose outputs are fresh")
    c.add_argument("--jobs", type=_count, metavar="N", help="scenes converted at once, >= 1 (default: the cores)")
    c.add_argument("--strict", action="store_true",
                   help="warnings are errors: a scene with any warning fails (exit 3) and nothing of it is written")
    c.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on the Dask scheduler at ADDRESS (e.g. tcp://farm:8786) instead of locally")
    c.add_argument("--report", metavar="FILE", help="write a JSON report of every scene to FILE")
    c.add_argument("--json", action="store_true", help="print the JSON report on stdout")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    c.set_defaults(run=cmd_convert)

    k = sub.add_parser("check", help="exit 1 when converted outputs are missing or stale (writes nothing)",
                       description="For each scene (files or folders), compare its outputs' manifest with "
                                   "the scene, its textures and the settings. Prints one line per stale "
                                   "scene; exit 1 when any is stale or missing. Without -o the outputs are "
                                   "looked for beside each scene (<stem>_<ext>_csm/), as the pre-commit hook "
                                   "writes them.")
    k.add_argument("paths", metavar="PATH", nargs="+", help="scene files or folders")
    k.add_argument("-o", "--output", metavar="OUTDIR", help="where convert wrote the outputs")
    _scene_flags(k)
    k.add_argument("-q", "--quiet", action="store_true", help="no summary line")
    k.set_defaults(run=cmd_check)

    hk = sub.add_parser("hook", help="pre-commit hook: regenerate stale outputs beside each scene",
                        description="Convert each scene whose outputs beside it (<stem>_<ext>_csm/) are missing "
                                    "or stale; exit 1 when anything was written (add it to the commit), "
                                    "0 when all was fresh. Files inside output folders are ignored.")
    hk.add_argument("paths", metavar="PATH", nargs="*", help="scene files (pre-commit passes them)")
    _scene_flags(hk)
    hk.add_argument("--jobs", type=_count, metavar="N", help="scenes converted at once, >= 1 (default: the cores)")
    hk.add_argument("--strict", action="store_true", help="warnings are errors (exit 3), as for convert")
    hk.add_argument("-q", "--quiet", action="store_true", help="no summary line")
    hk.set_defaults(run=cmd_hook)
    add_bench_parser(sub)
    add_view_parser(sub)
    return p


def _scene_flags(c) -> None:
    """The flags that decide a conversion's outputs (shared by convert, check and hook)."""
    c.add_argument("--height", action="append", metavar="MATERIAL=PATH",
                   help="use PATH as MATERIAL's height texture, white = high (repeatable); the depth comes "
                        "from the material's own displacement factor if the scene states one, else --depth")
    c.add_argument("--depth-map", action="append", metavar="MATERIAL=PATH",
                   help="as --height, for a depth map (white = deep): heights are 1 - value")
    c.add_argument("--bits", type=int, choices=(8, 16, 32), default=DEFAULTS.bits,
                   help="step maps: 8 or 16-bit PNG (default 8), or 32-bit float EXR (OBJ and USD only)")
    c.add_argument("--max-ratio", type=_positive, default=DEFAULTS.max_ratio, metavar="R", help="as for stepmap")
    c.add_argument("--depth", action="append", metavar="D|MATERIAL=D",
                   help="texture-space depth (uv units per unit of height) for every material, or with "
                        "MATERIAL= for one (repeatable; default: the displacement factor over the mesh's size "
                        "per uv unit, or 0.1 where the scene states no factor)")
    tile = c.add_mutually_exclusive_group()
    tile.add_argument("--tile", dest="tile", action="store_true", default=None,
                      help="treat every height texture as repeating")
    tile.add_argument("--no-tile", dest="tile", action="store_false",
                      help="treat none as repeating (default: each texture's own wrap mode)")
    from .render import VARIANTS

    c.add_argument("--max-error", type=_positive, metavar="E",
                   help="per material, the cheapest shader variant and step count whose p95 error is at "
                        "most E texels at every view, measured on its own step map (see bench trade)")
    c.add_argument("--variant", choices=tuple(VARIANTS), metavar="V",
                   help=f"shader variant written into the materials: {', '.join(VARIANTS)} (default exact; "
                        "with --max-error: pick only among V's step counts)")
    c.add_argument("--steps", type=_count, metavar="N",
                   help="steps of loop/fixed, linear steps of pom/relief (default 16, as verify; none for exact "
                        "and parallax; with --max-error: pick only among variants at N steps)")
    c.add_argument("--regenerate-tangents", action="store_true", help="replace tangents the file has")
    c.add_argument("--allow-outside-paths", action="store_true",
                   help="let scenes use files outside their own folder (refused by default)")
    c.add_argument("--no-bilinear-safe", dest="bilinear_safe", action="store_false",
                   help="exact step maps as the paper makes them, and its one-texel minimum step "
                        "(default: G is each texel's 3x3 minimum and the minimum step 0.25 texel, "
                        "which holds on noise-like maps at grazing views)")


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings (numpy's, a library's) as one ``csm-assets: warning:`` line, without
    the source path and code line Python prints."""
    text = " ".join(str(message).split())
    (file or sys.stderr).write(f"csm-assets: warning: {category.__name__}: {text}\n")


def main(argv=None) -> int:
    import warnings

    warnings.showwarning = _warning_line
    parser = build_parser()
    args = None
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        if not getattr(args, "quiet", False):
            notice_compiling()  # one line on a terminal when a kernel compiles (a fresh install)
        return args.run(args)
    except UsageError as e:
        return _fail(f"error: {e} (see csm-assets --help)", EXIT_USAGE)
    except FormatError as e:
        return _fail(f"error: {e}", EXIT_INPUT)
    except OutputError as e:
        return _fail(f"error: {e}", EXIT_OUTPUT)
    except ValueError as e:  # arguments the library refused (bits for a format, ...)
        return _fail(f"error: {_named(args, e)}", EXIT_USAGE)
    except (GLUnavailable, GLError) as e:
        return _fail(f"error: {e}", EXIT_NO_GL)
    except KeyboardInterrupt:
        return _fail("interrupted; outputs were left as they were", EXIT_INTERRUPTED)
    except OSError as e:  # an OS error no reader turned into a FormatError: name its file
        name = f"{e.filename}: " if getattr(e, "filename", None) else ""
        return _fail(f"error: {name}{e.strerror or e}", EXIT_INPUT)
    except Exception as e:  # a defect: still one line, the traceback on request
        if os.environ.get("CSM_ASSETS_DEBUG"):
            raise
        return _fail(f"error: {_named(args, f'internal error ({type(e).__name__}: {e})')}; set "
                     "CSM_ASSETS_DEBUG=1 for the traceback and please report it", EXIT_INPUT)


def _named(args, message) -> str:
    """``message`` with the command's input in front when it names no file (numpy's and the
    OS's own messages: "embedded null byte", "strides is incompatible ...")."""
    text = str(message)
    given = getattr(args, "input", None) or getattr(args, "paths", None)
    given = [given] if isinstance(given, str) else list(given or [])
    if not given or any(str(Path(g).name) in text for g in given) or ": " in text.split(" ")[0]:
        return text
    return f"{' '.join(given)}: {text}"


def _fail(message: str, code: int) -> int:
    lines = [" ".join(t.split()) for t in str(message).splitlines() if t.strip()]
    sys.stderr.write(f"csm-assets: {'; '.join(lines)}\n")
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
