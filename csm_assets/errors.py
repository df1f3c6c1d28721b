"""Errors the library raises on purpose; the CLI maps each to an exit code."""

from __future__ import annotations

import os
import stat
from pathlib import Path


class FormatError(ValueError):
    """A file could not be read or written as the format it claims to be (exit code 3).

    The message always starts with the file's path and says what was expected.

    Args:
        path (str | os.PathLike): the file.
        message: what was wrong or expected.

    Attributes:
        path (str): the file, as given.
    """

    def __init__(self, path, message: str):
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class OutputError(OSError):
    """An output could not be written (directory missing, no permission, disk full): exit code 4.

    Args:
        path (str | os.PathLike): the output.
        message: what went wrong.

    Attributes:
        path (str): the output, as given.
    """

    def __init__(self, path, message: str):
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class StrictError(FormatError):
    """``--strict`` or ``--error-on``: warnings that count as errors (exit 3); nothing was
    published. ``warnings`` holds every warning reported (:class:`~csm_assets.warning_codes.Notice`),
    ``failing`` those that made it fail, ``why`` the options that did."""

    def __init__(self, path, warnings: list, failing: list | None = None, why: str = "--strict"):
        self.warnings = list(warnings)
        self.failing = list(warnings if failing is None else failing)
        codes = ", ".join(dict.fromkeys(str(getattr(n, "code", "")) for n in self.failing if getattr(n, "code", "")))
        first = str(self.failing[0]) if self.failing else ""
        super().__init__(path, f"{len(self.failing)} warning(s) are errors under {why}"
                               + (f" ({codes})" if codes else "") + f", so nothing was written (first: {first[:300]})")


class OptionError(ValueError):
    """A command-line option that does not fit the input (a ``--height`` naming no
    material of the scene, a bit depth the scene's format cannot hold, a variant without
    its budget): exit code 2, like any bad argument."""


def not_regular(mode: int) -> str | None:
    """What a file of ``mode`` (``st_mode``) is when it is no regular file ("a FIFO", "a
    character device", ...), None for a regular file: what may not be read as one."""
    if stat.S_ISREG(mode):
        return None
    return {stat.S_IFIFO: "a FIFO", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
            stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder"}.get(stat.S_IFMT(mode), "not a regular file")


def no_file(path) -> str:
    """Why ``path`` is no file to read: ``"is a FIFO, not a file"`` (a folder, a device...) when
    something else has its name, else ``"no such file"`` and :func:`case_hint`."""
    try:
        kind = not_regular(os.stat(path).st_mode)
    except OSError:
        kind = None
    return f"is {kind}, not a file" if kind else f"no such file{case_hint(path)}"


def case_hint(path) -> str:
    """For a missing ``path``: ``" (NAME is a FIFO, not a file)"`` when something other than a
    regular file has its name (a FIFO, a folder, a device: never opened); else
    ``" (NAME exists: the names differ only by letter case)"`` when its folder holds a file whose name differs only by case (a scene made on a system whose
    file names ignore case, as Dabrovic Sponza's MTL names KAMEN-BUMP.PNG for kamen-bump.png), else ''."""
    p = Path(path)
    try:
        there = os.stat(p).st_mode
    except OSError:
        there = None
    if there is not None and (kind := not_regular(there)):  # there, but nothing a reader may open
        return f" ({p.name} is {kind}, not a file)"
    try:
        twins = sorted(q.name for q in p.parent.iterdir() if q.name.lower() == p.name.lower() and q.name != p.name)
    except OSError:
        return ""
    return f" ({twins[0]} exists: the names differ only by letter case)" if twins else ""
