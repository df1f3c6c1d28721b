"""Shared checks for the attack suites (crafted inputs and faults against the CLI).

Every attack case asserts the same contract: the documented exit code, at most one line
``csm-assets: error: ...`` naming the file, no traceback, inputs untouched (hashed before
and after) and outputs intact or absent. Use ``run_cli`` to run the real CLI in a
subprocess and ``Attack`` to hold the inputs' hashes across the run.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path


@dataclass
class CliRun:
    returncode: int
    stdout: str
    stderr: str


def run_cli(*args, timeout: float = 180, env=None, cwd=None) -> CliRun:
    """``python -m csm_assets ARGS`` in a subprocess (the install under test)."""
    r = subprocess.run([sys.executable, "-m", "csm_assets", *map(str, args)], capture_output=True,
                       text=True, timeout=timeout, env=env, cwd=cwd)
    return CliRun(r.returncode, r.stdout, r.stderr)


def run_cli_here(*args) -> CliRun:
    """The CLI's ``main(ARGS)`` in this process, its output captured: the same code path as
    :func:`run_cli` without a second of interpreter start, for sweeps of many runs (a
    subprocess still proves the real process)."""
    import contextlib
    import io
    import warnings

    from csm_assets.cli import main

    out, err = io.StringIO(), io.StringIO()
    shown = warnings.showwarning
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in args])
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else 1
    finally:
        warnings.showwarning = shown
    return CliRun(code, out.getvalue(), err.getvalue())


def tree_hashes(*paths: Path) -> dict[str, str]:
    """SHA-256 of every file under ``paths`` (files or folders), keyed by path."""
    out = {}
    for p in map(Path, paths):
        files = [p] if p.is_file() else sorted(q for q in p.rglob("*") if q.is_file())
        for f in files:
            out[str(f)] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def assert_clean_error(r: CliRun, code: int, names: str | Path | None = None) -> str:
    """The run failed with exit ``code`` and one error line (naming ``names``, a file
    name or path part, when given) and no traceback; returns the error line."""
    assert r.returncode == code, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("csm-assets: error:")]
    assert len(errors) == 1, r.stderr
    others = [line for line in r.stderr.splitlines()
              if line.strip() and not line.startswith(("csm-assets: error:", "csm-assets: warning:",
                                                       "csm-assets: info:"))]
    assert not others, f"stray stderr lines: {others}"
    if names is not None:
        assert str(Path(names).name if isinstance(names, Path) else names) in errors[0], errors[0]
    return errors[0]


def assert_clean_run(r: CliRun, code: int = 0) -> list[str]:
    """The run exited ``code`` with no traceback and no stray stderr (only warning lines);
    returns the warning lines (both severities: ``warning:`` and ``info:``)."""
    assert r.returncode == code, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    stray = [line for line in lines if not line.startswith("csm-assets: ")]
    assert not stray, f"stray stderr lines: {stray}"
    return [line for line in lines if line.startswith(("csm-assets: warning:", "csm-assets: info:"))]


class Attack:
    """Hashes ``inputs`` on entry and asserts on exit they are untouched."""

    def __init__(self, *inputs: Path):
        self.inputs = inputs
        self.before = tree_hashes(*inputs)

    def __enter__(self) -> "Attack":
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None:
            assert tree_hashes(*self.inputs) == self.before, "an input was modified"
