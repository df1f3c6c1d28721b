"""Wavefront MTL material libraries, read and written back byte for byte.

A library is kept as its raw lines (line endings and bytes that are not UTF-8
included); the writer adds lines after a material's last statement and renames the
texture files it copies, and changes nothing else.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import FormatError

MAP_STATEMENTS = {"map_ka", "map_kd", "map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal",
                  "refl", "map_pr", "map_pm", "map_ps", "map_ke", "norm", "map_kn"}
# option -> (how many arguments at most, "num" for numbers or "word" for one word of any kind)
OPTIONS = {"-blendu": (1, "word"), "-blendv": (1, "word"), "-bm": (1, "num"), "-boost": (1, "num"),
           "-cc": (1, "word"), "-clamp": (1, "word"), "-imfchan": (1, "word"), "-mm": (2, "num"),
           "-o": (3, "num"), "-s": (3, "num"), "-t": (3, "num"), "-texres": (1, "num"), "-type": (1, "word"),
           "-colorspace": (1, "word")}
CHANNELS = {"r": 0, "g": 1, "b": 2, "m": 3, "z": 0, "l": None}


@dataclass
class MapStatement:
    """One texture statement of an MTL: its options and the file it names (``path``, once
    resolved against the scene's folder); ``line`` is 1-based."""

    keyword: str
    options: dict[str, list[str]]
    file: str
    line: int
    path: Path | None = None


@dataclass
class MtlMaterial:
    name: str
    maps: dict[str, MapStatement] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)  # its statements and comments, as written
    last_line: int = 0  # index (0-based) of its last statement in the library's lines


@dataclass
class MtlLibrary:
    """A library as read: ``lines`` with their endings, its materials by name."""

    path: Path
    name: str  # as the OBJ's mtllib statement names it
    lines: list[str]
    materials: dict[str, MtlMaterial] = field(default_factory=dict)

    @property
    def newline(self) -> str:
        return "\r\n" if self.lines and self.lines[0].endswith("\r\n") else "\n"


def parse_map(keyword: str, args: list[str], line: int) -> MapStatement:
    """A texture statement's options (before or after the file name, as tinyobjloader
    accepts them) and its file (the other words, joined by one space)."""
    options, words, i = {}, [], 0
    while i < len(args):
        opt = args[i].lower()
        i += 1
        if opt not in OPTIONS:
            words.append(args[i - 1])
            continue
        most, kind = OPTIONS[opt]
        vals = []
        while (i < len(args) and len(vals) < most and (kind == "word" or _is_value(args[i]))
               and not (i == len(args) - 1 and not words)):  # the last word is the file
            vals.append(args[i])
            i += 1
        options[opt] = vals
    return MapStatement(keyword, options, " ".join(words), line)


def _is_value(token: str) -> bool:
    return bool(re.fullmatch(r"[-+]?((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|nan|inf|infinity)", token, re.IGNORECASE))


def number(path: Path, st: MapStatement, option: str, index: int, default: float) -> float:
    """The ``index``-th value of ``option`` in a statement, finite, or ``default``."""
    vals = st.options.get(option, [])
    if index >= len(vals):
        return default
    try:
        x = float(vals[index])
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise FormatError(path, f"line {st.line}: {st.keyword} {option} takes finite numbers, got {vals[index]!r}")
    return x


def read(path: Path, name: str) -> MtlLibrary:
    """A library and its materials, each line kept verbatim."""
    try:
        text = path.read_bytes().decode("utf-8", errors="surrogateescape")
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    lib = MtlLibrary(path, name, text.splitlines(keepends=True))
    current = None
    for n, raw in enumerate(lib.lines):
        parts = raw.lstrip("\ufeff").split()
        if current is not None and (not parts or parts[0].lower() != "newmtl"):
            current.lines.append(raw.rstrip("\r\n"))
        if not parts or parts[0].startswith("#"):
            continue
        key = parts[0].lower()
        if key == "newmtl":
            name_ = " ".join(parts[1:])
            current = lib.materials.setdefault(name_, MtlMaterial(name_))
            current.last_line = n
            continue
        if current is None:
            continue
        current.last_line = n
        if key in MAP_STATEMENTS and len(parts) > 1:
            current.maps[key] = parse_map(key, parts[1:], n + 1)
    return lib


def render(lib: MtlLibrary, added: dict[str, list[str]], renamed: dict[int, str]) -> bytes:
    """The library's bytes with ``added`` lines after each named material's last
    statement and the texture file of the statement on line ``i`` (0-based) renamed to
    ``renamed[i]``; every other byte as it was."""
    nl = lib.newline
    after = {lib.materials[name].last_line: lines for name, lines in added.items() if lines}
    out = []
    for i, raw in enumerate(lib.lines):
        out.append(_renamed(raw, renamed[i]) if i in renamed else raw)
        if i in after:
            if not out[-1].endswith(("\n", "\r")):
                out[-1] += nl
            out += [line + nl for line in after[i]]
    return "".join(out).encode("utf-8", errors="surrogateescape")


def _renamed(raw: str, new_file: str) -> str:
    """``raw`` (a map statement) naming ``new_file`` instead of its file, options kept."""
    body = raw.rstrip("\r\n")
    ending = raw[len(body):]
    parts = body.split()
    st = parse_map(parts[0], parts[1:], 0)
    at = body.rfind(st.file)
    if st.file and at >= 0:
        return body[:at] + new_file + body[at + len(st.file):] + ending
    lead = body[: len(body) - len(body.lstrip())]
    kept = [w for w in parts[1:] if w not in st.file.split()]
    return lead + " ".join([parts[0], *kept, new_file]) + ending
