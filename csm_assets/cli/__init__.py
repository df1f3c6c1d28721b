"""The ``csm-assets`` command line: parse, call the library, map errors to exit codes.

One module per command (:data:`COMMANDS`), each with ``add(subparsers)`` declaring its
arguments (defaults read from the library) and a ``run(args)`` that calls the library;
:mod:`.common` holds the shared pieces (exit codes, option types, the error mapping).

Exit codes: 0 done; 1 verify over budget / check stale / hook wrote; 2 bad arguments (usage);
3 input missing, unreadable, malformed or unsupported (and a warning that --strict or --error-on
makes an error; docs/reference/warnings.md);
4 output cannot be written (disk full, a clash, an output that would overwrite an input);
5 no OpenGL/EGL context; 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys

from .. import __version__
from . import bench, blender, check, config, convert, hook, stepmap, verify, view
from .common import (EXIT_INPUT, EXIT_INTERRUPTED, EXIT_NO_GL, EXIT_OK, EXIT_OUTPUT, EXIT_OVER_BUDGET,
                     EXIT_STALE, EXIT_USAGE, Parser, UsageError, run_command, warning_line)

COMMANDS = (stepmap, verify, convert, check, hook, config, bench, view, blender)  # in --help's order

__all__ = ["COMMANDS", "EXIT_INPUT", "EXIT_INTERRUPTED", "EXIT_NO_GL", "EXIT_OK", "EXIT_OUTPUT",
           "EXIT_OVER_BUDGET", "EXIT_STALE", "EXIT_USAGE", "UsageError", "build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="csm-assets", description=(
        "Turn height maps and scenes into exact Cone Step Mapping assets. Exit codes: "
        "0 done, 1 verify over budget / check stale / hook wrote, 2 bad arguments, 3 unreadable input "
        "(or a warning that --strict or --error-on makes an error), 4 unwritable output (disk full, a clash, "
        "an input in the way), "
        "5 no OpenGL context, 130 interrupted."))
    p.add_argument("--version", action="version", version=f"csm-assets {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for command in COMMANDS:
        command.add(sub)
    return p


def _notice(args) -> None:
    from ..kernels import notice_compiling

    if not getattr(args, "quiet", False):
        notice_compiling()  # one line on a terminal when a kernel compiles (a fresh install)


def main(argv=None) -> int:
    import warnings

    from ..allocator import fix_mmap_threshold
    from ..cstderr import own_stderr

    fix_mmap_threshold()  # freed band arrays go back to the system: peaks as the live arrays
    own_stderr()  # our lines never land in a thread's capture of C libraries' stderr
    warnings.showwarning = warning_line
    return run_command(build_parser(), argv, before=_notice)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
