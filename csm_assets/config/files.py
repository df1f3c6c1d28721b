"""Where a scene's project configuration and project root are (as ruff and pre-commit find theirs),
and reading a configuration file safely.

Walking up from the scene's folder, the first folder that holds ``csm-assets.toml``, or a
``pyproject.toml`` whose parsed ``tool`` table has a ``csm-assets`` key, gives the
configuration (the first wins in one folder). The walk stops at the repository's root (the
folder holding ``.git``): a file above the repository never applies to it.

A ``csm-assets.toml`` or ``pyproject.toml`` met on the walk that cannot be read as a regular
UTF-8 TOML file of at most :data:`MAX_BYTES` (a dangling link, a FIFO, a device, a folder,
a bigger file, a TOML error) is a :class:`ConfigError` (exit 2) naming it: it is never
passed over silently, since it may be the configuration meant (ruff refuses a broken
``pyproject.toml`` alike).

The **project root** is the configuration's folder, else the repository's root, else the
scene's own folder; every path is resolved (symlinks followed), so the answer never
depends on the working directory or on how a path was spelled.
"""

from __future__ import annotations

import functools
import os
import re
import stat
from pathlib import Path

from ..errors import OptionError, not_regular
from .toml_lines import key_lines, line_of, nesting_line

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

CONFIG_NAME = "csm-assets.toml"
PYPROJECT = "pyproject.toml"
TOOL = ("tool", "csm-assets")  # the table of a pyproject.toml
MAX_BYTES = 1 << 20  # the largest configuration file read (1 MiB; real ones hold a few KB)
MAX_NESTING = 64  # arrays and tables nested deeper are refused (tomllib recurses per level)
INT_RANGE = (-(1 << 63), (1 << 63) - 1)  # TOML's integers: 64-bit, bigger ones are an error
MAX_MESSAGE = 1000  # characters of a message kept (a value shown whole could be a MiB long)


class ConfigError(OptionError):
    """A project configuration that cannot be used (exit 2): ``path``, ``line`` (None: the
    whole file) and the message, which starts with ``path:line``."""

    def __init__(self, path, line: int | None, message: str):
        self.path, self.line = str(path), line
        if len(message) > MAX_MESSAGE:
            message = message[:MAX_MESSAGE] + " ..."
        # one line whatever a key or value holds: control characters (a newline in a quoted key) escaped
        message = "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)
        super().__init__(f"{self.path}{f':{line}' if line else ''}: {message}")


def check_regular(path: Path) -> None:
    """ConfigError naming ``path`` unless it is a regular file (a link to one is followed):
    from its ``stat``, so a FIFO or a device is never opened."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise ConfigError(path, None, f"a symbolic link to {os.readlink(path)!r}, which does not exist; "
                                          "remove the link or make it point to a file") from None
        raise ConfigError(path, None, "no such file") from None
    except (OSError, ValueError) as e:
        raise ConfigError(path, None, f"cannot read: {getattr(e, 'strerror', None) or e}") from None
    kind = not_regular(st.st_mode)
    if kind is not None:
        raise ConfigError(path, None, f"is {kind}, not a configuration file (a regular file is expected)")


def read_text(path: Path) -> str:
    """The text of the configuration file ``path``: a regular file (:func:`check_regular`)
    of at most :data:`MAX_BYTES`, UTF-8. ConfigError naming ``path`` otherwise."""
    check_regular(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # swapped since the stat above
                raise ConfigError(path, None, "is not a regular file")
            os.set_blocking(f.fileno(), True)
            data = f.read(MAX_BYTES + 1)
    except OSError as e:
        raise ConfigError(path, None, f"cannot read: {e.strerror or e}") from None
    if len(data) > MAX_BYTES:
        raise ConfigError(path, None, f"larger than {MAX_BYTES >> 20} MiB: not a configuration file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(path, data.count(b"\n", 0, e.start) + 1, f"not UTF-8 text: {e.reason} at byte "
                                                                    f"{e.start}") from None


def read_toml(path: Path) -> tuple[str, dict]:
    """``(text, data)`` of the TOML file ``path`` (:func:`read_text`), parsed. ConfigError
    with the line for a TOML error, values nested more than :data:`MAX_NESTING` deep (found
    in the text before parsing, as tomllib recurses per level, and in the parsed tables,
    which dotted keys nest without brackets) and integers outside TOML's 64 bits."""
    text = read_text(path)
    return text, parse_toml(path, text)


def parse_toml(path: Path, text: str) -> dict:
    """The TOML ``text`` of ``path`` parsed and checked (see :func:`read_toml`)."""
    deep = nesting_line(text, MAX_NESTING)
    if deep is not None:
        raise ConfigError(path, deep, f"arrays and inline tables nested more than {MAX_NESTING} deep")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        at = re.search(r"\(at line (\d+), column \d+\)$", str(e))
        raise ConfigError(path, int(at[1]) if at else None, f"not valid TOML: {e}") from None
    except (ValueError, RecursionError):  # tomllib's int() of a number of thousands of digits
        long = re.search(r"[0-9_]{4000}", text)
        raise ConfigError(path, text.count("\n", 0, long.start()) + 1 if long else None,
                          "not valid TOML: a number of thousands of digits" if long else
                          "not valid TOML: values nested too deep to read") from None
    problem = _out_of_bounds(data)
    if problem is not None:
        keys, message = problem
        lines = key_lines(text)
        line = line_of(lines, keys) or next((n for k, n in lines.items() if k[:len(keys)] == keys), None)
        raise ConfigError(path, line, message)
    return data


def _out_of_bounds(data: dict) -> tuple[tuple, str] | None:
    """The key path and message of the first value nested too deep or of an integer out of
    range, or None. Iterative: a value of any depth is walked without recursion."""
    stack = [((), data)]
    while stack:
        keys, value = stack.pop()
        if len(keys) > MAX_NESTING:
            return keys[:MAX_NESTING], f"tables and arrays nested more than {MAX_NESTING} deep"
        if isinstance(value, dict):
            stack.extend(((*keys, k), v) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend(((*keys, i), v) for i, v in enumerate(value))
        elif isinstance(value, int) and not isinstance(value, bool) and not INT_RANGE[0] <= value <= INT_RANGE[1]:
            shown = ".".join(str(k) for k in keys if isinstance(k, str))
            return keys, f"{shown + ': ' if shown else ''}an integer outside TOML's 64-bit range"
    return None


@functools.lru_cache(maxsize=16)
def _tool_table_in(path: str, text: str) -> bool:
    tool = parse_toml(Path(path), text).get(TOOL[0])
    return isinstance(tool, dict) and TOOL[1] in tool


def has_tool_table(pyproject: Path) -> bool:
    """Whether ``pyproject`` holds a ``csm-assets`` key in its ``tool`` table, by parsing it
    (a ``[tool.csm-assets]`` inside a string or a comment is no table). ConfigError for a
    file that cannot be read or parsed. The file is read each time, parsed once per text (a
    run of many scenes below one pyproject.toml)."""
    return _tool_table_in(str(pyproject), read_text(pyproject))


def _config_in(folder: Path) -> Path | None:
    """The configuration file in ``folder`` itself, or None; ConfigError for a file of
    either name there that cannot be read (see the module doc)."""
    own = folder / CONFIG_NAME
    if os.path.lexists(own):
        check_regular(own)  # a dangling link, a FIFO, a device, a folder: refused, named
        return own
    pyproject = folder / PYPROJECT
    return pyproject if os.path.lexists(pyproject) and has_tool_table(pyproject) else None


def _folders(start: Path):
    """``start`` (resolved) and the folders above it, up to the repository's root or the
    filesystem's: each with whether it is a repository's root."""
    for folder in (start, *start.parents):
        is_repo = (folder / ".git").exists()
        yield folder, is_repo
        if is_repo:
            return


def scene_folder(scene) -> Path:
    """The resolved folder holding ``scene``."""
    return Path(scene).resolve().parent


def find_config(scene) -> Path | None:
    """The configuration file that applies to ``scene``: the nearest ``csm-assets.toml``, or
    ``pyproject.toml`` with ``[tool.csm-assets]``, walking up to the repository's root.

    Args:
        scene (str | os.PathLike): a scene file (or folder).

    Returns:
        The file (in a resolved folder), or None.

    Raises:
        ConfigError: a configuration file there that is no regular file (an OptionError).
    """
    for folder, _ in _folders(scene_folder(scene)):
        found = _config_in(folder)
        if found is not None:
            return found
    return None


def repository_root(scene) -> Path | None:
    """The git repository (or worktree) holding ``scene``.

    Args:
        scene (str | os.PathLike): a scene file (or folder).

    Returns:
        The repository's root folder (resolved), or None outside one.
    """
    for folder, is_repo in _folders(scene_folder(scene)):
        if is_repo:
            return folder
    return None


def project_root(scene, config: Path | None = None) -> Path:
    """The folder ``scene``'s inputs are recorded relative to (resolved).

    Args:
        scene (str | os.PathLike): a scene file.
        config (pathlib.Path | None): the configuration; None: the one :func:`find_config`
            finds.

    Returns:
        The configuration's folder, else the repository's root, else the scene's own folder.
    """
    config = config if config is not None else find_config(scene)
    if config is not None:
        return Path(config).resolve().parent
    return repository_root(scene) or scene_folder(scene)
