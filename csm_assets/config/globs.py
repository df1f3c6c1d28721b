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
visit, not a walk per way round).
"""

from __future__ import annotations

import fnmatch
import os
import re
from pathlib import Path

ANY_FOLDERS = "**"
SKIPPED = {".git"}
_WILD = re.compile(r"[*?\[]")
_CASE = re.IGNORECASE if os.path.normcase("A") == "a" else 0  # Windows compares names without case


class Glob:
    """One glob as an automaton: a state is a frozenset of part indices (``len(parts)``:
    the whole glob matched)."""

    def __init__(self, text: str):
        parts: list = []
        for part in text.split("/"):
            if part in ("", ".") or (part == ANY_FOLDERS and parts and parts[-1] == ANY_FOLDERS):
                continue
            parts.append(part if part == ANY_FOLDERS or not _WILD.search(part) and not _CASE
                         else re.compile(fnmatch.translate(part), _CASE))
        self.parts = parts
        self.files = bool(parts) and parts[-1] != ANY_FOLDERS

    def _closure(self, states) -> frozenset:
        out = set(states)
        for i in sorted(out):
            while i < len(self.parts) and self.parts[i] == ANY_FOLDERS:
                i += 1
                out.add(i)
        return frozenset(out)

    def start(self) -> frozenset:
        return self._closure({0})

    def step(self, states: frozenset, name: str, *, link: bool = False) -> frozenset:
        """The states after the entry ``name`` (``link``: a folder reached through a link,
        which ``**`` does not enter)."""
        out = set()
        for i in states:
            if i == len(self.parts):
                continue
            part = self.parts[i]
            if part == ANY_FOLDERS:
                if not link:
                    out.add(i)
            elif part == name if isinstance(part, str) else part.match(name):
                out.add(i + 1)
        return self._closure(out) if out else frozenset()

    def open(self, states: frozenset) -> bool:
        """Whether a folder in these states may hold a match below it."""
        return any(i < len(self.parts) for i in states)

    def accepts(self, states: frozenset) -> bool:
        return self.files and len(self.parts) in states


def matching_files(folder: Path, globs: list[str], suffixes) -> list[set[Path]]:
    """For each of ``globs`` (relative to ``folder``), the resolved regular files below
    ``folder`` it matches whose suffix (any case) is in ``suffixes``."""
    autos = [Glob(g) for g in globs]
    found: list[set[Path]] = [set() for _ in globs]
    none = frozenset()
    stack = [(str(folder), [a.start() if a.files else none for a in autos])]
    seen = set()  # (folder, states) walked: links that lead back (loops, twins) cost one visit
    while stack:
        here, states = stack.pop()
        try:
            st = os.stat(here)
            key = (st.st_dev, st.st_ino, *states)
            if key in seen:
                continue
            seen.add(key)
            with os.scandir(here) as it:
                entries = list(it)
        except OSError:
            continue
        for entry in entries:
            if entry.name in SKIPPED:
                continue
            try:
                is_link = entry.is_symlink()
                is_dir = entry.is_dir(follow_symlinks=False) or is_link and _is_folder(entry)
            except OSError:
                continue
            if is_dir:
                below = [a.step(s, entry.name, link=is_link) if s else none for a, s in zip(autos, states)]
                if any(a.open(s) for a, s in zip(autos, below)):
                    stack.append((entry.path, below))
                continue
            if os.path.splitext(entry.name)[1].lower() not in suffixes:
                continue
            hits = [k for k, (a, s) in enumerate(zip(autos, states)) if s and a.accepts(a.step(s, entry.name))]
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
