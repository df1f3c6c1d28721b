"""Errors the library raises on purpose; the CLI maps each to an exit code."""

from __future__ import annotations


class FormatError(ValueError):
    """A file could not be read or written as the format it claims to be.

    The message always starts with the file's path and says what was expected.
    """

    def __init__(self, path, message: str):
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class OptionsError(ValueError):
    """An option is wrong for this input (a bit depth the format cannot hold, a variant
    without its budget): the CLI's exit code 2, as for bad arguments."""


class OutputError(OSError):
    """An output could not be written (directory missing, no permission, disk full)."""

    def __init__(self, path, message: str):
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")
