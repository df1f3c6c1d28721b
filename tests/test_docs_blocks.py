"""Every fenced ``sh`` and ``python`` block of README.md and docs/ runs as written.

A page's blocks run in order in a folder of their own holding a copy of ``samples/`` and
``.venv`` (a link to the environment under test, where the page's own install line would
have made it) and ``tests/tools/``, as a reader would type them: the ``sh`` blocks in one bash session (what
one block sets, such as an activated venv, holds for the next), each ``python`` block by
the environment's Python. A command must exit 0, or with the code its line's comment
says (``# ... exit 1: why``). A block that cannot run here is preceded by
``<!-- not run: REASON -->``, and the reason is checked to be there.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```(sh|python)\s*$")
NOT_RUN = re.compile(r"^<!-- not run: (.*?) -->$")
EXIT = re.compile(r"#.*\bexit (\d+):")


@dataclass
class Block:
    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    text: str
    not_run: str | None  # the reason given, or None

    def __str__(self):
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The page's ``sh`` and ``python`` blocks, in order."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m:
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            skip = NOT_RUN.match(lines[i - 1].strip()) if i else None
            found.append(Block(page, i + 1, m.group(1), "\n".join(lines[i + 1:end]) + "\n",
                               skip.group(1).strip() if skip else None))
            i = end
        i += 1
    return found


ALL = [b for page in PAGES for b in blocks(page)]
RUN_PAGES = sorted({b.page for b in ALL if b.not_run is None})


def test_every_block_not_run_says_why():
    assert ALL, "no blocks found"
    unexplained = [str(b) for b in ALL if b.not_run is not None and len(b.not_run) < 10]
    assert not unexplained, f"blocks marked not run without a reason: {unexplained}"


def test_the_newcomers_pages_run_their_examples():
    """README, getting started, the tutorial, concepts, versions and the guides the README sends a
    newcomer to run blocks."""
    for name in ("README.md", "docs/getting-started.md", "docs/tutorial.md", "docs/concepts.md", "docs/versioning.md",
                 "docs/guides/pipeline.md", "docs/guides/exporter.md"):
        assert ROOT / name in RUN_PAGES, f"{name} runs none of its blocks"


def _session(page_blocks: list[Block], folder: Path) -> tuple[str, list[tuple[int, int, int]]]:
    """One bash script running the page's blocks in order, and ``(block, line, exit)`` of each
    line that expects a non-zero exit."""
    parts = ['trap \'echo "@@status $? $CSM_BLOCK $((LINENO - CSM_BASE))" >&2\' ERR']
    expected = []
    for k, b in enumerate(page_blocks):
        if b.lang == "python":
            src = folder / f".block{k}.py"
            src.write_text(b.text, encoding="utf-8")
            parts.append(f'CSM_BLOCK={k}; CSM_BASE=$LINENO; "$CSM_PYTHON" {src.name}')
            continue
        body = b.text.splitlines()
        parts.append(f"CSM_BLOCK={k}; CSM_BASE=$LINENO")
        parts.extend(body)
        for n, line in enumerate(body, 1):
            m = EXIT.search(line)
            if m and m.group(1) != "0":
                expected.append((k, n, int(m.group(1))))
    return "\n".join(parts) + "\n", expected


@pytest.mark.slow
@pytest.mark.parametrize("page", RUN_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_page_blocks_run_as_written(page, tmp_path):
    page_blocks = [b for b in blocks(page) if b.not_run is None]
    for part in ("samples", "tests/tools"):  # what a checkout holds that pages name
        shutil.copytree(ROOT / part, tmp_path / part)
    (tmp_path / ".venv").symlink_to(sys.prefix, target_is_directory=True)
    script, expected = _session(page_blocks, tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if not p.startswith(sys.prefix))  # the page activates it
    env["CSM_PYTHON"] = sys.executable
    r = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=1200)
    got = {(int(k), int(line)): int(code)
           for code, k, line in re.findall(r"^@@status (\d+) (\d+) (-?\d+)$", r.stderr, re.M)}
    want = {(k, line): code for k, line, code in expected}
    where = {k: str(b) for k, b in enumerate(page_blocks)}
    wrong = [f"{where[k]} line {line}: exit {got.get((k, line), 0)}, expected {want.get((k, line), 0)}"
             for k, line in sorted(set(got) | set(want)) if got.get((k, line), 0) != want.get((k, line), 0)]
    assert not wrong and r.returncode == 0, "\n".join(wrong) + f"\n--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-6000:]}"
