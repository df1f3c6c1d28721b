"""The line each key of a TOML text is defined on (``tomllib`` parses values, not places).

:func:`key_lines` scans the text line by line: table headers (``[a."b.c"]``, ``[[a]]``),
``key = value`` lines with bare, quoted and dotted keys, and skips the inside of multi-line
strings and arrays. A key of a one-line inline table (``height = { Hull = "h.png" }``) is
found on its parent's line (:func:`line_of` falls back to the longest known prefix).
Limits: the text must already have parsed with ``tomllib``; keys are compared after
unquoting, without TOML's escape sequences.
"""

from __future__ import annotations

import re

_BARE = re.compile(r"[A-Za-z0-9_-]+")
_BASIC = re.compile(r'"((?:[^"\\]|\\.)*)"')
_LITERAL = re.compile(r"'([^']*)'")


def _key(text: str, pos: int) -> tuple[tuple[str, ...], int] | None:
    """The dotted key starting at ``pos`` (after blanks) and where it ends, or None."""
    parts = []
    while True:
        while pos < len(text) and text[pos] in " \t":
            pos += 1
        for pattern in (_BARE, _BASIC, _LITERAL):
            m = pattern.match(text, pos)
            if m:
                parts.append(m.group(1) if m.groups() else m.group(0))
                pos = m.end()
                break
        else:
            return None
        while pos < len(text) and text[pos] in " \t":
            pos += 1
        if pos < len(text) and text[pos] == ".":
            pos += 1
            continue
        return tuple(parts), pos


def _open_brackets(value: str) -> int:
    """How many ``[``/``{`` a value leaves open (strings and comments skipped)."""
    depth, i = 0, 0
    while i < len(value):
        c = value[i]
        if c == "#":
            break
        if c in "\"'":
            end = value.find(c, i + 1)
            while c == '"' and end > 0 and value[end - 1] == "\\":
                end = value.find(c, end + 1)
            i = len(value) if end < 0 else end + 1
            continue
        depth += (c in "[{") - (c in "]}")
        i += 1
    return depth


def key_lines(text: str) -> dict[tuple[str, ...], int]:
    """Every key path (and table header path) of ``text`` -> its 1-based line. An array of
    tables ``[[a]]`` numbers its items: ``("a", 0)``, ``("a", 1)``..."""
    lines: dict[tuple[str, ...], int] = {}
    counts: dict[tuple[str, ...], int] = {}
    table: tuple[str, ...] = ()
    in_string = None
    depth = 0
    for number, line in enumerate(text.splitlines(), 1):
        if in_string:
            if line.count(in_string) % 2:
                in_string = None
            continue
        if depth > 0:
            depth += _open_brackets(line)
            continue
        stripped = line.lstrip()
        if stripped.startswith("["):
            double = stripped.startswith("[[")
            found = _key(stripped, 2 if double else 1)
            if found:
                table = found[0]
                if double:
                    counts[table] = counts.get(table, -1) + 1
                    table = (*table, counts[table])
                lines.setdefault(table, number)
            continue
        found = _key(line, 0)
        if not found or found[1] >= len(line) or line[found[1]] != "=":
            continue
        path = (*table, *found[0])
        lines.setdefault(path, number)
        value = line[found[1] + 1:]
        for quote in ('"""', "'''"):
            if value.count(quote) % 2:
                in_string = quote
        if not in_string:
            depth = max(0, _open_brackets(value))
    return lines


def line_of(lines: dict[tuple[str, ...], int], path: tuple) -> int | None:
    """The line of ``path``, else of its longest prefix that has one (None: no line)."""
    for n in range(len(path), 0, -1):
        if tuple(path[:n]) in lines:
            return lines[tuple(path[:n])]
    return None
