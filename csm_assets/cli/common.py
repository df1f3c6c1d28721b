"""The pieces every command shares: exit codes, the parser that fails in one line, the
ranged-number argument type, ``-q``, the progress lines (rows of one map; the stages of a
conversion), and the mapping of errors to exit codes (:func:`run_command`)."""

from __future__ import annotations

import argparse
import inspect
import math
import os
import sys
import threading
import time
from pathlib import Path

from ..errors import FormatError, OutputError
from ..printable import printable
from ..render.renderer import GLError, GLUnavailable
from ..stepmap import BITS

EXIT_OK, EXIT_USAGE, EXIT_INPUT, EXIT_OUTPUT, EXIT_INTERRUPTED = 0, 2, 3, 4, 130
EXIT_STALE = EXIT_OVER_BUDGET = 1  # verify: over budget; check: outputs stale; hook: outputs were written
EXIT_NO_GL = 5  # no OpenGL/EGL context (verify, convert --max-error)


class UsageError(Exception):
    """Arguments that parse but make no sense together (exit code 2)."""


DOCS_PAGE = "docs/reference/cli"  # the command-line reference, a page per command generated from these parsers


def docs_pointer(prog: str) -> str:
    """The line ending ``PROG --help``: the command's page of the reference, relative to the
    project (``csm-assets convert`` -> ``docs: docs/reference/cli/convert.md``, ``csm-assets bench
    cones`` -> ``docs: docs/reference/cli/bench.md#bench-cones``, ``csm-assets`` -> its index)."""
    words = prog.split()[1:]
    if not words:
        return f"docs: {DOCS_PAGE}/index.md"
    return f"docs: {DOCS_PAGE}/{words[0]}.md" + (f"#{'-'.join(words)}" if len(words) > 1 else "")


class Parser(argparse.ArgumentParser):
    """argparse with one clear line instead of usage plus message (raises :class:`UsageError`);
    its help ends with the command's docs pointer (:func:`docs_pointer`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.epilog is None:
            self.epilog = docs_pointer(self.prog)

    def error(self, message):
        raise UsageError(message)


def number(kind=float, low=None, high=None, *, above=None, what=None):
    """An argparse type: ``kind`` (int or float) text, finite, in ``low..high`` (either end
    may be None: open) and strictly over ``above`` when given; a one-line error otherwise."""
    what = what or ("a whole number" if kind is int else "a number")
    if above is not None:
        bounds = f"> {above:g}"
    elif low is not None and high is not None:
        bounds = f"in {low:g}..{high:g}"
    else:
        bounds = f">= {low:g}" if low is not None else f"<= {high:g}" if high is not None else ""

    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (_finite(v) and (above is None or v > above) and (low is None or v >= low)
                and (high is None or v <= high)):
            finite = "a finite " + what[2:] if kind is float and what.startswith("a ") else what
            raise argparse.ArgumentTypeError(f"expected {finite} {bounds}".rstrip() + f", got {text!r}")
        return v

    parse.__name__ = what.replace(" ", "_")  # argparse names the type in "invalid X value"
    return parse


def _finite(v) -> bool:
    """Whether ``v`` is finite (an int too big for a float is not)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


BIT_DEPTHS = tuple(sorted(set(BITS.values())))  # a step map's bits: 8, 16 (integers), 32 (float)
POSITIVE = number(float, above=0)  # max ratio, depth, budgets
COUNT = number(int, low=1)  # jobs, steps


def default(func, name: str):
    """The library's default of ``func``'s parameter ``name`` (the CLI shows it, never restates it)."""
    return inspect.signature(func).parameters[name].default


def add_quiet(p, what: str = "no progress or summary") -> None:
    p.add_argument("-q", "--quiet", action="store_true", help=what)


def progress(label: str, quiet: bool):
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


class StageLine:
    """One line on a terminal's stderr, redrawn in place: ``label: stage 42% (done/total) 3.1 s``.
    Call it as ``line(stage, done, total)`` (a conversion's progress; total 0: no share known);
    a thread redraws the clock every ``tick`` s so a long stage visibly goes on. ``hold()``
    clears the line and stops the clock until the next call; ``close()`` ends it."""

    def __init__(self, label: str = "", tick: float = 0.5, stream=None):
        self.label, self.tick, self.stream = label, tick, stream or sys.stderr
        self.start = time.perf_counter()
        self.state: tuple[str, int, int] | None = None
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._clock, name="csm-progress", daemon=True)
        self.thread.start()

    def __call__(self, stage: str, done: int = 0, total: int = 0) -> None:
        with self.lock:
            self.state = (stage, done, total)
            self._draw()

    def _draw(self) -> None:
        stage, done, total = self.state
        share = f" {100 * done // total:3d}% ({done}/{total})" if total else ""
        head = f"{self.label}: " if self.label else ""
        self.stream.write(f"\r{head}{stage}{share} {time.perf_counter() - self.start:.1f} s\x1b[K")
        self.stream.flush()

    def _clock(self) -> None:
        while not self.stop.wait(self.tick):
            with self.lock:
                if self.state is not None:
                    self._draw()

    def hold(self) -> None:
        with self.lock:
            if self.state is not None:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
            self.state = None

    def close(self) -> None:
        self.hold()
        self.stop.set()
        self.thread.join()


def stage_line(quiet: bool, label: str = "") -> StageLine | None:
    """A :class:`StageLine` on a terminal's stderr; None with ``-q`` or off a terminal (pipes, CI logs)."""
    if quiet or not sys.stderr.isatty():
        return None
    return StageLine(label)


def warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings (numpy's, a library's) as one ``csm-assets: warning: CODE`` line, without
    the source path and code line Python prints: a csm-assets warning class's own code
    (:class:`~csm_assets.warning_codes.CodedWarning`), else CSM900 and the category's name."""
    from ..warning_codes import CodedWarning

    text = " ".join(str(message).split())
    if isinstance(category, type) and issubclass(category, CodedWarning):
        (file or sys.stderr).write(f"csm-assets: warning: {category.code} {text}\n")
    else:
        (file or sys.stderr).write(f"csm-assets: warning: CSM900 {category.__name__}: {text}\n")


def run_command(parser: argparse.ArgumentParser, argv, before=None) -> int:
    """Parse ``argv``, run the command (``args.run``) and map its errors to exit codes;
    ``before(args)`` runs first (the kernels' compile notice)."""
    args = None
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        if before is not None:
            before(args)
        return args.run(args)
    except UsageError as e:
        return fail(f"error: {e} (see csm-assets --help)", EXIT_USAGE)
    except FormatError as e:
        return fail(f"error: {e}", EXIT_INPUT)
    except OutputError as e:
        return fail(f"error: {e}", EXIT_OUTPUT)
    except ValueError as e:  # arguments the library refused (OptionError: bits for a format, ...)
        return fail(f"error: {named(args, e)}", EXIT_USAGE)
    except (GLUnavailable, GLError) as e:
        return fail(f"error: {e}", EXIT_NO_GL)
    except KeyboardInterrupt:
        return fail("interrupted; outputs were left as they were", EXIT_INTERRUPTED)
    except OSError as e:  # an OS error no reader turned into a FormatError: name its file
        name = f"{e.filename}: " if getattr(e, "filename", None) else ""
        return fail(f"error: {name}{e.strerror or e}", EXIT_INPUT)
    except MemoryError as e:  # past check_memory's estimate: still say what to lower
        detail = f" ({e})" if str(e) else ""
        return fail(f"error: {named(args, f'out of memory{detail}')}; lower CSM_ASSETS_MAX_TEXELS (and "
                    "CSM_ASSETS_MAX_VERTICES) to refuse inputs this big up front, or give the process more memory",
                    EXIT_INPUT)
    except Exception as e:  # a defect: still one line, the traceback on request
        if os.environ.get("CSM_ASSETS_DEBUG"):
            raise
        return fail(f"error: {named(args, f'internal error ({type(e).__name__}: {e})')}; set "
                    "CSM_ASSETS_DEBUG=1 for the traceback and please report it", EXIT_INPUT)


def named(args, message) -> str:
    """``message`` with the command's input in front when it names no file (numpy's and the
    OS's own messages: "embedded null byte", "strides is incompatible ...")."""
    text = str(message)
    if getattr(message, "path", None) and text.startswith(str(message.path)):
        return text  # names its file (a configuration's file:line)
    given = getattr(args, "input", None) or getattr(args, "paths", None)
    given = [given] if isinstance(given, str) else list(given or [])
    if not given or any(str(Path(g).name) in text for g in given) or ": " in text.split(" ")[0] \
            or text.startswith("--"):  # it names its option ("--scheduler ADDRESS: ...")
        return text
    return f"{' '.join(given)}: {text}"


def fail(message: str, code: int) -> int:
    """Write ``csm-assets: MESSAGE`` as one line on stderr (line breaks and other control
    characters escaped: a name from a file cannot start a line of its own); return ``code``."""
    sys.stderr.write(f"csm-assets: {printable(str(message).strip())}\n")
    return code


def view(text: str) -> tuple[float, float]:
    """An argparse type: ``EL[/AZ]``, elevation in (0, 90] degrees, azimuth any finite (default 0)."""
    el, _, az = str(text).partition("/")
    try:
        v = (float(el), float(az) if az else 0.0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ELEVATION[/AZIMUTH] in degrees, got {text!r}") from None
    if not (0.0 < v[0] <= 90.0 and math.isfinite(v[1])):
        raise argparse.ArgumentTypeError(f"a view's elevation must be in (0, 90] degrees, got {text!r}")
    return v


def add_views(p, views, what: str = "90: straight on") -> None:
    """``--views EL[/AZ]...``; ``views`` is the library's default list, shown in the help."""
    shown = " ".join(f"{el:g}/{az:g}" for el, az in views)
    p.add_argument("--views", nargs="+", type=view, metavar="EL[/AZ]",
                   help=f"views as elevation/azimuth in degrees ({what}; default {shown})")


def add_map_kind(p) -> None:
    """``--step-map | --height-map`` and ``--channel``: how a map IN is read when its kind is
    open (an RGBA image without csm-assets' settings; :func:`csm_assets.verify.maps.load_packed`)."""
    kind = p.add_mutually_exclusive_group()
    kind.add_argument("--step-map", action="store_true", default=None,
                      help="IN is an RGBA step map made elsewhere (maps from csm-assets are recognized)")
    kind.add_argument("--height-map", dest="step_map", action="store_false",
                      help="IN holds heights even though it has four channels (read as luminance, or --channel)")
    p.add_argument("--channel", metavar="C", help="height-map channel to read (index or name)")


def add_map_settings(p, scenes: str = "", several: bool = False) -> None:
    """``--max-ratio`` and ``--min-step`` of a map IN (a step map made elsewhere has no settings);
    ``several``: ``--min-step`` takes one value or more."""
    from ..packing import SAFE_MIN_STEP
    from ..stepmap import DEFAULTS

    p.add_argument("--max-ratio", type=number(float, 1e-9, 1e9), metavar="R",
                   help=f"cone ratio of G = 1 (default: from the step map, else {DEFAULTS.max_ratio:g})")
    more = (": several measure the variants it changes (exact, exact_interp, quadrant, relaxed) at each"
            if several else "")
    p.add_argument("--min-step", type=number(float, 1e-3, 1.0), metavar="S", nargs="+" if several else None,
                   help=f"the exact variant's minimum step in texels (default {SAFE_MIN_STEP:g} for bilinear-safe "
                        f"maps, else the paper's 1{scenes}){more}")
