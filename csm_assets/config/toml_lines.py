"""The line each key of a TOML text is defined on (``tomllib`` parses values, not places).

:func:`key_lines` scans the text line by line: table headers (``[a."b.c"]``, ``[[a]]``),
``key = value`` lines with bare, quoted and dotted keys, and skips the inside of multi-line
strings and arrays. A key of a one-line inline table (``height = { Hull = "h.png" }``) is
found on its parent's line (:func:`line_of` falls back to the longest known prefix).
Limits: the text must already have parsed with ``tomllib``; keys are compared after
unquoting, without TOML's escape sequences.

:func:`nesting_line` runs before parsing: where arrays and inline tables first nest deeper
than a limit (``tomllib`` recurses once per level, so a value 500 deep fails inside it).
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


_SPECIAL = re.compile(r"[\[\]{}\"'#\n]")


def _string_end(text: str, start: int, stop: int, quote: str) -> int:
    """Past the ``quote`` that closes a string whose content starts at ``start``, else
    ``stop``; in a basic string an escaped quote (``\\"``) does not close it."""
    while True:
        end = text.find(quote, start, stop)
        if end < 0:
            return stop
        if quote[0] == '"':
            slashes = end
            while slashes > start and text[slashes - 1] == "\\":
                slashes -= 1
            if (end - slashes) % 2:
                start = end + 1
                continue
        return end + len(quote)


def nesting_line(text: str, limit: int) -> int | None:
    """The 1-based line where ``[``/``{`` first nest deeper than ``limit`` outside strings and
    comments, or None. One pass, linear in the text; any text (valid TOML or not)."""
    depth, line, i, eol = 0, 1, 0, -1
    while True:
        m = _SPECIAL.search(text, i)
        if m is None:
            return None
        c, i = m.group(), m.end()
        if eol < i:  # the end of this line, found once per line
            eol = text.find("\n", i)
            eol = len(text) if eol < 0 else eol
        if c == "\n":
            line += 1
        elif c == "#":
            i = eol
        elif c in "[{":
            depth += 1
            if depth > limit:
                return line
        elif c in "]}":
            depth = max(0, depth - 1)
        elif text.startswith(c * 2, i):  # a multi-line string
            end = _string_end(text, i + 2, len(text), c * 3)
            line += text.count("\n", i, end)
            i = end
        else:
            i = _string_end(text, i, eol, c)


def line_of(lines: dict[tuple[str, ...], int], path: tuple) -> int | None:
    """The line of ``path``, else of its longest prefix that has one (None: no line)."""
    for n in range(len(path), 0, -1):
        if tuple(path[:n]) in lines:
            return lines[tuple(path[:n])]
    return None
