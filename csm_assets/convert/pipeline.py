"""Scene conversion: a chain of small steps over the scene model.

read -> screen heights -> step maps (:mod:`csm_assets.convert.maps`, one per distinct height texture) ->
tangents (:mod:`csm_assets.tangents.mesh_checks`, only meshes whose material got a step map) -> write, into a
staged output folder (:mod:`csm_assets.convert.output_folder`, :mod:`csm_assets.convert.manifest`). A material
without a height texture costs nothing; with ``relief_only``, neither does a scene without one.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Callable

from .. import height_source
from ..atomic import atomic_path
from ..config.files import project_root
from ..errors import FormatError, OptionError, OutputError, StrictError
from ..formats.registry import SCENE_FORMAT_ROWS, scene_module
from ..tangents.mesh_checks import make_tangents, mesh_problems, triangle_areas, warn_clamped_uvs, warn_mesh_problems
from ..material_names import check_names
from ..udim import records as udim_records
from ..packing import MAP_CONES as CONE_KINDS
from ..warning_codes import Notice, Policy
from . import manifest
from . import output_folder as folder
from .links import links, textures_mode
from .lost_relief import NO_RELIEF, is_record, settle, skip
from .inputs import Snapshot
from .maps import confirm_scene_picks, make_step_maps, map_names, screen_heights
from .options import ConvertOptions, check_material_options, check_warning_options
from .pick import checked_variant
from .report import ConvertReport, picked
from .udim import make_udim_maps, refuse_sets

__all__ = ["SCENE_FORMATS", "ConvertOptions", "ConvertReport", "Progress", "check_material_options",
           "check_warning_options", "convert", "fresh", "make_step_maps", "make_tangents", "mesh_problems",
           "scene_module", "triangle_areas"]

SCENE_FORMATS = {f.extension: f.module for f in SCENE_FORMAT_ROWS}
DEFAULT_DEPTH = height_source.DEFAULT_DEPTH  # texture-space depth when nothing states a factor
# progress(stage, done, total): stages "reading", "step maps", "pick", "tangents", "confirm",
# "writing" in that order (those the conversion needs); done/total count rows or materials, 0/0 none
Progress = Callable[[str, int, int], None]


def scene_root(in_path, opts: ConvertOptions) -> Path:
    """The project root of the scene at ``in_path`` under ``opts`` (resolved)."""
    return Path(opts.root).resolve() if opts.root is not None else project_root(in_path)


def read_scene(in_path, opts: ConvertOptions, module=None):
    """The scene at ``in_path`` as conversion reads it: files inside its project root (unless
    ``allow_outside``), ``heights`` applied and every material they name checked."""
    module = module or scene_module(in_path)
    scene = module.read(in_path, heights=opts.heights, allow_outside=opts.allow_outside,
                        root=scene_root(in_path, opts))
    check_names(scene, [*opts.heights, *opts.depths], opts.named_by)
    return scene


def read_seen(in_path, opts: ConvertOptions, module, seen: Snapshot):
    """:func:`read_scene`, each input looked at (``seen``) before its bytes are used: the scene
    file before it is read, its other files and height textures before a texel is read."""
    seen.take([in_path])
    scene = read_scene(in_path, opts, module)
    seen.take([*scene.inputs, *(f for m in scene.materials if m.height is not None for f in m.height.files())])
    return scene


def has_relief(in_path, opts: ConvertOptions) -> bool:
    """Whether the scene has a height texture to convert (read and screened, nothing made)."""
    return screen_heights(read_scene(in_path, opts))


def convert(in_path, out_dir, options: ConvertOptions | None = None, *, progress: Progress | None = None,
            executor=None, **kwargs) -> ConvertReport:
    """Convert the scene at ``in_path`` into ``out_dir`` (created if missing).

    Options come as a :class:`ConvertOptions` or as its fields by keyword. Outputs whose
    manifest shows them fresh are left alone (``report.skipped`` says why) unless
    ``force``. Everything is made in a staging folder inside ``out_dir`` and moved into
    place only when all of it succeeded, manifest last: a failure leaves no partial
    outputs, an interruption leaves each file old and intact or new and complete.
    Several scenes may be converted into one folder: each takes names no other scene's
    entry in the manifest holds (see :mod:`csm_assets.convert.output_folder`).

    Args:
        in_path (str | os.PathLike): a .gltf, .glb, .obj, .usd, .usda, .usdc or .usdz scene.
        out_dir (str | os.PathLike): the output folder (not the scene's own folder).
        options: the settings; None: ``ConvertOptions(**kwargs)``.
        progress: ``progress(stage, done, total)`` (:data:`Progress`), told each stage as it
            starts and goes on.
        executor: a Dask cluster's (:func:`csm_assets.dask_client.dask_executor`): each UDIM
            tile's map a task there, other maps' cones searched there in bands; the same files.
        **kwargs: :class:`ConvertOptions` fields, when ``options`` is None.

    Returns:
        The report; its ``warnings`` hold those not ignored, identical ones collapsed.

    Raises:
        OptionError: an option the scene cannot take (a bit depth its format cannot hold,
            ``cones`` and ``variant`` that do not go together, a bad ``steps``,
            ``light_size`` or warning code, a ``heights`` name that is no material).
        FormatError: an unreadable or malformed scene or texture; StrictError (a
            FormatError) for warnings that are errors under ``strict``/``error_on``.
        OutputError: an output would overwrite an input or another scene's output, or
            cannot be written.
    """
    start = time.perf_counter()
    in_path, out_dir = Path(in_path), Path(out_dir)
    opts = textures_mode(options or ConvertOptions(**kwargs), in_path, out_dir)
    module = scene_module(in_path)
    regular_scene(in_path)
    if out_dir.resolve() == in_path.parent.resolve():
        raise OutputError(out_dir, "is the input's folder: the converted scene would overwrite "
                                   f"{in_path.name}; choose another output folder")
    if opts.bits is not None and opts.bits not in module.STEP_MAP_BITS:
        raise OptionError(f"{in_path}: {in_path.suffix} scenes take {' or '.join(map(str, module.STEP_MAP_BITS))}"
                         f"-bit step maps, not {opts.bits}-bit (glTF images are PNG)")
    if opts.cones not in CONE_KINDS:
        raise OptionError(f"cones must be one of {', '.join(CONE_KINDS)}, got {opts.cones!r}")
    checked_variant(opts)  # relaxed or quadrant cones: that variant only
    check_material_options(opts)
    check_warning_options(opts)
    refuse_sets(in_path, opts, module)  # a UDIM set for a format without UDIM textures
    policy, tell = Policy.of(opts), progress or _silent
    report = ConvertReport(in_path)
    root = scene_root(in_path, opts)
    settings = opts.settings(root)
    scene = relief = None
    seen = Snapshot()  # what each input was when read: the manifest records that, or nothing is published
    if opts.relief_only and not out_dir.exists():  # nothing to be fresh: read first, create nothing without relief
        tell("reading", 0, 0)
        scene = read_seen(in_path, opts, module, seen)
        if not (relief := screen_heights(scene)):
            return skip(report, scene, policy, start)
    with folder.locked(out_dir):
        folder.clean_dead_stages(out_dir)
        known = manifest.load(out_dir)
        mine = known["scenes"].get(in_path.name)
        if mine is not None and mine.get("source", manifest.source_key(in_path, out_dir)) != \
                manifest.source_key(in_path, out_dir):
            raise OutputError(out_dir / in_path.name, f"is the output of another scene ({mine['source']}); "
                                                      "convert this one into another folder")
        if _fresh(report, out_dir, opts, known, root, policy):
            report.seconds = time.perf_counter() - start
            return report
        if scene is None:
            tell("reading", 0, 0)
            scene = read_seen(in_path, opts, module, seen)
            relief = screen_heights(scene)
        if not relief and opts.relief_only:  # one that had outputs keeps a record of the files it misses
            skip(report, scene, policy, start)
            if mine is not None:
                settle(report, known, scene, out_dir, settings, root, seen.confirm([in_path, *scene.inputs]))
            return report
        others = manifest.owned_by_others(known, in_path.name)
        scene.reserved = {manifest.NAME, in_path.name}
        scene.others = folder.other_files(others, out_dir)
        scene.links = links(opts, in_path, out_dir)
        scene.published = Path(out_dir).resolve()
        with folder.staging(out_dir) as stage:
            report.step_maps = make_udim_maps(scene, stage, opts, module.STEP_MAP_BITS, tell, executor)
            report.step_maps.update(make_step_maps(scene, stage, opts, module.STEP_MAP_BITS, tell, executor))
            warn_clamped_uvs(scene)
            warn_mesh_problems(scene)
            if module.STORES_TANGENTS:
                tell("tangents", 0, 0)
                report.tangent_meshes = make_tangents(scene, opts)
            if opts.max_error is not None:
                report.step_maps.update({p.stem: p for p in confirm_scene_picks(scene, stage, opts, module, tell)})
            embedded = getattr(module, "embeds_step_maps", lambda _: False)(scene)  # a GLB holds its own
            tell("writing", 0, 0)
            scene_files = module.write(scene, stage)
            maps = [] if embedded else [stage / n for p in report.step_maps.values()
                                        for n in map_names(p, opts, stage)]
            staged = [*maps, *scene_files]  # a quadrant map's second image beside its first
            if failing := policy.failing(scene.warnings):
                raise StrictError(in_path, policy.kept(scene.warnings), failing, policy.why(failing))
            names = [p.name for p in staged]
            inputs = [in_path, *scene.inputs]
            folder.check_names(stage, names, out_dir, inputs, others)
            digests = seen.confirm(inputs)  # InputChanged when one was replaced or rewritten since it was read
            report.picks = {m.name: picked(m) for m in scene.materials if m.csm is not None}
            read = {f: digests[f] for f in scene.inputs} | udim_records(scene)  # the tiles each set has
            known["scenes"][in_path.name] = manifest.entry(in_path, out_dir, read, staged, settings, report.picks,
                                                           [n.record() for n in scene.warnings], root=root,
                                                           absent=scene.absent)
            with atomic_path(stage / manifest.NAME) as tmp:
                manifest.write(tmp, known)
            report.written = folder.publish(stage, names + [manifest.NAME], out_dir)
        folder.remove_orphans(out_dir, set(mine["outputs"]) if mine else set(), set(names), set(others), inputs)
    report.step_maps = {k: out_dir / (scene_files[0] if embedded else v).name for k, v in report.step_maps.items()}
    report.warnings = policy.kept(scene.warnings)
    report.seconds = time.perf_counter() - start
    return report


def fresh(in_path, out_dir, options: ConvertOptions | None = None) -> ConvertReport | None:
    """The report :func:`convert` would give for a scene whose outputs are fresh.

    Nothing is done; it costs as much as hashing the scene's inputs.

    Args:
        in_path (str | os.PathLike): the scene.
        out_dir (str | os.PathLike): its output folder.
        options: the settings (None: the defaults).

    Returns:
        The report (``skipped`` says fresh), or None when the scene is to be converted.

    Raises:
        StrictError: a fresh scene whose recorded warnings are errors under
            ``strict``/``error_on``.
        FormatError: an unreadable manifest.
    """
    in_path, out_dir, start = Path(in_path), Path(out_dir), time.perf_counter()
    opts = textures_mode(options or ConvertOptions(), in_path, out_dir)
    if opts.force or not (out_dir / manifest.NAME).is_file():
        return None
    check_warning_options(opts)
    report = ConvertReport(in_path)
    with folder.locked(out_dir):
        if not _fresh(report, out_dir, opts, manifest.load(out_dir), scene_root(in_path, opts), Policy.of(opts)):
            return None
    report.seconds = time.perf_counter() - start
    return report


def _fresh(report: ConvertReport, out_dir: Path, opts: ConvertOptions, known: dict, root: Path,
           policy: Policy) -> bool:
    """Whether ``report.input``'s outputs are fresh; if so, ``report`` says so, with the
    warnings (those ``policy`` keeps) and picks of the conversion that made them."""
    in_path = report.input
    if opts.force or not in_path.is_file() or \
            manifest.staleness(in_path, out_dir, opts.settings(root), known, root=root) is not None:
        return False
    mine = known["scenes"][in_path.name]
    recorded = [Notice.from_dict(d) for d in mine.get("warnings", [])]
    report.skipped = NO_RELIEF if is_record(mine) else "outputs are fresh"  # a record: no relief, waiting
    report.warnings = policy.kept(recorded)
    report.picks = dict(mine.get("picks", {}))
    if failing := policy.failing(recorded):
        raise StrictError(in_path, report.warnings, failing, policy.why(failing))
    return True


def regular_scene(in_path: Path) -> None:
    """FormatError unless ``in_path`` is a regular file (through links): a FIFO or a link to
    ``/dev/zero`` would hang or fill memory in the reader. A missing one is the reader's to report."""
    try:
        kind = manifest.not_regular(os.stat(in_path).st_mode)
    except FileNotFoundError:
        return
    except OSError as e:
        raise FormatError(in_path, f"cannot be read: {e.strerror or e}") from e
    if kind is not None:
        raise FormatError(in_path, f"is {kind}, not a scene file (expected a regular file)")


def _silent(stage: str, done: int, total: int) -> None:
    """No progress wanted."""
