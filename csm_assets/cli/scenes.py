"""What ``convert``, ``check`` and ``hook`` share: ``--jobs``, the progress on a terminal, the
batch report's printing and its exit code; the flags that decide each scene's settings and the
settings themselves come from :mod:`.scene_settings` (importable from here too)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..atomic import atomic_path
from ..errors import OutputError
from ..printable import printable
from ..warning_codes import line
from .common import COUNT, EXIT_INPUT, EXIT_NO_GL, EXIT_OK, EXIT_OUTPUT, EXIT_USAGE, stage_line
from .scene_settings import (add_scene_flags, add_warning_flags, check_value, height_flags,  # noqa: F401
                             job_options, resolver)  # (the commands take them from here)


def add_removed_inputs(c) -> None:
    """``--removed-inputs`` of ``check`` and ``hook`` (the pre-commit hooks pass it)."""
    c.add_argument("--removed-inputs", action="store_true",
                   help="also take every scene of the repository whose manifest records an input that is gone "
                        "(deleted or renamed: pre-commit never passes such a file); with no PATH, those only")


def add_jobs(c) -> None:
    c.add_argument("--jobs", type=COUNT, metavar="N", help="scenes converted at once, >= 1 (default: the cores)")


def batch_exit(report) -> int:
    """The exit code of a batch report: the worst failure kind, else 0."""
    kinds = {r.error_kind for r in report.results if r.status == "failed"}
    return (EXIT_OUTPUT if "output" in kinds else EXIT_NO_GL if "gl" in kinds else EXIT_USAGE if "usage" in kinds
            else EXIT_INPUT if kinds else EXIT_OK)


def batch_progress(args, log: bool):
    """``(progress, stages, line)`` for :func:`csm_assets.convert.batch.run`: on a terminal (not
    ``-q``/``--json``) a bar per finished scene and the stages of a scene converted in this
    process on one line (``line``, to close); off a terminal, with ``log``, one plain line per
    scene on stdout; else nothing."""
    from ..convert import batch

    quiet = args.quiet or getattr(args, "json", False)
    line = stage_line(quiet)
    if line is None:
        return (batch.progress_printer(sys.stdout) if log and not quiet else None), None, None
    bar = batch.progress_printer()

    def progress(done, total, result):
        line.hold()
        bar(done, total, result)

    return progress, line, line


def finish(report, args, extra: dict | None = None) -> None:
    """Warnings (``warning:`` or ``info:`` lines, with their codes) and errors to stderr (a scene
    that --strict/--error-on failed has one error line naming the codes), the report to
    --report / --json (with ``extra``'s keys), the summary line."""
    said = set()
    for r in report.results:
        for notice in r.warnings:
            sys.stderr.write(line(notice))
        if r.error and r.error not in said:  # a configuration entry failing several scenes: once
            said.add(r.error)
            sys.stderr.write(f"csm-assets: error: {printable(r.error)}\n")
    if getattr(args, "report", None):
        check_report_path(Path(args.report), report)
        with atomic_path(args.report) as tmp:
            tmp.write_text(json.dumps({**report.to_dict(), **(extra or {})}, indent=2) + "\n")
    if getattr(args, "json", False):
        print(json.dumps({**report.to_dict(), **(extra or {})}, indent=2))
    elif not args.quiet:
        for r in report.results:  # bits chosen above 8: say why (the JSON report says it for every map)
            for name, p in r.picks.items():
                if p.get("bits", 8) > 8 and p.get("bits_reason", "given") != "given":
                    sys.stdout.write(f"{r.scene}: material {name!r}: {p['bits']}-bit step map: {p['bits_reason']}\n")
        sys.stdout.write(f"{report.summary()}\n")


def check_report_path(path: Path, report) -> None:
    """OutputError when the report would overwrite a scene, an input or an output."""
    from ..convert import manifest
    from ..convert.output_folder import check_not_input

    taken = [Path(r.scene) for r in report.results] + [Path(f) for r in report.results for f in r.written]
    check_not_input(path, [f for f in taken if f.exists()])
    for r in report.results:
        if r.status == "failed":
            continue
        try:
            known = manifest.load(r.out_dir)
        except manifest.ManifestError:
            continue
        e = known["scenes"].get(Path(r.scene).name, {})
        root = manifest.recorded_root(e, r.scene, r.out_dir)
        check_not_input(path, [root / k for k in e.get("inputs", {}) if (root / k).exists()])
        check_not_input(path, [Path(r.out_dir) / manifest.NAME])


def early_report_check(args, jobs) -> None:
    """Refuse a --report that names a scene or a manifest before converting anything."""
    if getattr(args, "report", None):
        from ..convert import manifest
        from ..convert.output_folder import check_not_input

        check_not_input(Path(args.report), [j.scene for j in jobs])
        if Path(args.report).name == manifest.NAME:
            raise OutputError(args.report, "the report would take the manifest's name; choose another file")
