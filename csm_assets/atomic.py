"""Atomic file output: write to a temporary file beside the target, check, sync, rename; files that
go together (:func:`atomic_paths`) are all written before any is renamed."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import signal
import threading
from pathlib import Path
from typing import Callable

from .errors import OutputError


@contextlib.contextmanager
def atomic_path(path, *, check: Callable[[Path], None] | None = None):
    """Yield a temporary path beside ``path`` (same suffix, so writers that pick the
    format by extension still work); on success it replaces ``path`` in one rename.

    Before the rename the temporary file is checked (``check(tmp)``, e.g. a read-back of
    what a library wrote, raising OutputError or OSError when it is not all there) and its
    data flushed to the disk (fsync), so a full disk or a failing device is an error here
    and never a truncated file published later. On any error the temporary file is
    removed and ``path`` is left as it was. The new file gets the old one's permissions,
    or the umask's for a new output. OSErrors become :class:`OutputError`.
    """
    with atomic_paths([path]) as (tmp,):
        yield tmp
        if check is not None:
            with _naming(Path(path)):
                check(tmp)


@contextlib.contextmanager
def atomic_paths(paths):
    """:func:`atomic_path` for files that go together (a map and the images it names): yield
    their temporary paths (a list, in ``paths``' order); once the block ends without error each
    is flushed to the disk, then all are renamed in ``paths``' order (the file that names the
    others last), with Ctrl-C held back until the last rename is done. A failure before the
    renames (a full disk, an error, Ctrl-C) removes every temporary file and leaves every path
    as it was. Only a crash between two renames (microseconds) can publish some of them."""
    paths, tmps = [Path(p) for p in paths], []
    try:
        for path in paths:
            tmps.append(_temporary(path))
        yield list(tmps)
        for path, tmp in zip(paths, tmps):
            with _naming(path):
                sync_file(tmp)
        with _holding_interrupts():
            for path, tmp in zip(paths, tmps):
                with _naming(path):
                    os.replace(tmp, path)
        for folder in dict.fromkeys(p.parent for p in paths):
            _sync_dir(folder)
    except BaseException:
        for tmp in tmps:
            _unlink(tmp)
        raise


def _temporary(path: Path) -> Path:
    """A new empty file beside ``path``, of its suffix and, where ``path`` is a regular file (or a
    link to one), its permissions; else the umask's (a device's 0666 is not an output's)."""
    tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        if path.is_file():
            os.chmod(tmp, path.stat().st_mode & 0o7777)
    except OSError as e:
        _unlink(tmp)
        raise OutputError(path, f"cannot write here: {_reason(e)}") from e
    return tmp


@contextlib.contextmanager
def _naming(path: Path):
    """OSErrors inside become :class:`OutputError` naming ``path``."""
    try:
        yield
    except OutputError:
        raise
    except OSError as e:
        raise OutputError(path, f"cannot write: {_reason(e)}") from e


@contextlib.contextmanager
def _holding_interrupts():
    """SIGINT (Ctrl-C) inside goes to the process's handler (Python's: KeyboardInterrupt) once the
    block is done (main thread only: Python runs signal handlers there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    old = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
    if caught:
        signal.raise_signal(signal.SIGINT)  # to the handler restored (Python's: KeyboardInterrupt)


def sync_file(path) -> None:
    """Flush ``path``'s data to the device (OSError, e.g. ENOSPC, when it cannot be)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _sync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: not every filesystem allows it)."""
    with contextlib.suppress(OSError):
        sync_file(folder)


def _reason(e: OSError) -> str:
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return "no space left on the device (the old file, if any, is kept)"
    return " ".join(str(e.strerror or e).split())


def _unlink(p):
    with contextlib.suppress(FileNotFoundError):
        os.unlink(p)
