"""``csm-assets convert IN... -o OUTDIR``: scenes to CSM assets (:func:`csm_assets.convert.batch.run`)."""

from __future__ import annotations

import contextlib
from pathlib import Path

from .common import UsageError, add_quiet
from .scenes import (add_jobs, add_scene_flags, add_warning_flags, batch_exit, batch_progress, early_report_check,
                     finish, job_options)


def add(sub) -> None:
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
    add_scene_flags(c)
    c.add_argument("--force", action="store_true", help="convert even scenes whose outputs are fresh")
    add_jobs(c)
    add_warning_flags(c, "warnings that mean the output may be wrong or incomplete are errors: such a scene fails "
                         "(exit 3) and nothing of it is written (informational ones do not count)")
    c.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on the Dask scheduler at ADDRESS (tcp://HOST:PORT; needs csm-assets[dask]): each "
                        "scene a task there, or for one scene each UDIM tile a task there and other maps' cones "
                        "in bands of rows; the same bytes as a local run")
    c.add_argument("--report", metavar="FILE", help="write a JSON report of every scene to FILE")
    c.add_argument("--json", action="store_true", help="print the JSON report on stdout")
    add_quiet(c)
    c.set_defaults(run=run)


def run(args) -> int:
    from ..convert import batch

    parts: dict = {}
    jobs = batch.plan(args.input, args.output, parts)
    if not jobs and parts:
        named = "; ".join(f"{layer} is a layer of {scene}" for layer, scene in parts.items())
        raise UsageError(f"{named}: convert the scene that composes it")
    if not jobs:
        raise UsageError(f"no scene files ({', '.join(sorted(batch.SCENE_FORMATS))}) in {' '.join(args.input)}")
    cache = Path(args.output) / ".csm-cache" if len(jobs) > 1 else None
    job_options(jobs, args, force=args.force, cache_dir=cache)
    for job in jobs:  # a scene found in a folder and without relief costs nothing
        if job.options is not None:
            job.options.relief_only = job.found
    early_report_check(args, jobs)
    progress, stages, line = batch_progress(args, log=True)
    try:
        with batch.dask_executor(args.scheduler) if args.scheduler else contextlib.nullcontext() as executor:
            report = batch.run(jobs, executor=executor, jobs_at_once=args.jobs, progress=progress, stages=stages)
    finally:
        if line is not None:
            line.close()
    finish(report, args)
    return batch_exit(report)
