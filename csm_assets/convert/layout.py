"""Which scenes a run covers and where each one's outputs go (``plan``), for ``convert``,
``check`` and ``hook`` alike."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ..errors import FormatError, OutputError
from . import manifest
from .composition import composers
from .dependents import concerned, relative
from .links import OUTPUT_SUFFIX, beside, output_name  # noqa: F401 (the layout API)
from .pipeline import SCENE_FORMATS, ConvertOptions


@dataclass
class Job:
    """One scene to convert into ``out_dir``.

    Attributes:
        scene (pathlib.Path): the scene file.
        out_dir (pathlib.Path): its output folder.
        options (ConvertOptions | None): its own settings (None: the batch's).
        found (bool): a folder search found it (rather than its being named).
        error (str | None): why its settings could not be made (a configuration entry naming
            it); the job then fails alone.
    """

    scene: Path
    out_dir: Path
    options: ConvertOptions | None = None
    found: bool = False
    error: str | None = None  # its settings could not be made (a configuration entry naming it): it fails alone


def is_output(path: Path) -> bool:
    """True for files csm-assets wrote: never inputs, whatever the folder's name.

    Args:
        path (pathlib.Path | str): any file.

    Returns:
        Whether its folder holds a ``csm-manifest.json`` (of whatever kind: never opened here).
    """
    return os.path.lexists(Path(path).parent / manifest.NAME)


def discover(paths, parts: dict | None = None, dependents: bool = False,
             removed: bool = False) -> list[tuple[Path, Path, bool]]:
    """Scene files among ``paths`` (folders searched recursively, output folders skipped).

    A USD file that another USD file of its repository composes is part of that scene and left
    out, whether or not that scene is among ``paths``
    (:func:`~csm_assets.convert.composition.composers`); with ``dependents`` that scene comes
    instead, as if found in a folder (a commit of a layer alone, or of a layer an unselected
    variant names appearing, checks the scene composing it).

    Args:
        paths: scene files and folders.
        parts: when given, gets ``{file as given: the resolved scene composing it}`` for the
            layers left out.
        dependents: a named file that is no scene (a texture, a buffer, a configuration)
            brings the scenes it concerns (:func:`~csm_assets.convert.dependents.concerned`),
            as if found in a folder.
        removed: with ``dependents``, every scene of the repository whose manifest records an
            input that is gone comes too (:func:`~csm_assets.convert.dependents.concerned`).

    Returns:
        ``(scene, root, found)`` triples: the root its output layout is relative to, and
        whether a folder search found it (False: named). A scene named twice comes once.

    Raises:
        FormatError: a path that does not exist.
    """
    paths = list(map(Path, paths))
    found = []
    if dependents:
        scenes, folders = concerned([p for p in paths if p.is_file()],
                                    lambda f: f.suffix.lower() in SCENE_FORMATS, removed)
        found.extend((f, f.parent, True) for f in scenes)
        paths.extend(folders)
    for p in paths:
        if p.is_dir():
            for f in sorted(p.rglob("*")):
                if f.suffix.lower() in SCENE_FORMATS and f.is_file() and not is_output(f):
                    found.append((f, p, True))
        elif p.suffix.lower() in SCENE_FORMATS and not is_output(p):
            found.append((p, p.parent, False))
        elif not p.exists():
            raise FormatError(p, "no such file or folder")
    unique: dict[Path, tuple[Path, Path, bool]] = {}
    for f, root, searched in found:  # one scene named twice (a/x.gltf a/../a/x.gltf) is converted once
        unique.setdefault(f.resolve(), (f, root, searched))
    layers = composers(list(unique))
    todo = [c for c in dict.fromkeys(layers.values()) if c not in unique] if dependents else []
    while todo:  # check/hook: a layer given alone (a commit of it) brings the scene composing it, and so on up
        unique.update({c: (relative(c), c.parent, True) for c in todo})
        layers.update(up := composers(todo))
        todo = [c for c in dict.fromkeys(up.values()) if c not in unique]
    if parts is not None:
        parts.update({v[0]: layers[k] for k, v in unique.items() if k in layers})
    return [v for k, v in unique.items() if k not in layers]


def plan(paths, out_dir=None, parts: dict | None = None, dependents: bool = False,
         removed: bool = False) -> list[Job]:
    """Jobs for ``paths``, each with its output folder.

    The extension in the folder's name keeps wall.gltf and wall.obj apart.

    Args:
        paths: scene files and folders (see :func:`discover`).
        out_dir (str | os.PathLike | None): ``out_dir`` itself for a single scene file,
            ``out_dir/<folder>/<stem>_<ext>/`` for several or for folders; None: beside each
            scene (``<stem>_<ext>_csm/``).
        parts: see :func:`discover`.
        dependents: see :func:`discover`.
        removed: see :func:`discover`.

    Returns:
        The jobs, in the order found.

    Raises:
        FormatError: a path that does not exist.
        OutputError: two scenes would share an output folder.
    """
    scenes = discover(paths, parts, dependents, removed)
    single = len(scenes) == 1 and not any(Path(p).is_dir() for p in paths)
    jobs = []
    for scene, root, found in scenes:
        folder = output_name(scene)
        if out_dir is None:
            target = beside(scene)
        elif single:
            target = Path(out_dir)
        else:
            target = Path(out_dir) / scene.parent.relative_to(root) / folder
        jobs.append(Job(scene, target, found=found))
    return _apart(jobs, out_dir)


def _apart(jobs: list[Job], out_dir) -> list[Job]:
    """Scenes of one name from different folders (``a/wall.gltf b/wall.gltf -o out``) would
    share an output folder: those go to ``out/<their folders below the common one>/<stem>_<ext>``.
    OutputError when two jobs still share one."""
    by_target: dict[Path, list[Job]] = {}
    for job in jobs:
        by_target.setdefault(job.out_dir.resolve(), []).append(job)
    for same in by_target.values():
        if len(same) > 1 and out_dir is not None:
            common = Path(os.path.commonpath([j.scene.resolve().parent for j in same]))
            for j in same:
                j.out_dir = Path(out_dir) / j.scene.resolve().parent.relative_to(common) / j.out_dir.name
    seen: dict[Path, Job] = {}
    for job in jobs:
        other = seen.setdefault(job.out_dir.resolve(), job)
        if other is not job:
            raise OutputError(job.out_dir, f"both {other.scene} and {job.scene} would be converted into this "
                                           "folder; convert them separately")
    return jobs
