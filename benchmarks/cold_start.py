"""A fresh install's first run: ``python benchmarks/cold_start.py [--keep DIR]``.

Creates a new virtual environment, ``pip install``s this checkout into it (timed apart:
pip's own time; its size on disk is what pre-commit's environment for the hook takes), then times the Quick start's first line's conversion in it, from an
empty kernel cache: ``csm-assets stepmap samples/cobbles.png -o ...`` and ``csm-assets
convert samples/brick_wall.gltf -o ...``. Prints pip's seconds and the conversion's
seconds beyond them (wall clock, and CPU time, which other work on a shared machine
does not inflate), then the same commands again with the cache filled, then in a second
new environment on the same machine (what a new pre-commit or tox environment meets: the
kernels' cache is shared by every environment holding the same sources). The cache is the
default one, ``~/.cache/csm-assets/numba``, with ``XDG_CACHE_HOME`` pointed at an empty
folder (cold) so the user's own cache is neither used nor touched; the script checks that the
kernels landed there and prints its size. The target is at most 5 s beyond pip's own time on
the 2-core development machine.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def tree_mb(folder: Path) -> float:
    """Installed size: the bytes of every file under ``folder``, in MB."""
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file() and not f.is_symlink()) / 1e6


def timed(cmd, env, cwd) -> tuple[float, float]:
    """(wall, CPU) seconds of ``cmd``; exits with its output when it fails."""
    c0, t0 = _cpu(), time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    if r.returncode:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return wall, cpu


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keep", type=Path, help="make the environment here and keep it")
    ap.add_argument("--python", default=sys.executable, help="interpreter for the venv")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="csm-cold-"))
    venvs = [args.keep or work / "venv", work / "venv2"]
    # the default cache location, empty, as on a machine that never ran csm-assets
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["XDG_CACHE_HOME"] = str(work / "cache")
    shared = work / "cache" / "csm-assets" / "numba"
    try:
        src = work / "src"  # a clean copy: pip builds in the tree it is given
        shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
            ".git", ".venv", ".tox", "build", "*.egg-info", "__pycache__", ".hypothesis", "bench-out"))
        for venv in venvs:
            subprocess.run([args.python, "-m", "venv", str(venv)], check=True)
            pip_wall, pip_cpu = timed([venv / "bin" / "pip", "install", "-q", str(src)], env, work)
            print(f"pip install into {venv.name}: {pip_wall:.1f} s wall, {pip_cpu:.1f} s CPU; the "
                  f"environment (what a pre-commit hook installs): {tree_mb(venv):.0f} MB")
        runs = [("first run (cold kernel cache)", venvs[0]), ("second run (cached)", venvs[0]),
                ("first run in a second new environment (shared cache)", venvs[1])]
        for label, venv in runs:
            cli = venv / "bin" / "csm-assets"
            steps = [[cli, "stepmap", ROOT / "samples" / "cobbles.png", "-o", "cobbles_stepmap.png"],
                     [cli, "convert", ROOT / "samples" / "brick_wall.gltf", "-o", "converted"]]
            for out in ("cobbles_stepmap.png", "converted"):
                shutil.rmtree(work / out, ignore_errors=True)
                (work / out).unlink(missing_ok=True) if (work / out).is_file() else None
            parts = [timed(cmd, env, work) for cmd in steps]
            wall, cpu = sum(p[0] for p in parts), sum(p[1] for p in parts)
            each = ", ".join(f"{c[1]} {w:.2f} s" for c, (w, _) in zip(steps, parts))
            print(f"{label}: {wall:.2f} s wall beyond pip ({each}); {cpu:.2f} s CPU; shared kernel cache "
                  f"{shared}: {tree_mb(shared) if shared.is_dir() else 0:.1f} MB")
        if not shared.is_dir() or not any(shared.rglob("*.nbi")):
            sys.exit(f"no kernels were cached in {shared}: the shared cache is not where it should be")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
