"""Reading one project configuration: every setting it states, with its line, checked.

The keys are the long option names of ``convert`` (``max-error``, ``self-shadow``, ...), one
per field of :class:`~csm_assets.convert.pipeline.ConvertOptions` (:func:`option_fields`:
fields added later are keys at once), plus the per-material keys::

    bits = 16                                  # every scene below this file
    [scenes."models/ship/*.gltf"]              # scenes matching a glob (relative to this file)
    height = { Hull = "../textures/hull_height.png" }   # paths relative to this file
    depth-map = { Deck = "textures/deck_disp.png" }
    depth = 0.04                               # or { Hull = 0.04 } by material

In a ``pyproject.toml`` the same lives under ``[tool.csm-assets]`` (and
``[tool.csm-assets.scenes."GLOB"]``). An unknown key, a value of the wrong kind, a missing
texture or a glob that matches no scene file is a :class:`ConfigError` naming the file and line.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import os
import re
import stat
import types
import typing
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..checks import positive
from ..convert.options import ConvertOptions
from ..convert.pipeline import SCENE_FORMATS
from ..errors import FormatError
from ..formats import format_module
from ..height_source import HeightSpec
from ..udim import is_pattern, tile_files
from .files import PYPROJECT, TOOL, ConfigError, read_toml
from .globs import Glob, matching_files
from .toml_lines import key_lines, line_of

SCENES = "scenes"                                  # [scenes."GLOB"]: settings of matching scenes
TEXTURE_KEYS = {"height": False, "depth-map": True}  # material -> texture; the value: a depth map
DEPTH = "depth"                                    # a number, or a table material -> number


@dataclass(frozen=True)
class Value:
    """One setting as a configuration (or the command line) states it: ``key`` as written
    (``bits``, ``height.Hull``), ``target`` the setting it decides (a ConvertOptions field,
    or ``("heights" | "depths", material)``), the ``value`` and ``where`` (``file:line``)."""

    key: str
    target: str | tuple[str, str]
    value: Any
    where: str


@dataclass
class Section:
    """The settings of every scene (``glob`` None) or of the scenes ``glob`` matches
    (``matches``: their resolved paths)."""

    glob: str | None
    values: list[Value] = field(default_factory=list)
    matches: frozenset = frozenset()
    problems: list = field(default_factory=list)  # ConfigErrors of the scenes it applies to only


@dataclass
class ProjectConfig:
    path: Path
    sections: list[Section]

    @property
    def folder(self) -> Path:
        return self.path.parent

    def applying(self, scene) -> list[Section]:
        """The sections that apply to ``scene``, in the order they apply (later ones win)."""
        s = Path(scene).resolve()
        return [sec for sec in self.sections if sec.glob is None or s in sec.matches]


def option_fields() -> dict[str, dataclasses.Field]:
    """Configuration key -> :class:`ConvertOptions` field, for every field the configuration
    sets (``metadata["config"]`` not False); the key is ``metadata["option"]`` or the name
    with ``-`` for ``_``."""
    return {f.metadata.get("option", f.name.replace("_", "-")): f for f in dataclasses.fields(ConvertOptions)
            if f.metadata.get("config", True)}


def load(path, check: Callable[[str, Any], Any] | None = None) -> ProjectConfig:
    """The configuration at ``path`` (``csm-assets.toml``, or a ``pyproject.toml``'s
    ``[tool.csm-assets]``). ``check(key, value)`` may check a value further and return it
    (the command line passes its option's own checks); it raises ValueError to refuse.
    ConfigError (exit 2, naming the file and line) for anything else than a table of known
    keys with values of their kinds, whatever the TOML holds (see :func:`.files.read_toml`)."""
    given = Path(os.path.realpath(Path(path).parent)) / Path(path).name  # a link as named, for its errors
    text, data = read_toml(given)
    path = given.resolve()
    lines = key_lines(text)
    prefix = TOOL if PYPROJECT in (given.name, path.name) else ()
    table = data
    for n, key in enumerate(prefix, 1):
        if key not in table:
            raise ConfigError(path, None, f"has no [{'.'.join(TOOL)}] table (the configuration of a "
                                          f"{PYPROJECT} lives there)")
        table = table[key]
        if not isinstance(table, dict):
            raise ConfigError(path, line_of(lines, prefix[:n]) or 1,
                              f"{toml_key(prefix[:n])}: expected a table, got {_kind(table)}")
    reader = _Reader(path, lines, prefix, check)
    sections = [Section(None, reader.values({k: v for k, v in table.items() if k != SCENES}, ()),
                        problems=reader.take_problems())]
    scenes = table.get(SCENES, {})
    reader.expect_table(scenes, (SCENES,))
    for glob, settings in scenes.items():
        at = (SCENES, glob)
        reader.expect_table(settings, at)
        reader.check_glob(glob, at)
        sections.append(Section(glob, reader.values(settings, at), problems=reader.take_problems()))
    matched = matching_files(path.parent, [sec.glob for sec in sections[1:]], SCENE_FORMATS)
    for sec, found in zip(sections[1:], matched):
        if not Glob(sec.glob).files:  # can never match a file: a mistake in the file itself
            raise reader.fail((SCENES, sec.glob), f"the glob matches no scene file under {path.parent} (a glob "
                                                  "ending in ** matches folders only: write **/*.gltf)")
        if not found:  # it names no scene (one moved away), so it fails none: said, not an error
            warnings.warn(reader.fail((SCENES, sec.glob), f"the glob matches no scene file under {path.parent}; "
                                                          "its settings apply to nothing").args[0], stacklevel=2)
        sec.matches = frozenset(found)
    return ProjectConfig(path, sections)


class _Reader:
    """Values of one file, each checked and placed (``where``)."""

    def __init__(self, path: Path, lines: dict, prefix: tuple, check):
        self.path, self.lines, self.prefix, self.check = path, lines, prefix, check
        self.problems: list[ConfigError] = []

    def take_problems(self) -> list:
        """The problems of the values read since the last call (see :meth:`textures`)."""
        problems, self.problems = self.problems, []
        return problems

    def line(self, at: tuple) -> int:
        return line_of(self.lines, (*self.prefix, *at)) or 1

    def where(self, at: tuple) -> str:
        return f"{self.path}:{self.line(at)}"

    def fail(self, at: tuple, message: str):
        shown = toml_key(at)
        return ConfigError(self.path, self.line(at), f"{shown + ': ' if shown else ''}{message}")

    def expect_table(self, value, at: tuple) -> None:
        if not isinstance(value, dict):
            raise self.fail(at, f"expected a table, got {_kind(value)}")

    def values(self, table: dict, at: tuple) -> list[Value]:
        out: list[Value] = []
        fields = option_fields()
        for key, value in table.items():
            here = (*at, key)
            if key in TEXTURE_KEYS:
                out += self.textures(key, value, here)
            elif key == DEPTH and isinstance(value, dict):
                out += [Value(f"{key}.{m}", ("depths", m), self.depth(d, (*here, m)), self.where((*here, m)))
                        for m, d in value.items()]
            elif key == DEPTH:
                out.append(Value(key, key, self.depth(value, here), self.where(here)))
            elif key in fields:
                out.append(Value(key, fields[key].name, self.setting(key, value, fields[key], here), self.where(here)))
            else:
                known = sorted([*fields, *TEXTURE_KEYS] + ([SCENES] if not at else []))
                close = difflib.get_close_matches(key, known, 1)
                hint = f"did you mean {close[0]!r}? " if close else ""
                raise self.fail(here, f"unknown key; {hint}the keys are {', '.join(known)}")
        seen: dict[str, str] = {}
        for v in out:  # height.X and depth-map.X in one table
            if isinstance(v.target, tuple) and v.target[0] == "heights":
                if v.target[1] in seen:
                    raise ConfigError(self.path, int(v.where.rpartition(":")[2]), f"material {v.target[1]!r} is "
                                      f"given two height textures ({seen[v.target[1]]} and {v.key})")
                seen[v.target[1]] = v.key
        return out

    def textures(self, key: str, value, at: tuple) -> list[Value]:
        if not isinstance(value, dict):
            raise self.fail(at, f"expected a table of material = \"path\", got {_kind(value)}")
        out = []
        for material, rel in value.items():
            here = (*at, material)
            if not isinstance(rel, str) or not rel:
                raise self.fail(here, f"expected a path (text), got {_kind(rel)}")
            file = self.path.parent / rel
            if "\0" in rel:
                raise self.fail(here, f"not a path (it holds a NUL character) {rel!r}")
            problem = _not_a_file(file)
            if problem:
                error = self.fail(here, f"{problem} {rel!r} (paths are relative to {self.path.name}'s folder)")
                if problem in _GONE:  # deleted or moved: the scenes this table applies to fail, not the others
                    self.problems.append(error)
                    continue
                raise error
            try:
                format_module(file)
            except FormatError as e:
                raise self.fail(here, str(e)[len(e.path) + 2:]) from None
            out.append(Value(f"{key}.{material}", ("heights", material), HeightSpec(file, TEXTURE_KEYS[key]),
                             self.where(here)))
        return out

    def depth(self, value, at: tuple) -> float:
        try:
            return positive(value, "the depth")
        except ValueError as e:
            raise self.fail(at, str(e)) from None

    def setting(self, key: str, value, f: dataclasses.Field, at: tuple):
        hint = typing.get_type_hints(ConvertOptions)[f.name]
        fitted = _fit(value, hint)
        if fitted is _NO:
            raise self.fail(at, f"expected {_expected(hint)}, got {_kind(value)}")
        if self.check is not None:
            try:
                fitted = self.check(key, fitted)
            except ValueError as e:
                raise self.fail(at, str(e)) from None
        return fitted

    def check_glob(self, glob: str, at: tuple) -> None:
        parts = [p for p in glob.split("/") if p not in ("", ".")]
        if not parts or glob.startswith("/") or Path(glob).is_absolute() or ".." in parts or "\0" in glob:
            raise self.fail(at, "a glob relative to this file's folder, without '..', is expected")


_NO = object()
_GONE = ("no such file", "a symbolic link to nothing", "no such file (no tile of the UDIM set)")  # what _not_a_file says of a file that is gone


def _not_a_file(file: Path) -> str | None:
    """Why ``file`` is no regular file to read (None: it is one); a UDIM set (``h.<UDIM>.png``) is one
    when a tile of it is."""
    if is_pattern(file):
        return None if tile_files(file) else "no such file (no tile of the UDIM set)"
    try:
        st = os.stat(file)
    except FileNotFoundError:
        return "a symbolic link to nothing" if os.path.islink(file) else "no such file"
    except OSError as e:
        return f"cannot read ({e.strerror or e})"
    return None if stat.S_ISREG(st.st_mode) else "not a regular file"


def toml_key(parts) -> str:
    """A key path as TOML writes it: ``scenes."models/*.gltf".bits``."""
    return ".".join(p if re.fullmatch(r"[A-Za-z0-9_-]+", str(p)) else json.dumps(str(p)) for p in parts)


def _fit(value, hint):
    """``value`` as the type ``hint`` wants (an int for a float), or _NO."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        for arm in typing.get_args(hint):
            if arm is not type(None) and _fit(value, arm) is not _NO:
                return _fit(value, arm)
        return _NO
    origin = typing.get_origin(hint) or hint
    if hint is bool:
        return value if isinstance(value, bool) else _NO
    if isinstance(value, bool):
        return _NO
    if hint is int:
        return value if isinstance(value, int) else _NO
    if hint is float:
        return float(value) if isinstance(value, (int, float)) else _NO
    if hint is str:
        return value if isinstance(value, str) else _NO
    if origin in (list, tuple, set, frozenset) and isinstance(value, list):
        arm = (typing.get_args(hint) or (object,))[0]
        items = [v if arm is object else _fit(v, arm) for v in value]
        return _NO if any(i is _NO for i in items) else origin(items)
    return _NO


def _expected(hint) -> str:
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(_expected(a) for a in typing.get_args(hint) if a is not type(None))
    names = {bool: "true or false", int: "a whole number", float: "a number", str: "text"}
    if hint in names:
        return names[hint]
    return f"a list of {_expected((typing.get_args(hint) or (str,))[0]).removeprefix('a ')}"


def _kind(value) -> str:
    return {bool: "true/false", int: "a whole number", float: "a number", str: "text", list: "a list",
            dict: "a table"}.get(type(value), type(value).__name__)
