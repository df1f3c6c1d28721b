"""The manifest beside converted outputs: what they were made from, to skip fresh work.

``csm-manifest.json`` in an output folder records, for **each scene** converted into that
folder, the settings, the sha256 of every input file the conversion read (the scene, its
buffers, material libraries and textures) and of every output it wrote, and its warnings.
Several scenes may share one folder (a ``for f in *.gltf`` loop into ``out/``); each entry
tells the truth for its own scene, and which files each scene owns decides the names the
next conversion may take. A scene's outputs are fresh when all of its entry still holds
(one hash per file, no conversion).

Shape (format 2)::

    {"tool": "csm-assets", "version": "0.1.0", "format": 2,
     "scenes": {"wall.gltf": {"scene": "wall.gltf", "version": "0.1.0", "source": "../in/wall.gltf", "root": "../..",
                              "folder": "wall_gltf_csm",
                              "settings": {...}, "inputs": {"models/wall.gltf": "<sha256>", ...},
                              "outputs": {"wall.gltf": "<sha256>", ...},
                              "absent": ["textures/wall_height.png"], "picks": {...}, "warnings": [...]}}}

``warnings`` holds every warning of the conversion, ignored ones too, as
:meth:`csm_assets.warning_codes.Notice.record` writes them (``{"code", "where", "text", "about",
"count"}``; plain strings from before codes read as CSM000).
``folder`` is the output folder's own name when written (a folder renamed or copied by hand holds
outputs under a name no run writes: :mod:`csm_assets.convert.orphans` reports them).
``source`` is the scene's path and ``root`` the project root's (see
:mod:`csm_assets.config.files`), both relative to the output folder (so all may move
together); ``inputs`` keys are relative to the project root, resolved (symlinks followed),
so they never depend on the working directory or on how a path was spelled; ``outputs``
keys are plain file names in the output folder; ``absent`` lists, keyed as ``inputs``, the files the
scene names that did not exist (a missing texture: its appearing makes the outputs stale; none when
the key is missing). An entry without ``root`` (written before
it) has its keys relative to the scene's folder. A format-1 manifest (one scene at the
top level) is read as one entry.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path, PurePosixPath

from .. import __version__
from ..config.files import project_root
from .. import udim
from ..errors import OutputError, not_regular
from ..udim import TOKEN
from .hashes import TEXT_SUFFIXES, content_hash, file_hash  # noqa: F401 (the manifest API)

NAME = "csm-manifest.json"
"""The manifest's file name in every output folder; a folder holding one is an output folder."""
HEIGHT_NOTE = re.compile(r"( \((depth map|channel [^()]*)\))+$")  # after a height texture's key in the settings
FORMAT = 2
MAX_BYTES = 64 << 20  # a manifest is read only up to this size (about 20,000 scenes' entries)


class ManifestError(OutputError):
    """A ``csm-manifest.json`` that is not a csm-assets manifest (exit 4: the folder's
    ownership of files is unknown, so nothing is overwritten)."""


def path_key(root, file) -> str:
    """``file``'s key in ``inputs`` (and a height texture's in the settings).

    Args:
        root (str | os.PathLike): the project root.
        file (str | os.PathLike): the input.

    Returns:
        Its resolved path relative to ``root`` (posix), whatever the working directory.
    """
    return Path(os.path.relpath(Path(file).resolve(), Path(root).resolve())).as_posix()


def source_key(scene_path, out_dir) -> str:
    """The scene's path relative to the output folder (posix)."""
    return Path(os.path.relpath(Path(scene_path).resolve(), Path(out_dir).resolve())).as_posix()


def entry(scene_path, out_dir, inputs, outputs, settings: dict, picks: dict, warnings: list[dict], *,
          root=None, absent=()) -> dict:
    """One scene's record (``inputs``: ``{path: sha256}`` as read, see :mod:`csm_assets.convert.inputs`,
    or paths to hash now; ``outputs``: paths named as the output files; ``absent``: files named that do
    not exist; ``root``: the project root, by default :func:`~csm_assets.config.files.project_root`)."""
    root = Path(root).resolve() if root is not None else project_root(scene_path)
    hashes = inputs if isinstance(inputs, dict) else {f: file_hash(f) for f in dict.fromkeys(map(Path, inputs))}
    return {
        "scene": Path(scene_path).name, "version": __version__, "source": source_key(scene_path, out_dir),
        "folder": Path(out_dir).resolve().name,
        "root": source_key(root, out_dir),
        "settings": json.loads(json.dumps(settings)),
        "inputs": {path_key(root, f): digest for f, digest in hashes.items()},
        "outputs": {Path(f).name: file_hash(f) for f in outputs},
        "absent": sorted({path_key(root, f) for f in absent}),
        "picks": picks, "warnings": list(warnings),
    }


def load(out_dir) -> dict:
    """The manifest of an output folder.

    Args:
        out_dir (str | os.PathLike): the output folder.

    Returns:
        ``{"version", "scenes": {name: entry}}`` (no scenes when there is no manifest).

    Raises:
        ManifestError: an OutputError naming the file when it is unreadable or of the wrong
            shape (exit 4).
    """
    path = Path(out_dir) / NAME
    raw = _read(path, Path(out_dir))
    if raw is None:
        return {"version": __version__, "scenes": {}}
    try:
        m = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as e:
        raise ManifestError(path, f"not a csm-assets manifest (not JSON: {e}); remove it or choose "
                                  "another output folder") from e
    problem = _shape_problem(m)
    if problem:
        raise ManifestError(path, f"not a csm-assets manifest ({problem}); remove it or choose another "
                                  "output folder")
    if "scenes" not in m:  # format 1: one scene at the top level
        m = {"version": m["version"], "scenes": {m["scene"]: m}}
    return {"version": m["version"], "scenes": m["scenes"]}


def _read(path: Path, out_dir: Path) -> bytes | None:
    """The bytes of the manifest at ``path`` (None when there is none): a regular file of at most
    :data:`MAX_BYTES`, or a link to one inside ``out_dir``; else a ManifestError, found unread."""
    fix = "; remove it or choose another output folder"
    target = Path(os.path.realpath(path))
    if path.is_symlink() and not target.is_relative_to(Path(os.path.realpath(out_dir))):
        raise ManifestError(path, f"is a link leading outside its output folder (to {target}); expected a "
                                  f"csm-assets manifest file{fix}")
    try:
        if (problem := _unfit(os.stat(path))) is None:  # opened without blocking, checked again once open
            with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC), "rb") as f:
                problem = _unfit(os.fstat(f.fileno()))
                raw = b"" if problem else f.read(MAX_BYTES + 1)
                if len(raw) > MAX_BYTES:
                    problem = f"a file of more than {MAX_BYTES} bytes"
    except FileNotFoundError:
        return None
    except OSError as e:
        raise ManifestError(path, f"cannot read the manifest: {e.strerror or e}") from e
    if problem is not None:
        raise ManifestError(path, f"is {problem}, not a csm-assets manifest (expected a regular JSON file of at "
                                  f"most {MAX_BYTES >> 20} MiB){fix}")
    return raw


def _unfit(st: os.stat_result) -> str | None:
    """What makes a file of status ``st`` no manifest to read (not a regular file, too big), or None."""
    if stat.S_ISREG(st.st_mode):
        return f"a file of {st.st_size} bytes" if st.st_size > MAX_BYTES else None
    return not_regular(st.st_mode)


def _shape_problem(m) -> str | None:
    """What makes ``m`` not a manifest of either format, or None."""
    if not isinstance(m, dict):
        return f"the top level is {type(m).__name__}, expected an object"
    if not isinstance(m.get("version"), str):
        return "'version' is missing or not a string"
    if "scenes" in m:
        if not isinstance(m["scenes"], dict):
            return "'scenes' is not an object"
        entries = m["scenes"].items()
    else:
        entries = [(m.get("scene"), m)]
    for name, e in entries:
        if not isinstance(name, str) or not isinstance(e, dict):
            return f"scene entry {str(name)[:60]!r} is not an object"
        if not isinstance(e.get("settings"), dict):
            return f"scene {name[:60]!r}: 'settings' is not an object"
        for key in ("inputs", "outputs"):
            files = e.get(key)
            if not isinstance(files, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                                      for k, v in files.items()):
                return f"scene {name[:60]!r}: {key!r} is not an object of file names and hashes"
        if not all(_plain_name(k) for k in e["outputs"]):
            return f"scene {name[:60]!r}: an output is not a plain file name"
        if not isinstance(absent := e.get("absent", []), list) or not all(isinstance(k, str) for k in absent):
            return f"scene {name[:60]!r}: 'absent' is not a list of paths"
        for key in ("source", "root", "version", "folder"):
            if key in e and not isinstance(e[key], str):
                return f"scene {name[:60]!r}: {key!r} is not a string"
    return None


def _plain_name(name: str) -> bool:
    return bool(name) and name not in (".", "..") and "/" not in name and "\\" not in name and "\0" not in name


def write(path, m: dict, *, version: str = __version__) -> None:
    """Write manifest ``m`` (as :func:`load` returns it) to ``path`` (a plain write: the
    caller writes it into a staging folder or through :func:`csm_assets.atomic.atomic_path`),
    as made by ``version`` (this one: it converted them; another only where entries are
    removed, not made)."""
    before = m.get("version", version)  # entries written before each held its version: the folder's
    scenes = {name: e if "version" in e else {**e, "version": before} for name, e in m["scenes"].items()}
    data = {"tool": "csm-assets", "version": version, "format": FORMAT, "scenes": scenes}
    Path(path).write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")


def owned_by_others(m: dict, scene_name: str) -> dict[str, str]:
    """Output names other scenes' entries hold, each with its scene (a conversion of ``scene_name``
    takes other names, or shares a file only for the same bytes)."""
    return {name: s for s, e in m["scenes"].items() if s != scene_name for name in e["outputs"]}


def recorded_root(e: dict, scene_path, out_dir) -> Path:
    """The project root a manifest entry's input keys are relative to.

    Args:
        e: the scene's entry.
        scene_path (str | os.PathLike): the scene.
        out_dir (str | os.PathLike): the output folder holding the manifest.

    Returns:
        The resolved root (the scene's folder for an entry written before roots were recorded).
    """
    if isinstance(e.get("root"), str):
        return (Path(out_dir) / e["root"]).resolve()
    return Path(scene_path).resolve().parent


def staleness(scene_path, out_dir, settings: dict, m: dict | None = None, *, root=None) -> str | None:
    """Why the outputs in ``out_dir`` are stale for this scene and settings, or None if fresh.

    Never hashes a file outside the project root unless the settings allow outside paths or
    name it as a height texture (a manifest's keys are not trusted), nor outside ``out_dir``.

    Args:
        scene_path (str | os.PathLike): the scene.
        out_dir (str | os.PathLike): its output folder.
        settings: ``ConvertOptions(...).settings()`` (what the manifest stores).
        m: the manifest already loaded (None: load it).
        root (str | os.PathLike | None): the project root (None: :func:`~csm_assets.config.files.project_root`).

    Returns:
        The reason, one line (an unreadable manifest's message too; ``FILE appeared`` for a file named
        and absent when converted), or None if fresh.
    """
    scene_path, out_dir = Path(scene_path), Path(out_dir)
    root = Path(root).resolve() if root is not None else project_root(scene_path)
    if m is None:
        try:
            m = load(out_dir)
        except ManifestError as e:
            return str(e)[len(e.path) + 2:]
    e = m["scenes"].get(scene_path.name)
    if e is None:
        return "never converted (no manifest)" if not m["scenes"] else "never converted (not in the manifest)"
    if e.get("source", source_key(scene_path, out_dir)) != source_key(scene_path, out_dir):
        return f"the outputs are another scene's ({e['source']})"
    made_by = e.get("version", m["version"])  # the folder's for entries written before their own
    if made_by != __version__:
        return f"made by csm-assets {made_by}, this is {__version__}"
    if e["settings"] != json.loads(json.dumps(settings)):
        return "settings changed"
    if recorded_root(e, scene_path, out_dir) != root:
        return f"the project root changed (now {root})"
    inputs = e["inputs"]
    if path_key(root, scene_path) not in inputs:
        return "manifest is for another scene"
    where = "the scene's folder" if root == scene_path.resolve().parent else "the project root"
    outside = f"manifest names an input outside {where}"
    named = {HEIGHT_NOTE.sub("", str(v)) for v in (settings.get("heights") or {}).values()}
    for rel, digest in [*inputs.items(), *((rel, None) for rel in e.get("absent", []))]:
        if "\0" in rel or PurePosixPath(rel).is_absolute():
            return f"{outside} ({rel[:80]!r})"
        f = root / rel
        if not settings.get("allow_outside") and rel not in named and not f.resolve().is_relative_to(root):
            return f"{outside} ({rel[:80]!r})"
        if digest is None:  # named and absent when converted
            if f.is_file() or TOKEN in rel and udim.record(f):
                return f"{rel} appeared"
            continue
        if TOKEN in rel:  # a UDIM set: the tiles it has (each tile's bytes are inputs of their own)
            if udim.record(f) != digest:
                return f"UDIM set {rel} changed ({udim.record(f) or 'no tile'}, was {digest})"
            continue
        if not f.is_file():
            return f"input {rel} is gone"
        if file_hash(f) != digest:
            return f"input {rel} changed"
    for name, digest in e["outputs"].items():
        f = out_dir / name
        if f.is_symlink():  # conversions publish regular files only
            return f"output {name} was replaced by a link"
        if not f.is_file():
            return f"output {name} is missing"
        if file_hash(f) != digest:
            return f"output {name} was modified"
    return None


def output_folders(roots) -> list[Path]:
    """The output folders under ``roots`` (folders), hidden folders left out."""
    found = []
    for root in roots:
        for folder, dirs, files in os.walk(root):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            if NAME in files:
                found.append(Path(folder))
    return found
