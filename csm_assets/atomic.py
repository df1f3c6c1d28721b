"""Atomic file output: write to a temporary file beside the target, check, sync, rename."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
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
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        if path.exists():
            os.chmod(tmp, path.stat().st_mode & 0o7777)
    except OSError as e:
        raise OutputError(path, f"cannot write here: {_reason(e)}") from e
    try:
        yield Path(tmp)
        if check is not None:
            check(Path(tmp))
        sync_file(tmp)
        os.replace(tmp, path)
        _sync_dir(path.parent)
    except OutputError:
        _unlink(tmp)
        raise
    except OSError as e:
        _unlink(tmp)
        raise OutputError(path, f"cannot write: {_reason(e)}") from e
    except BaseException:
        _unlink(tmp)
        raise


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
