"""``csm-assets check PATH...``: exit 1 when converted outputs are missing or stale
(:func:`csm_assets.convert.survey.survey`; writes nothing)."""

from __future__ import annotations

import sys

from .common import EXIT_OK, EXIT_STALE, add_quiet
from .scenes import add_scene_flags, job_options


def add(sub) -> None:
    k = sub.add_parser("check", help="exit 1 when converted outputs are missing or stale (writes nothing)",
                       description="For each scene (files or folders), compare its outputs' manifest with "
                                   "the scene, its textures and the settings. Prints one line per stale "
                                   "scene; exit 1 when any is stale or missing. Without -o the outputs are "
                                   "looked for beside each scene (<stem>_<ext>_csm/), as the pre-commit hook "
                                   "writes them. A scene without relief (no height texture) is skipped, not "
                                   "stale. Settings come from each scene's project configuration "
                                   "(csm-assets.toml), the flags given on top, as for convert and hook.")
    k.add_argument("paths", metavar="PATH", nargs="+", help="scene files or folders")
    k.add_argument("-o", "--output", metavar="OUTDIR", help="where convert wrote the outputs")
    add_scene_flags(k)
    add_quiet(k, "no summary line")
    k.set_defaults(run=run)


def run(args) -> int:
    from ..convert import batch
    from ..convert.survey import survey

    jobs = batch.plan(args.paths, args.output)
    job_options(jobs, args, relief_only=True)
    states = survey(jobs)
    stale = [(job, reason) for job, state, reason in states if state == "stale"]
    skipped = sum(state == "skipped" for _, state, _ in states)
    for job, reason in stale:
        sys.stdout.write(f"stale: {job.scene} -> {job.out_dir}: {reason}\n")
    if not args.quiet:
        also = f", {skipped} {batch.SKIPPED}" if skipped else ""
        sys.stderr.write(f"csm-assets: {len(jobs) - len(stale) - skipped} of {len(jobs)} scene(s) up to date"
                         f"{also}\n")
    return EXIT_STALE if stale else EXIT_OK
