"""Committed outputs whose scene is gone: findings for ``check`` and ``hook``.

An entry of an output folder's manifest is **orphaned** when its scene no longer exists
where the entry says (renamed, moved or deleted), when the scene is now a layer another
scene composes (part of that scene), or when the scene no longer has relief (its height
texture is no longer named; one that misses a file keeps a waiting record instead, see
:mod:`csm_assets.convert.lost_relief`), so its outputs would go stale unseen. ``check``
reports each (exit 1); ``hook`` removes the entry's own outputs and the entry itself. An entry
in a folder whose name is not the one it was written in (``rock_gltf_csm/`` renamed or copied
to ``rock_copy/`` by hand) is a **duplicate**, reported and removed the same way.

Which folders are looked at: every output folder (a folder holding ``csm-manifest.json``)
under the folders a run was given, or under ``-o OUTDIR``; for named scene files, their own
output folders and the output folders beside them (``*_csm/`` holding a manifest): a scene
renamed in its folder (``git mv rock.obj boulder.obj``) leaves ``rock_obj_csm/`` there, and
pre-commit passes only ``boulder.obj``; for named output files, their folder.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path

from ..atomic import atomic_path
from . import manifest
from .layout import OUTPUT_SUFFIX, beside
from .output_folder import locked


@dataclass
class Orphan:
    """A manifest entry whose scene is gone, became a layer of another, or lost its relief.

    Attributes:
        out_dir (pathlib.Path): the output folder.
        scene (str): the manifest entry's name.
        source (pathlib.Path): where the scene was.
        reason (str): why it is an orphan, as ``check`` prints it.
        kind (str): ``orphaned``, or ``duplicate`` for a scene's outputs in a folder renamed or
            copied by hand (its name is not the one the entry was written in).
    """

    out_dir: Path  # the output folder
    scene: str     # the manifest entry's name
    source: Path   # where the scene was
    reason: str
    kind: str = "orphaned"  # or "duplicate": a scene's outputs in a folder renamed or copied by hand

    def line(self) -> str:
        """``orphaned: OUTDIR (SCENE): reason`` (or ``duplicate: ...``), as ``check`` prints it."""
        return f"{self.kind}: {self.out_dir} ({self.scene}): {self.reason}"

    def to_dict(self) -> dict:
        """The fields as JSON-ready strings (``--json``)."""
        return {"out_dir": str(self.out_dir), "scene": self.scene, "source": str(self.source),
                "reason": self.reason, "kind": self.kind}


def find(paths, jobs, states: dict, parts: dict, out_dir=None) -> list[Orphan]:
    """The orphaned manifest entries a run over ``paths`` can see.

    Args:
        paths: the files and folders of the run.
        jobs: the run's plan (:func:`~csm_assets.convert.layout.plan`).
        states: ``{resolved out_dir: state}`` of its jobs (``"skipped"``: no relief).
        parts: ``{file: composing scene}`` from the plan.
        out_dir (str | os.PathLike | None): the run's output folder (None: beside each scene).

    Returns:
        The orphans, by output folder. A manifest that cannot be read is left to the run
        (reported stale there).
    """
    roots = [Path(out_dir)] if out_dir is not None else [Path(p) for p in paths if Path(p).is_dir()]
    folders = {f.resolve(): f for f in manifest.output_folders(roots)}
    for p in map(Path, paths):  # outputs named (a commit of a folder renamed by hand): their folder
        if p.is_file() and (p.parent / manifest.NAME).is_file():
            folders.setdefault(p.parent.resolve(), p.parent)
    planned = {job.out_dir.resolve(): job for job in jobs}
    for job in jobs:
        if states.get(job.out_dir.resolve()) == "skipped" and (job.out_dir / manifest.NAME).is_file():
            folders.setdefault(job.out_dir.resolve(), job.out_dir)
    if out_dir is None:
        for layer in parts:  # a layer converted alone once: its own folder beside it
            own = beside(Path(layer))
            if (own / manifest.NAME).is_file():
                folders.setdefault(own.resolve(), own)
        for here in {job.scene.parent.resolve(): job.scene.parent for job in jobs}.values():
            for near in _output_folders_in(here):
                folders.setdefault(near.resolve(), near)
    layers = {Path(k).resolve(): v for k, v in parts.items()}
    found = []
    for key, folder in sorted(folders.items()):
        try:
            entries = manifest.load(folder)["scenes"]
        except manifest.ManifestError:
            continue  # reported as stale by the run that plans into it
        for name, entry in entries.items():
            if not isinstance(entry.get("source"), str):
                continue
            source = Path(os.path.normpath(folder / entry["source"]))
            job = planned.get(key)
            no_relief = job is not None and states.get(key) == "skipped" and bool(entry["outputs"])  # not a record
            reason = _reason(source, job, no_relief, layers)
            if reason:
                found.append(Orphan(folder, name, source, reason))
            elif entry.get("folder", key.name) != key.name:  # written in a folder of another name
                found.append(Orphan(folder, name, source, f"a copy of the outputs of {source}, written in "
                                    f"{entry['folder']}/: renamed or copied by hand", "duplicate"))
    return found


def _output_folders_in(folder: Path) -> list[Path]:
    """The output folders directly in ``folder`` (``*_csm`` holding a manifest): one listing."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    return [folder / n for n in names if n.endswith(OUTPUT_SUFFIX) and (folder / n / manifest.NAME).is_file()]


def _reason(source: Path, job, no_relief: bool, layers: dict) -> str | None:
    if no_relief and job.scene.resolve() == source.resolve():
        return "its scene no longer has relief (no height texture found): these outputs are not refreshed"
    if not os.path.lexists(source):
        return f"its scene {source} is gone (renamed, moved or deleted)"
    if source.resolve() in layers:
        return f"its scene is now a layer of {layers[source.resolve()]}, converted with it"
    return None


def remove(orphan: Orphan) -> list[Path] | None:
    """Remove ``orphan``'s own outputs (files no other entry of the folder owns) and its
    entry; the manifest goes when no entry is left, the folder when it is then empty.
    Only plain files inside the folder are touched, under the folder's lock (a conversion
    into it meanwhile neither loses its entry nor a file it shares).

    Args:
        orphan: from :func:`find`.

    Returns:
        The files removed (none when the entry's files were gone already: the manifest still
        changed), or None when the entry itself was gone (nothing changed).
    """
    if not (orphan.out_dir / manifest.NAME).is_file():
        return None  # removed meanwhile (the folder is not made again to lock it)
    with locked(orphan.out_dir):
        return _remove(orphan)


def _remove(orphan: Orphan) -> list[Path] | None:
    m = manifest.load(orphan.out_dir)
    entry = m["scenes"].pop(orphan.scene, None)
    if entry is None:
        return None
    others = manifest.owned_by_others({"scenes": {orphan.scene: entry, **m["scenes"]}}, orphan.scene)
    man = orphan.out_dir / manifest.NAME
    removed = []
    if m["scenes"]:  # the entry goes first: an interrupted removal leaves files no entry names
        with atomic_path(man) as tmp:
            manifest.write(tmp, m, version=m["version"])
    else:
        man.unlink()
        removed.append(man)
    for name in entry.get("outputs", {}):
        file = orphan.out_dir / name
        if name in others or name == manifest.NAME or Path(name).name != name or not file.is_file() \
                or file.is_symlink():  # a manifest naming itself among its outputs keeps it
            continue
        file.unlink()
        removed.append(file)
    if not m["scenes"]:
        with contextlib.suppress(OSError):  # something else lives there: left as it is
            orphan.out_dir.rmdir()
    return removed
