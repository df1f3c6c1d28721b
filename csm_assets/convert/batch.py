"""Batch conversion: many scenes, in parallel, on the local cores or any executor.

A batch is data: :func:`plan` lists (scene, output folder) pairs, :func:`run` converts
them through a ``concurrent.futures.Executor`` (a process pool by default, or Dask's
``Client.get_executor()`` for a cluster) and returns a :class:`BatchReport`. One bad
scene is reported and the batch goes on. Each job may carry its own options (the project
configuration's settings for that scene, :mod:`csm_assets.config`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

from ..dask_client import dask_executor  # noqa: F401 (the batch API: convert --scheduler)
from ..errors import FormatError, OptionError, OutputError
from ..printable import printable
from ..render.renderer import GLError, GLUnavailable
from . import manifest
from .layout import OUTPUT_SUFFIX, Job, discover, is_output, plan  # noqa: F401 (the batch API)
from ..warning_codes import Notice
from .pipeline import NO_RELIEF, SCENE_FORMATS, ConvertOptions, convert, fresh  # noqa: F401 (SCENE_FORMATS: the batch API)
from .survey import survey
from .workers import process_pool, sigint_blocked, stop_pool

SKIPPED = f"skipped ({NO_RELIEF})"  # how reports name a scene without relief


@dataclass
class JobResult:
    """What happened to one scene.

    Attributes:
        scene (str): the scene's path.
        out_dir (str): its output folder.
        status (str): ``converted``, ``unchanged`` (no material had a height texture: the
            scene was written as it was), ``skipped`` (no relief, under ``relief_only``:
            nothing written), ``fresh`` (outputs up to date) or ``failed``.
        seconds (float): wall time.
        written (list[str]): the files written.
        removed (list[str]): the files removed (a scene that lost its relief, see
            :mod:`csm_assets.convert.lost_relief`).
        warnings (list): the warnings not ignored (:class:`~csm_assets.warning_codes.Notice`).
        error (str | None): a failure's one-line message, naming a file.
        error_kind (str | None): ``"input"`` (unreadable scene), ``"usage"`` (an option no
            material fits), ``"output"`` or ``"gl"``; it picks the exit code.
        picks (dict): material -> ``{"variant", "steps", ...}`` written (converted only).
    """

    scene: str
    out_dir: str
    status: str
    seconds: float = 0.0
    written: list[str] = field(default_factory=list)
    warnings: list = field(default_factory=list)  # csm_assets.warning_codes.Notice, not ignored
    error: str | None = None
    removed: list[str] = field(default_factory=list)
    error_kind: str | None = None  # "input" (unreadable scene), "usage" (an option no material fits), "output", "gl"
    picks: dict = field(default_factory=dict)  # material -> {"variant", "steps"} written (converted only)


@dataclass
class BatchReport:
    """What a batch did, scene by scene.

    Attributes:
        results (list[JobResult]): one per job, in job order.
        seconds (float): wall time of the whole batch.
    """

    results: list[JobResult] = field(default_factory=list)
    seconds: float = 0.0

    def count(self, status: str) -> int:
        """How many results have ``status`` (see :class:`JobResult`).

        Args:
            status: ``converted``, ``unchanged``, ``skipped``, ``fresh`` or ``failed``.
        """
        return sum(r.status == status for r in self.results)

    @property
    def wrote(self) -> bool:
        """Some scene wrote or removed files (the hook's exit 1)."""
        return any(r.written or r.removed for r in self.results)

    def summary(self) -> str:
        """One line: scenes by status, warnings and seconds."""
        warnings = sum(n.count for r in self.results for n in r.warnings)
        skipped = f"{self.count('skipped')} {SKIPPED}, " if self.count("skipped") else ""
        return (f"{len(self.results)} scene(s): {self.count('converted')} converted, "
                f"{self.count('unchanged')} unchanged, {self.count('fresh')} fresh, {skipped}"
                f"{self.count('failed')} failed, {warnings} warning(s) in {self.seconds:.1f} s")

    def to_dict(self) -> dict:
        """The report as ``--json`` prints it: ``summary``, ``seconds``, ``results``."""
        return {"summary": self.summary(), "seconds": round(self.seconds, 3),
                "results": [{**asdict(r), "warnings": [n.to_dict() for n in r.warnings]} for r in self.results]}


def label(status: str) -> str:
    """A result's status as reports print it ("skipped (no relief)")."""
    return SKIPPED if status == "skipped" else status


def stale(jobs: list[Job], options: ConvertOptions | None = None,
          progress: Callable[[str, int, int], None] | None = None) -> list[tuple[Job, str]]:
    """The jobs whose outputs are missing or stale, with the reason; writes nothing.

    Args:
        jobs: from :func:`~csm_assets.convert.layout.plan`.
        options: for jobs without their own.
        progress: ``progress("checking", done, total)`` by scene.

    Returns:
        ``(job, reason)`` pairs (see :func:`~csm_assets.convert.survey.survey`).
    """
    return [(job, reason) for job, state, reason in survey(jobs, options, progress) if state == "stale"]


def recorded(job: Job) -> list:
    """The warnings (:class:`~csm_assets.warning_codes.Notice`) the manifest in a job's output
    folder recorded for its scene; none when there is no entry."""
    entry = manifest.load(job.out_dir)["scenes"].get(job.scene.name, {})
    return [Notice.from_dict(d) for d in entry.get("warnings", [])]


def run_job(job: Job, options: ConvertOptions | None = None,
            stages: Callable[[str, int, int], None] | None = None, executor: Executor | None = None) -> JobResult:
    """Convert one scene; errors are caught into the result, so a batch goes on.

    Every error names the scene (a library message that does not gets the scene's path in
    front).

    Args:
        job: the scene and its output folder.
        options: for a job without its own.
        stages: ``stages(stage, done, total)``: the conversion's progress, the stage after
            the scene's name.
        executor: where the scene's UDIM tiles and the cones of its maps are made (a Dask
            cluster's; see :func:`~csm_assets.convert.pipeline.convert`), else here.

    Returns:
        The result; ``status`` ``failed`` with ``error`` and ``error_kind`` for an error.
    """
    start = time.perf_counter()
    tell = (lambda stage, done, total: stages(f"{job.scene.name}: {stage}", done, total)) if stages else None
    try:
        report = convert(job.scene, job.out_dir, job.options or options, progress=tell, executor=executor)
    except (FormatError, OutputError, ValueError, OSError) as e:
        kind = "usage" if isinstance(e, OptionError) else "input" if isinstance(e, ValueError) else "output"
        return JobResult(str(job.scene), str(job.out_dir), "failed", time.perf_counter() - start,
                         warnings=list(getattr(e, "warnings", [])), error=_naming(job.scene, e),
                         error_kind=kind)
    except MemoryError as e:  # past limits.check_memory's estimate: this scene fails, the batch goes on
        return JobResult(str(job.scene), str(job.out_dir), "failed", time.perf_counter() - start,
                         error=f"{job.scene}: out of memory{f' ({e})' if str(e) else ''}; lower "
                               "CSM_ASSETS_MAX_TEXELS to refuse inputs this big up front, or give it more memory",
                         error_kind="input")
    except (GLUnavailable, GLError) as e:  # --max-error measures with OpenGL: this scene fails
        return JobResult(str(job.scene), str(job.out_dir), "failed", time.perf_counter() - start,
                         error=f"{job.scene}: {e}", error_kind="gl")
    return _result(job, report)


def _result(job: Job, report) -> JobResult:
    status = ("skipped" if report.skipped == NO_RELIEF else "fresh" if report.skipped
              else "unchanged" if report.unchanged else "converted")
    return JobResult(str(job.scene), str(job.out_dir), status, report.seconds, [str(p) for p in report.written],
                     report.warnings, picks=report.picks, removed=[str(p) for p in report.removed])


def fresh_result(job: Job, options: ConvertOptions | None = None) -> JobResult | None:
    """The result of a job whose outputs are fresh, found in this process (no worker is
    started for it), else None: it is converted, and any error is reported then."""
    try:
        report = fresh(job.scene, job.out_dir, job.options or options)
    except (FormatError, OutputError, ValueError, OSError):
        return None
    return None if report is None else _result(job, report)


def _naming(scene: Path, e: Exception) -> str:
    """``e`` as one line that names a file (the scene's path when the message names none)."""
    text = "; ".join(t.strip() for t in str(e).splitlines() if t.strip()) or type(e).__name__
    named = getattr(e, "path", None) or getattr(e, "filename", None)
    if (named and str(named) in text) or str(scene) in text:
        return text
    return f"{scene}: {text}"


def run(jobs: list[Job], options: ConvertOptions | None = None, *, executor: Executor | None = None,
        jobs_at_once: int | None = None, progress: Callable[[int, int, JobResult], None] | None = None,
        stages: Callable[[str, int, int], None] | None = None) -> BatchReport:
    """Convert every job. Jobs whose outputs are fresh are answered in the calling process
    first (:func:`fresh_result`); a failed scene does not stop the others.

    Args:
        jobs: from :func:`~csm_assets.convert.layout.plan`.
        options: for jobs without their own.
        executor: any ``concurrent.futures.Executor`` (e.g.
            ``distributed.Client(addr).get_executor()``), a task per scene; a single scene to convert
            is converted in the calling process instead, each of its UDIM tiles a task on the
            executor and its other maps' cones searched there in bands (:func:`run_job`). By default
            a local process pool of ``jobs_at_once`` workers, or the calling process for a single job
            (whose kernels then use every core).
        jobs_at_once: the pool's workers (None: the core count).
        progress: ``progress(done, total, result)``, told of each finished scene.
        stages: the stages of scenes converted in this process (see :func:`run_job`; a
            process pool's workers report none).

    Returns:
        The report, results in job order.
    """
    start = time.perf_counter()
    results: dict[int, JobResult] = {}
    todo = []
    for i, job in enumerate(jobs):  # fresh scenes cost a hash each here, never a worker
        found = JobResult(str(job.scene), str(job.out_dir), "failed", 0.0, error=job.error,
                          error_kind="usage") if job.error else fresh_result(job, options)
        if found is None:
            todo.append(i)
            continue
        results[i] = found
        if progress:
            progress(len(results), len(jobs), found)
    workers = jobs_at_once or os.cpu_count() or 1
    own = None
    if executor is None and len(todo) > 1 and workers > 1:
        own = executor = process_pool(min(workers, len(todo)))
    try:
        if executor is None or len(todo) == 1:
            for i in todo:
                results[i] = run_job(jobs[i], options, stages, executor)
                if progress:
                    progress(len(results), len(jobs), results[i])
        else:
            with sigint_blocked() if own is not None else contextlib.nullcontext():
                futures = {executor.submit(run_job, jobs[i], options): i for i in todo}
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                if progress:
                    progress(len(results), len(jobs), results[futures[fut]])
    except KeyboardInterrupt:
        if own is not None:
            stop_pool(own)
            own = None
        raise
    finally:
        if own is not None:
            own.shutdown(cancel_futures=True)
    return BatchReport([results[i] for i in range(len(jobs))], time.perf_counter() - start)


def progress_printer(stream=None) -> Callable[[int, int, JobResult], None]:
    """A bar redrawn in place on a terminal's stderr; elsewhere (CI logs, pipes) one plain
    line per scene on stdout (``stream``), so stderr holds only warnings and errors."""
    tty = stream is None and sys.stderr.isatty()

    def show(done: int, total: int, r: JobResult) -> None:
        name = printable(Path(r.scene).name)
        if tty:
            width = 30
            bar = "#" * (width * done // total) + "-" * (width - width * done // total)
            end = "\n" if done == total else ""
            sys.stderr.write(f"\r[{bar}] {done}/{total} {label(r.status):9s} {name[:40]}\x1b[K{end}")
            sys.stderr.flush()
        else:
            out = stream or sys.stdout
            out.write(f"[{done}/{total}] {label(r.status)} {r.scene} -> {r.out_dir} ({r.seconds:.1f} s)\n")
            out.flush()

    return show
