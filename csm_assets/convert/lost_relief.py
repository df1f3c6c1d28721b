"""A scene without relief under ``relief_only`` (``hook``, ``check``, a folder ``convert``): nothing is
made for it, and a scene that had outputs and lost its relief keeps a **waiting record**.

A height texture renamed or deleted takes a scene's relief away. Its outputs go (they would go
stale unseen), but its manifest entry stays as a record with no outputs whose ``absent`` list names
the files the scene names and misses (the height texture, an MTL, a USD layer), its inputs hashed
as usual. While they stay missing the record is fresh ("no relief, waiting for FILE"); the moment one
exists again the record is stale (``FILE appeared``), and a commit of that file alone brings the
scene (:mod:`csm_assets.convert.dependents` reads ``absent``), so its outputs are made again. A
scene that loses its relief and misses no file (its height texture no longer named) keeps nothing:
its outputs are orphans (:mod:`csm_assets.convert.orphans`), a record of it is removed.
"""

from __future__ import annotations

import contextlib
import time

from ..atomic import atomic_path
from ..errors import StrictError
from . import manifest
from .output_folder import remove_orphans

NO_RELIEF = "no relief"  # ConvertReport.skipped of a scene without a height texture (relief_only)


def is_record(entry: dict | None) -> bool:
    """Whether a manifest entry is a waiting record (no outputs: every conversion writes some)."""
    return entry is not None and not entry.get("outputs")


def waits_for(entry: dict) -> str:
    """``waiting for FILE, ...`` of a record (the files as its ``absent`` keys them)."""
    return f"waiting for {', '.join(entry.get('absent', []))}"


def waiting_line(entry: dict) -> str:
    """``no relief; waiting for FILE, ...``: a record's reason, as ``check --json`` gives it."""
    return f"{NO_RELIEF}; {waits_for(entry)}"


def record_of(out_dir, scene_name: str) -> dict | None:
    """The waiting record of ``scene_name`` in ``out_dir``'s manifest, or None (no record, or a
    manifest that cannot be read: the run reports that)."""
    try:
        entry = manifest.load(out_dir)["scenes"].get(scene_name)
    except manifest.ManifestError:
        return None
    return entry if is_record(entry) else None


def skip(report, scene, policy, start: float):
    """``report`` of a scene without relief: nothing written (StrictError when its warnings are
    errors under ``policy``)."""
    if failing := policy.failing(scene.warnings):
        raise StrictError(scene.path, policy.kept(scene.warnings), failing, policy.why(failing))
    report.skipped = NO_RELIEF
    report.warnings = policy.kept(scene.warnings)
    report.seconds = time.perf_counter() - start
    return report


def settle(report, known: dict, scene, out_dir, settings: dict, root, digests: dict) -> None:
    """Under ``out_dir``'s lock: the entry of a scene without relief that had one in ``known`` (its
    outputs or a record) becomes a record when the scene misses a file (``scene.absent``); a record
    of a scene that misses none is removed (outputs with no missing file are left to the orphans).
    ``report.written`` gets the manifest written, ``report.removed`` the files removed.

    Args:
        report: the scene's :class:`~csm_assets.convert.pipeline.ConvertReport`.
        known: the folder's manifest as loaded under the lock.
        scene: the scene as read.
        out_dir (pathlib.Path): the output folder.
        settings: the settings the manifest stores.
        root (pathlib.Path): the project root.
        digests: ``{input: sha256}`` of the scene's inputs as read.
    """
    name, man = scene.path.name, out_dir / manifest.NAME
    mine = known["scenes"][name]
    if not scene.absent and not is_record(mine):
        return
    others = set(manifest.owned_by_others(known, name))
    if scene.absent:
        known["scenes"][name] = manifest.entry(scene.path, out_dir, digests, [], settings, {},
                                               [n.record() for n in scene.warnings], root=root, absent=scene.absent)
    else:
        del known["scenes"][name]
    if known["scenes"]:
        with atomic_path(man) as tmp:
            manifest.write(tmp, known)
        report.written = [man]
    else:
        man.unlink()
        report.removed.append(man)
    report.removed += remove_orphans(out_dir, set(mine["outputs"]), set(), others, digests)
    if not known["scenes"]:
        with contextlib.suppress(OSError):  # something else lives there: left as it is
            out_dir.rmdir()
