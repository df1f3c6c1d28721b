"""The output folder of a conversion: staging, the names a scene may take, publishing.

A conversion makes every file in a staging folder inside the output folder and moves
them into place (one rename each, manifest last) only when all of it succeeded. Before
that, :func:`check_names` makes sure that no output overwrites an input (through any
folder or link), that a conversion's names are distinct and never the manifest's, and
that no file another scene in the same folder owns is taken. A folder is locked
(``flock``) while a conversion works in it, so conversions into one folder take turns.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import OutputError
from .manifest import NAME as MANIFEST
from .hashes import content_hash, file_hash

STAGE_PREFIX = ".csm-stage-"


@contextlib.contextmanager
def locked(out_dir: Path):
    """Create ``out_dir`` if needed and hold an exclusive lock on it for the block. A lock is
    only held on the folder that is at ``out_dir`` once it is granted: when the folder a
    waiting conversion locked was removed meanwhile (a conversion that created it failed and
    removed it), or replaced, the folder is made and locked again. A folder created here and
    left empty (a failed conversion) is removed while the lock is still held."""
    for _ in range(100):
        created = not out_dir.exists()
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
            fd = os.open(out_dir, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        except OSError as e:
            raise OutputError(out_dir, f"cannot write the output folder: {e.strerror or e}") from e
        with contextlib.suppress(OSError):  # filesystems without flock: no lock, as before
            fcntl.flock(fd, fcntl.LOCK_EX)
        if _still_there(fd, out_dir):
            break
        os.close(fd)  # granted on a folder that is gone: take the one at out_dir now
    else:
        raise OutputError(out_dir, "the output folder was removed or replaced 100 times while waiting for its lock")
    try:
        yield out_dir
    finally:
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()  # before unlocking: a waiting conversion never gets the removed folder
        os.close(fd)


def _still_there(fd: int, out_dir: Path) -> bool:
    """Whether the open folder ``fd`` is still the folder at ``out_dir`` (not removed, not replaced:
    an inode held open is never reused, so device and inode tell)."""
    try:
        held, now = os.fstat(fd), os.stat(out_dir)
    except OSError:
        return False
    return (held.st_dev, held.st_ino) == (now.st_dev, now.st_ino)


@contextlib.contextmanager
def staging(out_dir: Path):
    """A fresh folder inside ``out_dir`` (removed afterwards)."""
    try:
        stage = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-", dir=out_dir))
    except OSError as e:
        raise OutputError(out_dir, f"cannot write the output folder: {e.strerror or e}") from e
    try:
        yield stage
    except OutputError as e:  # name the output, not its staged copy
        if Path(e.path).parent == stage:
            raise OutputError(out_dir / Path(e.path).name, reason(e)) from e
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def reason(e: OutputError) -> str:
    """The message of an OutputError without its leading path."""
    text = str(e)
    return text[len(e.path) + 2:] if text.startswith(f"{e.path}: ") else text


def clean_dead_stages(out_dir: Path) -> None:
    """Remove staging folders that killed runs left in ``out_dir``."""
    for old in out_dir.glob(f"{STAGE_PREFIX}*"):
        pid = old.name[len(STAGE_PREFIX):].split("-")[0]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` are one file (through links and folders)."""
    try:
        return Path(a).resolve() == Path(b).resolve() or os.path.samefile(a, b)
    except OSError:
        return False


def identities(files) -> set:
    """What tells ``files`` apart, once for many :func:`among` tests (a scene's inputs against
    each of its outputs: linear, not outputs times inputs): their resolved paths and, for those
    that exist, their (device, inode)."""
    ids = set()
    for f in files:
        with contextlib.suppress(OSError):
            ids.add(Path(f).resolve())
            st = os.stat(f)
            ids.add((st.st_dev, st.st_ino))
    return ids


def among(path: Path, ids: set) -> bool:
    """Whether ``path`` is one of the files :func:`identities` gave ``ids`` (as :func:`same_file`)."""
    try:
        if Path(path).resolve() in ids:
            return True
        st = os.stat(path)
    except OSError:
        return False
    return (st.st_dev, st.st_ino) in ids


def check_not_input(path: Path, inputs, ids: set | None = None) -> None:
    """OutputError when writing ``path`` would overwrite one of ``inputs`` (``ids``: their
    :func:`identities`, when known)."""
    path = Path(path)
    if among(path, identities(inputs) if ids is None else ids):
        f = next((f for f in inputs if same_file(path, f)), path)
        raise OutputError(path, f"would overwrite the input {f}; choose another output path "
                                "(inputs are never overwritten)")


def check_names(stage: Path, names: list[str], out_dir: Path, inputs, others: dict[str, str]) -> None:
    """The staged ``names`` may be published into ``out_dir``: distinct, not the manifest,
    none of them an input, and none another scene's file (``others``: name -> owner)
    unless it holds the same bytes (scenes may share an identical file, e.g. one MTL
    library). OutputError otherwise."""
    seen, ids = set(), identities(inputs)
    for name in names:
        if name in seen:
            raise OutputError(out_dir / name, "two outputs of this scene would take this name "
                                              "(one would overwrite the other)")
        seen.add(name)
        if name == MANIFEST:
            raise OutputError(out_dir / name, "an output would take the manifest's name")
        check_not_input(out_dir / name, inputs, ids)
        theirs = out_dir / name
        if name in others and theirs.is_file() and file_hash(theirs) != file_hash(stage / name):
            raise OutputError(theirs, f"is the output of another scene in this folder ({others[name]}) "
                                      "with other content; convert this scene into another folder")


def free_name(stem: str, suffix: str, taken, others: dict[str, Path] | None = None, content=None) -> str:
    """The one rule every writer and the step maps name their outputs by.

    Scenes may share one identical file, never overwrite another's.

    Args:
        stem: the name without its suffix.
        suffix: ``.png``, ``.gltf``, ...
        taken (set | Callable): names already used (a set, or a predicate on a name).
        others: name -> the file another scene owns in the output folder.
        content (str | os.PathLike | bytes | None): what this file will hold; another
            scene's file of the same content is no clash.

    Returns:
        The first of ``stem + suffix``, ``stem_1 + suffix``, ``stem_2 + suffix`` ... that is
        free.
    """
    held = taken if callable(taken) else taken.__contains__
    digest = []

    def clash(name: str) -> bool:
        if held(name):
            return True
        theirs = (others or {}).get(name)
        if theirs is None or not Path(theirs).is_file():
            return False
        if content is None:
            return True
        if not digest:
            digest.append(content_hash(content, name) if isinstance(content, (bytes, bytearray))
                          else file_hash(content))
        return file_hash(theirs) != digest[0]

    name, n = f"{stem}{suffix}", 1
    while clash(name):
        name, n = f"{stem}_{n}{suffix}", n + 1
    return name


def other_files(others: dict[str, str], out_dir: Path) -> dict[str, Path]:
    """``{name: file}`` of the files other scenes own in ``out_dir`` (``others``: name -> owner)."""
    return {name: Path(out_dir) / name for name in others}


def settle(path: Path, taken: set[str], others: dict[str, Path] | None = None) -> Path:
    """``path`` renamed, if need be (:func:`free_name`), so that it takes no name of ``taken``
    and no file another scene owns (``others``) unless that file has the same bytes."""
    name = free_name(path.stem, path.suffix, taken, others, content=path)
    if name != path.name:
        path = path.rename(path.with_name(name))
    return path


def publish(stage: Path, names: list[str], out_dir: Path) -> list[Path]:
    """Move staged files into ``out_dir``, each in one rename, in the order given."""
    done = []
    for name in dict.fromkeys(names):
        try:
            os.replace(stage / name, out_dir / name)
        except OSError as e:
            raise OutputError(out_dir / name, f"cannot write: {e.strerror or e}") from e
        done.append(out_dir / name)
    return done


def remove_orphans(out_dir: Path, old: set[str], new: set[str], others: set[str], inputs) -> list[Path]:
    """Delete files this scene wrote before and no longer writes (never another scene's,
    never an input); the files deleted."""
    ids, removed = identities(inputs), []
    for name in sorted(old - new - others - {MANIFEST}):
        f = out_dir / name
        if f.is_file() and not among(f, ids):
            with contextlib.suppress(OSError):
                f.unlink()
                removed.append(f)
    return removed
