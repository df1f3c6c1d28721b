"""The files ``csm-assets view`` serves: opened afresh and checked on every request.

:class:`Folder` holds a descriptor of a folder (the scene's, the page's) from start-up on;
:meth:`Folder.open` opens one file beneath it, walking each path part with ``O_NOFOLLOW``
from that descriptor, so a file, or a folder on its way, swapped after start-up for a link
that leads out, a FIFO or a device (``/dev/zero``) is refused, never followed or read (no
check-then-open race). A link that stays inside the folder is followed (its target is
opened, the same way). The opened descriptor is checked with ``fstat``: a regular file of
at most :data:`MAX_FILE_BYTES`. :func:`content_type` gives only the types a glTF can
reference; everything else is ``application/octet-stream``.
"""

from __future__ import annotations

import os
import posixpath
import stat
from pathlib import Path

# the largest file served: a GLB cannot be larger (its length field has 32 bits)
MAX_FILE_BYTES = (1 << 32) - 1
# what a glTF scene may reference (the document, buffers, images of the core spec and of
# KHR_texture_basisu, EXT_texture_webp, EXT_texture_avif); nothing active (html, svg, js)
SCENE_TYPES = {".gltf": "model/gltf+json", ".glb": "model/gltf-binary", ".bin": "application/octet-stream",
               ".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".webp": "image/webp",
               ".ktx2": "image/ktx2", ".avif": "image/avif"}
# the viewer's own files (csm_assets/web)
PAGE_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript", ".wasm": "application/wasm"}
OCTET_STREAM = "application/octet-stream"

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_NONBLOCK = getattr(os, "O_NONBLOCK", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_BINARY = getattr(os, "O_BINARY", 0)
_WALK = _DIRECTORY and _NOFOLLOW and os.open in os.supports_dir_fd


def content_type(name: str, table: dict = SCENE_TYPES) -> str:
    """The Content-Type of ``name`` by its suffix (any case) in ``table``, else octet-stream."""
    return table.get(posixpath.splitext(name)[1].lower(), OCTET_STREAM)


class Refused(Exception):
    """The file cannot be served (missing, a link out, not a regular file, too big)."""


def parts(rel: str) -> list[str]:
    """The parts of a relative path (``/`` or ``\\`` separated); Refused for an empty,
    absolute or ``..`` path, or one holding a NUL byte."""
    text = rel.replace("\\", "/")
    if not text or text.startswith("/") or "\0" in text:
        raise Refused(rel)
    out = [p for p in posixpath.normpath(text).split("/") if p not in ("", ".")]
    if not out or ".." in out:
        raise Refused(rel)
    return out


class Folder:
    """A folder opened once; files beneath it opened per request (see the module doc)."""

    def __init__(self, path):
        self.path = Path(os.path.realpath(path))
        self.fd = os.open(self.path, os.O_RDONLY | _DIRECTORY | _CLOEXEC) if _WALK else None

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def open(self, rel: str):
        """``(file, size)``: a binary file object open on the regular file at ``rel`` beneath
        the folder and its size at opening. Refused for anything else (see the module doc)."""
        names = parts(rel)
        try:
            # links inside the folder are followed to their target, which must stay inside
            real = os.path.realpath(os.path.join(self.path, *names))
            if os.path.commonpath([real, str(self.path)]) != str(self.path) or real == str(self.path):
                raise Refused(rel)
            fd = self._open_beneath(os.path.relpath(real, self.path).split(os.sep))
        except (OSError, ValueError) as e:
            raise Refused(f"{rel}: {e}") from None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_FILE_BYTES:
                raise Refused(rel)
            if _NONBLOCK:
                os.set_blocking(fd, True)
            return os.fdopen(fd, "rb", buffering=0), st.st_size
        except BaseException:
            os.close(fd)
            raise

    def _open_beneath(self, names: list[str]) -> int:
        flags = os.O_RDONLY | _NOFOLLOW | _NONBLOCK | _CLOEXEC | _BINARY  # no wait on a FIFO
        if not _WALK:  # no dir_fd here (Windows): the resolved path, checked above
            return os.open(os.path.join(self.path, *names), flags)
        if self.fd is None:
            raise Refused("closed")
        at = self.fd
        try:
            for name in names[:-1]:
                nxt = os.open(name, os.O_RDONLY | _DIRECTORY | _NOFOLLOW | _CLOEXEC, dir_fd=at)
                if at != self.fd:
                    os.close(at)
                at = nxt
            return os.open(names[-1], flags, dir_fd=at)
        finally:
            if at != self.fd:
                os.close(at)
