"""The ``csm-assets`` command line: parse, call the library, map errors to exit codes.

Exit codes: 0 done; 2 bad arguments (usage); 3 input missing, unreadable or
malformed; 4 output cannot be written; 130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from . import __version__
from .bench import add_bench_parser
from .errors import FormatError, OutputError
from .formats import load_heightfield, write_step_map
from .packing import step_map

EXIT_OK, EXIT_USAGE, EXIT_INPUT, EXIT_OUTPUT, EXIT_INTERRUPTED = 0, 2, 3, 4, 130


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
    src, dst = Path(args.input), Path(args.output)
    if _same_file(src, dst):
        raise UsageError(f"output {dst} is the input; choose another path (inputs are never overwritten)")
    bits = args.bits if args.bits is not None else (32 if dst.suffix.lower() == ".exr" else 8)
    hf = load_heightfield(src, channel=args.channel, invert=args.invert)
    tile = not args.no_tile
    packed = step_map(hf.data, tile=tile, max_ratio=args.max_ratio, bits=bits,
                      progress=_progress(f"cones {src.name}", args.quiet))
    write_step_map(packed, dst, {"max_ratio": args.max_ratio, "tile": [tile, tile], "bits": bits,
                                 "height_scale": 1.0, "height_offset": 0.0, "source": src.name})
    if not args.quiet and sys.stderr.isatty():
        h, w = hf.data.shape
        sys.stderr.write(f"wrote {dst} ({w}x{h}, {bits}-bit, max_ratio {args.max_ratio:g})\n")
    return EXIT_OK


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="csm-assets", description=(
        "Turn height maps and scenes into exact Cone Step Mapping assets. Exit codes: "
        "0 done, 2 bad arguments, 3 unreadable input, 4 unwritable output, 130 interrupted."))
    p.add_argument("--version", action="version", version=f"csm-assets {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    s = sub.add_parser("stepmap", help="write the packed RGBA step map of a height map",
                       description="Write the packed RGBA step map (R height, G sqrt(cone ratio / max "
                                   "ratio), B/A slopes) of a height map. The format follows OUT's "
                                   "extension: .png (8/16-bit), .tga (8-bit), .tif (8/16/32), .exr (32).")
    s.add_argument("input", metavar="IN", help="height map: PNG, TGA, TIFF, EXR or JPEG")
    s.add_argument("-o", "--output", metavar="OUT", required=True, help="packed map to write (never IN)")
    s.add_argument("--invert", action="store_true", help="IN is a depth map (white = deep): use 1 - value")
    s.add_argument("--no-tile", action="store_true",
                   help="the texture does not repeat: no wrap-around in distances and slopes")
    s.add_argument("--bits", type=int, choices=(8, 16, 32),
                   help="8 or 16-bit integers, or 32-bit float (default: 32 for .exr, else 8)")
    s.add_argument("--max-ratio", type=_positive, default=1.0, metavar="R",
                   help="cone ratio stored as G = 1 (default 1.0, as in the paper)")
    s.add_argument("--channel", metavar="C",
                   help="channel to read: index or name (default: grey, or luminance of colour)")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress, even on a terminal")
    s.set_defaults(run=cmd_stepmap)
    add_bench_parser(sub)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        return args.run(args)
    except UsageError as e:
        return _fail(f"error: {e} (see csm-assets --help)", EXIT_USAGE)
    except FormatError as e:
        return _fail(f"error: {e}", EXIT_INPUT)
    except OutputError as e:
        return _fail(f"error: {e}", EXIT_OUTPUT)
    except ValueError as e:  # arguments the library refused (bits for a format, ...)
        return _fail(f"error: {e}", EXIT_USAGE)
    except KeyboardInterrupt:
        return _fail("interrupted; outputs were left as they were", EXIT_INTERRUPTED)


def _fail(message: str, code: int) -> int:
    sys.stderr.write(f"csm-assets: {message}\n")
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
