"""The scenes a changed non-scene file concerns, so that a commit of a texture alone is checked.

pre-commit passes ``hook`` and ``check`` the files being committed. A height texture, a
buffer or a material library is no scene, but the scenes that read it go stale when it
changes: every manifest of the file's repository (else its folder) that records it among a
scene's inputs (or among the files it named that were absent: a texture restored) names that scene. A project configuration (``csm-assets.toml``, a
``pyproject.toml``) concerns every scene below its folder. A file deleted or renamed is never
passed (pre-commit passes the files a commit keeps), so with ``removed`` (``--removed-inputs``,
as the pre-commit hooks run) every scene of the repository whose manifest records an input
that is gone is concerned too: it has lost a texture.
"""

from __future__ import annotations

import os
from pathlib import Path

from .. import udim
from . import manifest

CONFIG_FILES = ("csm-assets.toml", "pyproject.toml")


def _search_root(file: Path) -> Path:
    from ..config.files import repository_root

    return repository_root(file) or file.resolve().parent


def concerned(files, is_scene, removed: bool = False) -> tuple[list[Path], list[Path]]:
    """The scenes and folders that non-scene files (textures, buffers, configurations) concern.

    A file inside an output folder concerns the scenes of its manifest (a folder renamed or copied
    by hand is found so, and the scene's own outputs made again where they belong).

    Args:
        files: paths as given (missing ones are left out).
        is_scene: ``is_scene(path)`` tells scene files apart (they are left to the caller).
        removed: also every scene whose recorded inputs include a file that is gone (in the
            repositories of ``files``, else of the working folder): what pre-commit cannot pass.

    Returns:
        ``(scenes, folders)``: the scenes (as a manifest's ``source`` records them, existing
        ones only) whose recorded inputs include one of ``files`` (or, with ``removed``, a
        file that is gone), and the folders of the configuration files among them.
    """
    wanted, folders, given, scenes = set(), [], [], {}
    for f in map(Path, files):
        if not os.path.lexists(f):
            continue
        given.append(f)
        if (f.parent / manifest.NAME).is_file():  # an output (a folder renamed or copied by hand): its scenes
            scenes.update({s.resolve(): relative(s) for s in _recorded(f.parent)})
            continue
        if is_scene(f):
            continue
        if f.name in CONFIG_FILES:
            folders.append(f.parent)
        else:
            wanted.add(f.resolve())
    if not wanted and not removed:
        return sorted(scenes.values()), folders
    roots = dict.fromkeys(_search_root(f) for f in (given if removed else wanted))
    if not roots:  # nothing passed (a commit that only deletes): the working folder's repository
        from ..config.files import repository_root

        here = repository_root(Path.cwd() / CONFIG_FILES[0])  # a file in it: repository_root takes its folder
        roots = dict.fromkeys([here] if here is not None else [])
    for root in roots:
        for folder in manifest.output_folders([root]):
            try:
                entries = manifest.load(folder)["scenes"]
            except manifest.ManifestError:
                continue
            for entry in entries.values():
                source = entry.get("source")
                if not isinstance(source, str):
                    continue
                scene = Path(os.path.normpath(folder / source))
                base = manifest.recorded_root(entry, scene, folder)
                inputs = [base / key for key in entry["inputs"]]
                named = [*inputs, *(base / key for key in entry.get("absent", []))]  # absent: appearing concerns it
                if scene.is_file() and (any(_reads(i, wanted) for i in named)
                                        or removed and any(map(_gone, inputs))):
                    scenes.setdefault(scene.resolve(), relative(scene))
    return sorted(scenes.values()), folders


def _recorded(folder: Path) -> list[Path]:
    """The existing scenes an output folder's manifest has entries of (none when unreadable)."""
    try:
        entries = manifest.load(folder)["scenes"].values()
    except manifest.ManifestError:
        return []
    found = (Path(os.path.normpath(folder / e["source"])) for e in entries if isinstance(e.get("source"), str))
    return [s for s in found if s.is_file()]


def _gone(input_path: Path) -> bool:
    """Whether a manifest's input no longer exists (a UDIM set never counts: a tile removed changes
    the set, which the run sees through its tiles)."""
    if udim.is_pattern(input_path):
        return False
    return not os.path.lexists(input_path)


def _reads(input_path: Path, wanted: set[Path]) -> bool:
    """Whether a manifest's input is one of ``wanted`` (resolved), or a UDIM set one of them is a tile of
    (a tile added concerns the scene too)."""
    if udim.is_pattern(input_path):
        return any(udim.in_set(input_path, f) for f in wanted)
    return input_path.resolve() in wanted


def relative(path: Path) -> Path:
    """``path`` relative to the working directory where it lies below it (as pre-commit names
    files), else as it is."""
    try:
        return path.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return path
