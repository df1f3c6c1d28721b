"""``csm-assets hook [PATH...]``: the pre-commit hook; regenerate stale outputs beside each
scene (:func:`csm_assets.convert.batch.run`) and fail (1) when anything was written."""

from __future__ import annotations

import sys
from pathlib import Path

from .common import EXIT_OK, EXIT_STALE, add_quiet
from .scenes import (add_jobs, add_removed_inputs, add_scene_flags, add_warning_flags, batch_exit, batch_progress, finish,
                     job_options)


def add(sub) -> None:
    hk = sub.add_parser("hook", help="pre-commit hook: regenerate stale outputs beside each scene",
                        description="Convert each scene whose outputs beside it (<stem>_<ext>_csm/) are missing "
                                    "or stale; exit 1 when anything was written (add it to the commit), "
                                    "0 when all was fresh. A scene without relief (no height texture) is "
                                    "skipped and nothing is written for it. Files inside output folders (a folder "
                                    "holding a csm-manifest.json) are ignored. Settings come from each scene's "
                                    "project configuration (csm-assets.toml), the flags given on top.")
    hk.add_argument("paths", metavar="PATH", nargs="*", help="scene files (pre-commit passes them)")
    add_scene_flags(hk)
    add_jobs(hk)
    add_removed_inputs(hk)
    add_warning_flags(hk, "warnings that mean the output may be wrong or incomplete are errors (exit 3), as for "
                          "convert")
    hk.add_argument("--json", action="store_true", help="print the JSON report on stdout (every scene, its status "
                                                         "and files; the orphans removed)")
    add_quiet(hk, "no progress or summary line")
    hk.set_defaults(run=run)


def run(args) -> int:
    from ..convert import batch

    from ..convert import orphans
    from ..convert.lost_relief import record_of, waits_for

    parts: dict = {}
    jobs = batch.plan(args.paths, None, parts, dependents=True, removed=args.removed_inputs)
    job_options(jobs, args, relief_only=True)
    progress, stages, line = batch_progress(args, log=False)
    try:
        report = batch.run(jobs, jobs_at_once=args.jobs, progress=progress, stages=stages)
    finally:
        if line is not None:
            line.close()
    states = {Path(r.out_dir).resolve(): r.status for r in report.results if r.out_dir}
    gone = [(orphan, files) for orphan in orphans.find(args.paths, jobs, states, parts)
            if (files := orphans.remove(orphan)) is not None]
    # a skipped scene's or a removed entry's waiting record: its manifest read once
    records = {id(r): record_of(r.out_dir, Path(r.scene).name) for r in report.results
               if r.status == "skipped" or r.removed}
    if not (args.quiet or args.json):
        for r in report.results:
            if r.status == "skipped":
                record = records[id(r)]
                waits = f" ({waits_for(record)})" if record else ""
                sys.stdout.write(f"{batch.SKIPPED}: {r.scene}{waits}\n")
    finish(report, args, {"orphans": [{**o.to_dict(), "removed": [str(f) for f in files]} for o, files in gone]})
    for r in report.results:
        if r.removed or r.status == "skipped" and r.written:  # a scene that lost its relief, or its record
            record = records[id(r)]
            kept = f"its manifest is kept, {waits_for(record)}" if record else "nothing is kept"
            if record is not None and not r.removed:
                sys.stderr.write(f"csm-assets: {r.scene} has no relief ({waits_for(record)}): its record in "
                                 f"{r.out_dir} was written; add it to the commit\n")
            else:
                sys.stderr.write(f"csm-assets: {r.scene} lost its relief: removed {len(r.removed)} file(s) from "
                                 f"{r.out_dir}, {kept}; stage the change\n")
        elif r.written:
            sys.stderr.write(f"csm-assets: wrote {len(r.written)} file(s) for {r.scene} into {r.out_dir}; "
                             f"add them to the commit\n")
    for orphan, files in gone:
        sys.stderr.write(f"csm-assets: removed {len(files)} file(s) of {orphan.scene} from {orphan.out_dir}: "
                         f"{orphan.reason}; stage the removal\n")
    code = batch_exit(report)  # an entry removed changed its manifest, even with no file of its own left
    return code if code else (EXIT_STALE if report.wrote or gone else EXIT_OK)
