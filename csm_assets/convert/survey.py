"""What ``check`` reports of each scene without writing anything: fresh, stale (and why), or
skipped (no relief: converting it would write nothing; a scene that lost its relief and waits for a
missing file, :mod:`csm_assets.convert.lost_relief`, while its record holds)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..errors import FormatError, OptionError
from ..formats.image import read_size
from ..warning_codes import Notice
from . import manifest
from .lost_relief import record_of, waiting_line
from .links import textures_mode
from .maps import check_material_depth, material_depth, screen_heights
from .pipeline import NO_RELIEF, ConvertOptions, read_scene, scene_root


def survey(jobs, options: ConvertOptions | None = None,
           progress: Callable[[str, int, int], None] | None = None,
           notices: dict | None = None) -> list[tuple[object, str, str | None]]:
    """The state of each job's outputs; writes nothing.

    Args:
        jobs: :class:`~csm_assets.convert.batch.Job` objects (each with its options, else
            ``options``).
        options: for jobs without their own.
        progress: ``progress("checking", done, total)`` by scene.
        notices: when given, gets ``{scene: warnings}`` of the skipped scenes' reading (a
            missing height texture: what ``hook`` and ``convert`` would warn).

    Returns:
        ``(job, state, reason)`` each: state ``"fresh"``, ``"stale"`` (with the reason), ``"error"``
        (a depth nothing can be measured at, the one-line message naming the setting) or
        ``"skipped"`` (stale, but under ``relief_only`` the scene has no relief, so converting
        it would write nothing; the scene is read and its heights screened, no step map made;
        or a fresh waiting record, the reason naming the files it waits for). A stale record is
        stale whatever the scene holds: ``hook`` writes it again, or the outputs.
    """
    out = []
    for done, job in enumerate(jobs):
        if progress:
            progress("checking", done, len(jobs))
        opts = textures_mode(job.options or options or ConvertOptions(), job.scene, job.out_dir)
        root = scene_root(job.scene, opts)
        reason = manifest.staleness(job.scene, job.out_dir, opts.settings(root), root=root)
        record = record_of(job.out_dir, job.scene.name)
        if reason is None and record is not None:  # no relief, waiting for a missing file: as hook says it
            out.append((job, "skipped", waiting_line(record)))
            if notices is not None:
                notices[job.scene] = [Notice.from_dict(d) for d in record.get("warnings", [])]
        elif reason is None:
            out.append((job, "fresh", None))
        elif record is None and opts.relief_only and job.scene.is_file():
            try:
                relief = _relief(job.scene, opts, notices)
            except OptionError as e:  # a setting's depth nothing can be measured at: as hook fails it (exit 2)
                out.append((job, "error", str(e) if str(job.scene) in str(e) else f"{job.scene}: {e}"))
                continue
            out.append((job, "stale", reason) if relief else (job, "skipped", NO_RELIEF))
        else:
            out.append((job, "stale", reason))
    return out


def _relief(scene: Path, opts: ConvertOptions, notices: dict | None) -> bool:
    """:func:`has_relief`, True when the scene cannot be read (converting it reports why); the
    reading's warnings into ``notices[scene]``. OptionError when a setting (an option, a
    configuration key) gives a material a depth nothing can be measured at on its height texture,
    as converting it would refuse (the scene's own depth, or a texture whose header tells no size,
    is left to that)."""
    try:
        read = read_scene(scene, opts)
    except FormatError:
        return True
    relief = screen_heights(read)
    if notices is not None:
        notices[scene] = list(read.warnings)
    for mat in read.materials if relief else ():
        h = mat.height
        if h is None or h.udim is not None or h.texture.path is None:
            continue
        try:
            width, height = read_size(h.texture.path)
            check_material_depth(read, mat, opts, material_depth(read, mat, opts), (height, width))
        except (FormatError, OSError):  # the scene's own depth, or a texture without a size: convert says
            continue
    return relief
