"""Atomic file output: write to a temporary file beside the target, then rename."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from .errors import OutputError


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path`` (same suffix, so writers that pick the
    format by extension still work); on success it replaces ``path`` in one rename.

    On any error the temporary file is removed and ``path`` is left as it was.
    OSErrors while creating or renaming become :class:`OutputError`.
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}",
                                   dir=path.parent if str(path.parent) else ".")
        os.close(fd)
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
