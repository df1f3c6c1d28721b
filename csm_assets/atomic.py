"""Atomic file output: write to a temporary file beside the target, then rename."""

from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path

from .errors import OutputError


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path`` (same suffix, so writers that pick the
    format by extension still work); on success it replaces ``path`` in one rename.

    On any error the temporary file is removed and ``path`` is left as it was. The new
    file gets the old one's permissions, or the umask's for a new output.
    OSErrors while creating or renaming become :class:`OutputError`.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        if path.exists():
            os.chmod(tmp, path.stat().st_mode & 0o7777)
    except OSError as e:
        raise OutputError(path, f"cannot write here: {e.strerror or e}") from e
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except OSError as e:
        _unlink(tmp)
        raise OutputError(path, f"cannot write: {e.strerror or e}") from e
    except BaseException:
        _unlink(tmp)
        raise


def _unlink(p):
    with contextlib.suppress(FileNotFoundError):
        os.unlink(p)
