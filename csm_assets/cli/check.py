"""``csm-assets check PATH...``: exit 1 when converted outputs are missing or stale
(:func:`csm_assets.convert.survey.survey`; writes nothing), 3 when fresh outputs were made with
warnings that ``--strict``/``--error-on`` make errors (as ``convert`` would fail)."""

from __future__ import annotations

import json
import sys

from ..warning_codes import Policy, line
from .common import EXIT_INPUT, EXIT_OK, EXIT_STALE, EXIT_USAGE, add_quiet, stage_line
from .scenes import add_removed_inputs, add_scene_flags, add_warning_flags, job_options


def add(sub) -> None:
    k = sub.add_parser("check", help="exit 1 when converted outputs are missing or stale (writes nothing)",
                       description="For each scene (files or folders), compare its outputs' manifest with "
                                   "the scene, its textures and the settings. Prints one line per stale "
                                   "scene; exit 1 when any is stale or missing, 3 when fresh outputs carry "
                                   "warnings that --strict or --error-on make errors. Without -o the outputs "
                                   "are looked for beside each scene (<stem>_<ext>_csm/), as the pre-commit "
                                   "hook writes them. A scene without relief (no height texture) is skipped, "
                                   "not stale. Settings come from each scene's project configuration "
                                   "(csm-assets.toml), the flags given on top, as for convert and hook.")
    k.add_argument("paths", metavar="PATH", nargs="*", help="scene files or folders (at least one, but with "
                                                           "--removed-inputs)")
    k.add_argument("-o", "--output", metavar="OUTDIR", help="where convert wrote the outputs")
    add_scene_flags(k)
    add_removed_inputs(k)
    add_warning_flags(k, "fresh outputs whose recorded warnings mean the output may be wrong or incomplete "
                         "fail (exit 3), as convert --strict would")
    k.add_argument("--json", action="store_true", help="print every scene's state (fresh, stale, skipped, error) and "
                                                        "reason, and the orphans, as JSON on stdout")
    add_quiet(k, "no progress or summary line")
    k.set_defaults(run=run)


def run(args) -> int:
    from ..convert import batch
    from ..convert.pipeline import regular_scene
    from ..convert.survey import survey

    from ..convert import orphans

    parts: dict = {}
    if not args.paths and not args.removed_inputs:
        sys.stderr.write("csm-assets: error: check: give scene files or folders (or --removed-inputs)\n")
        return EXIT_USAGE
    jobs = batch.plan(args.paths, args.output, parts, dependents=True, removed=args.removed_inputs)
    for job in jobs:  # a FIFO or a device named as a scene: exit 3 as convert and hook say, never read
        regular_scene(job.scene)
    job_options(jobs, args, relief_only=True)
    broken = [job for job in jobs if job.error]  # a configuration entry naming them fails: they alone
    jobs = [job for job in jobs if not job.error]
    for error in dict.fromkeys(job.error for job in broken):
        sys.stderr.write(f"csm-assets: error: {error}\n")
    progress = stage_line(args.quiet)
    try:
        states = survey(jobs, progress=progress, notices=(read := {}))
    finally:
        if progress is not None:
            progress.close()
    refused = [(job, reason) for job, state, reason in states if state == "error"]  # as hook refuses them
    for _, reason in refused:
        sys.stderr.write(f"csm-assets: error: {reason}\n")
    stale = [(job, reason) for job, state, reason in states if state == "stale"]
    skipped = sum(state == "skipped" for _, state, _ in states)
    lost = orphans.find(args.paths, jobs, {job.out_dir.resolve(): state for job, state, _ in states}, parts,
                        args.output)
    if args.json:
        rows = [*states, *((job, "error", job.error) for job in broken)]  # a broken config entry's too
        print(json.dumps({"scenes": [{"scene": str(job.scene), "out_dir": str(job.out_dir), "state": state,
                                      "reason": reason} for job, state, reason in rows],
                          "parts": {str(k): str(v) for k, v in parts.items()},
                          "orphans": [o.to_dict() for o in lost]}, indent=2))
    else:
        for job, reason in stale:
            sys.stdout.write(f"stale: {job.scene} -> {job.out_dir}: {reason}\n")
        for orphan in lost:
            sys.stdout.write(orphan.line() + "\n")
        for job, state, reason in states if not args.quiet else ():
            if state == "skipped":  # a scene that lost its relief: the files it waits for
                waits = f" ({reason.removeprefix(batch.NO_RELIEF + '; ')})" if reason != batch.NO_RELIEF else ""
                sys.stdout.write(f"{batch.SKIPPED}: {job.scene}{waits}\n")
    failed = 0
    for job, state, _ in states:
        policy = Policy.of(job.options)
        notes = batch.recorded(job) if state == "fresh" else read.get(job.scene, [])
        failing = policy.failing(notes)
        for notice in failing if state == "fresh" else policy.kept(notes):  # a skipped scene's: why, as hook says
            sys.stderr.write(line(notice))
        if failing:
            failed += 1
            codes = ", ".join(dict.fromkeys(n.code for n in failing))
            what = "its outputs were made with" if state == "fresh" else "reading it gives"
            sys.stderr.write(f"csm-assets: error: {job.scene}: {what} {len(failing)} "
                             f"warning(s) that are errors under {policy.why(failing)} ({codes})\n")
    if not (args.quiet or args.json):
        also = f", {skipped} {batch.SKIPPED}" if skipped else ""
        for kind in ("orphaned", "duplicate"):  # duplicate: in a folder renamed or copied by hand
            n = sum(o.kind == kind for o in lost)
            also += f", {n} {kind} output folder entr{'y' if n == 1 else 'ies'}" if n else ""
        also += f", {len(broken) + len(refused)} failed (configuration)" if broken or refused else ""
        fresh = len(jobs) - len(stale) - skipped - len(refused)
        sys.stderr.write(f"csm-assets: {fresh} of {len(jobs) + len(broken)} scene(s) up to date{also}\n")
    return EXIT_INPUT if failed else EXIT_USAGE if broken or refused else EXIT_STALE if stale or lost else EXIT_OK
