"""The scene files that the ``[scenes."GLOB"]`` globs of one configuration match: one walk
of the configuration's folder for all its globs, at a cost linear in what it walks.

A glob is split at ``/``: a part ``**`` is any number of folders (none included), any
other part matches one name as :func:`fnmatch.fnmatchcase` does (``*``, ``?``, ``[...]``;
a leading dot is an ordinary character, as in :meth:`pathlib.Path.glob`). A glob ending in
``**`` matches folders only, so no scene file.

Each glob runs as a small automaton over its parts (:class:`Glob`: the set of parts it
may be at), so ``**/**/**`` costs what one ``**`` costs and no folder is walked twice:
pathlib walks a subtree again for each ``**`` (seven of them on a tree 30 folders deep took
minutes). The walk enters only folders that some glob can still match below, never a folder
named ``.git``; folders it cannot list are passed over, as pathlib does. A folder reached through a
symbolic link is entered by a name part (``*``, ``models``), never by ``**`` (as pathlib
does), and a folder is walked at most once per set of states (a link loop costs one more
visit, not a walk per way round). An entry costs the globs that may move on it: those
waiting for its very name (looked up) and those at a wildcard or ``**`` (tried).
"""

from __future__ import annotations

import fnmatch
import functools
import os
import re
from pathlib import Path

ANY_FOLDERS = "**"
SKIPPED = {".git"}
_WILD = re.compile(r"[*?\[]")
_CASE = re.IGNORECASE if os.path.normcase("A") == "a" else 0  # Windows compares names without case


@functools.lru_cache(maxsize=4096)
def _pattern(part: str) -> re.Pattern:
    return re.compile(fnmatch.translate(part), _CASE)  # fnmatch's patterns do not backtrack without end


class Glob:
    """One glob as an automaton over path parts: ``parts`` holds ``"**"``, a name to compare,
    or a compiled pattern; a state is a frozenset of part indices (``len(parts)``: the whole
    glob matched)."""

    def __init__(self, text: str):
        parts: list = []
        for part in text.split("/"):
            if part in ("", ".") or (part == ANY_FOLDERS and parts and parts[-1] == ANY_FOLDERS):
                continue
            parts.append(part if part == ANY_FOLDERS or not _WILD.search(part) and not _CASE else _pattern(part))
        self.parts = parts
        self.files = bool(parts) and parts[-1] != ANY_FOLDERS

    def closure(self, states) -> frozenset:
        """``states`` and every state a ``**`` (none of its folders) leads to from them."""
        out = set(states)
        for i in sorted(out):
            while i < len(self.parts) and self.parts[i] == ANY_FOLDERS:
                i += 1
                out.add(i)
        return frozenset(out)

    def open(self, states: frozenset) -> bool:
        """Whether a folder in these states may hold a match below it."""
        return any(i < len(self.parts) for i in states)

    def accepts(self, states: frozenset) -> bool:
        return self.files and len(self.parts) in states


class _Moves:
    """The parts the live globs of one folder wait for: names (looked up) and the rest
    (``**`` and wildcards, tried on every entry), so an entry costs the globs it may move,
    not every glob of the file."""

    def __init__(self, autos: list[Glob], live: dict[int, frozenset]):
        self.autos, self.named, self.other = autos, {}, []
        for k, states in live.items():
            parts = autos[k].parts
            for i in states:
                if i == len(parts):
                    continue
                if isinstance(parts[i], str) and parts[i] != ANY_FOLDERS:
                    self.named.setdefault(parts[i], []).append((k, i))
                else:
                    self.other.append((k, i))

    def after(self, name: str, link: bool = False) -> dict[int, frozenset]:
        """Glob -> its states after the entry ``name`` (``link``: a folder reached through a
        link, which ``**`` does not enter); globs left in no state are dropped."""
        moved: dict[int, set] = {}
        for k, i in self.named.get(name, ()):
            moved.setdefault(k, set()).add(i + 1)
        for k, i in self.other:
            part = self.autos[k].parts[i]
            if part == ANY_FOLDERS:
                if not link:
                    moved.setdefault(k, set()).add(i)
            elif part.match(name):
                moved.setdefault(k, set()).add(i + 1)
        return {k: self.autos[k].closure(states) for k, states in moved.items()}


def matching_files(folder: Path, globs: list[str], suffixes) -> list[set[Path]]:
    """For each of ``globs`` (relative to ``folder``), the resolved regular files below
    ``folder`` it matches whose suffix (any case) is in ``suffixes``."""
    autos = [Glob(g) for g in globs]
    found: list[set[Path]] = [set() for _ in globs]
    stack = [(str(folder), {k: a.closure({0}) for k, a in enumerate(autos) if a.files})]
    seen = set()  # (folder, states) walked: links that lead back (loops, twins) cost one visit
    while stack:
        here, live = stack.pop()
        try:
            st = os.stat(here)
            key = (st.st_dev, st.st_ino, frozenset(live.items()))
            if key in seen:
                continue
            seen.add(key)
            with os.scandir(here) as it:
                entries = list(it)
        except OSError:
            continue
        moves = _Moves(autos, live)
        for entry in entries:
            if entry.name in SKIPPED:
                continue
            try:
                is_link = entry.is_symlink()
                is_dir = entry.is_dir(follow_symlinks=False) or is_link and _is_folder(entry)
            except OSError:
                continue
            if is_dir:
                below = {k: s for k, s in moves.after(entry.name, is_link).items() if autos[k].open(s)}
                if below:
                    stack.append((entry.path, below))
            elif os.path.splitext(entry.name)[1].lower() in suffixes:
                hits = [k for k, s in moves.after(entry.name).items() if autos[k].accepts(s)]
                if hits and _is_file(entry):
                    resolved = Path(entry.path).resolve()
                    for k in hits:
                        found[k].add(resolved)
    return found


def _is_folder(entry: os.DirEntry) -> bool:
    try:
        return entry.is_dir()
    except OSError:
        return False


def _is_file(entry: os.DirEntry) -> bool:
    try:
        return entry.is_file()
    except OSError:
        return False
