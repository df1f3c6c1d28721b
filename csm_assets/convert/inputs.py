"""A conversion's inputs as they were read, so that a manifest never records the hash of
bytes other than those converted.

:class:`Snapshot` looks at each input file (its sha256, device, inode, size and mtime) before
the conversion uses it: the scene file before it is read, its buffers, libraries and height
textures as soon as the scene names them (before a texel is read for a step map). Before
publishing, :meth:`Snapshot.confirm` looks again: a file replaced or rewritten meanwhile
raises :class:`InputChanged` (exit 3, nothing published; the old outputs stay, and ``check``
calls them stale), else the manifest gets the hashes of the first look.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import FormatError
from .hashes import file_hash


class InputChanged(FormatError):
    """An input file changed while it was being converted (exit 3): nothing was published."""


def look(path) -> tuple | None:
    """``(st_dev, st_ino, st_size, st_mtime_ns, sha256)`` of the regular file ``path`` (None for
    anything else: no FIFO or device is read here). Raises InputChanged when the file changes
    while it is hashed, OSError when it cannot be read."""
    before = _ident(path)
    if before is None:
        return None
    digest = file_hash(path)
    if _ident(path) != before:
        raise InputChanged(path, "changed while it was being hashed; nothing was written (run again)")
    return (*before, digest)


def _ident(path) -> tuple | None:
    st = os.stat(path)
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns) if stat.S_ISREG(st.st_mode) else None


class Snapshot:
    """The first look at each input of one conversion, keyed by resolved path."""

    def __init__(self):
        self.seen: dict[Path, tuple | None] = {}

    def take(self, files) -> None:
        """Look at each of ``files`` not looked at yet (a file that cannot be read now is
        recorded as such: the reader that needs it says why)."""
        for f in map(Path, files):
            key = f.resolve()
            if key not in self.seen:
                try:
                    self.seen[key] = look(f)
                except (FileNotFoundError, PermissionError, NotADirectoryError):
                    self.seen[key] = None

    def confirm(self, files) -> dict[Path, str]:
        """``{file: sha256}`` of ``files`` as the conversion read them. Raises InputChanged
        naming the first file that is not what it was at the first look (replaced,
        rewritten, gone), FormatError for an input that is not a regular file (it cannot be
        hashed again: freshness could not be told)."""
        digests = {}
        for f in dict.fromkeys(map(Path, files)):
            key = f.resolve()
            try:
                now = look(f)
            except FileNotFoundError:
                if key in self.seen and self.seen[key] is None:
                    raise FormatError(f, "is missing; expected the file the scene names") from None
                raise InputChanged(f, "was removed while it was being converted; nothing was written "
                                      "(run again)") from None
            if now is None:
                raise FormatError(f, "is not a regular file; expected an image, scene, buffer or library file "
                                     "that can be read again to record its hash")
            if key in self.seen and self.seen[key] != now:
                raise InputChanged(f, "changed while it was being converted (replaced or rewritten after it was "
                                      "read); nothing was written (run again)")
            digests[f] = now[-1]
        return digests
