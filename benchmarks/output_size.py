"""Output size against input size: ``python benchmarks/output_size.py [FOLDER]``.

Copies the scenes of FOLDER (default: the repository's ``samples/``) with their files into a new
git repository, twice, and runs ``csm-assets hook`` over each copy: once with ``--textures
reference`` (the default beside a scene: lean outputs) and once with ``--textures copy`` (as
outputs were before). Prints, per scene and in total, the bytes of its inputs (every file its
manifest entry lists: the scene, buffers, material libraries, textures), the bytes of its output
folder (``<stem>_<ext>_csm/``, manifest included) and their ratio, for both modes. Inputs two
scenes share are counted once in the total.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE_SUFFIXES = (".gltf", ".glb", ".obj", ".usda", ".usdc", ".usdz")


def measure(source: Path, work: Path, mode: str) -> dict[str, tuple[dict[str, int], int]]:
    """``{scene: ({input: bytes}, output folder bytes)}`` of a hook run over a copy of ``source``."""
    repo = work / mode
    shutil.copytree(source, repo, ignore=shutil.ignore_patterns("*_csm", "*.py", "__pycache__"))
    subprocess.run(["git", "init", "-q"], cwd=repo, check=True)
    r = subprocess.run([sys.executable, "-m", "csm_assets", "hook", ".", "--textures", mode, "-q"], cwd=repo,
                       capture_output=True, text=True)
    if r.returncode not in (0, 1):
        sys.exit(f"csm-assets hook failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    out = {}
    for scene in sorted(f for f in repo.rglob("*") if f.suffix.lower() in SCENE_SUFFIXES and "_csm" not in f.parent.name):
        folder = scene.parent / f"{scene.stem}_{scene.suffix[1:].lower()}_csm"
        if not (folder / "csm-manifest.json").is_file():
            continue
        entry = json.loads((folder / "csm-manifest.json").read_text())["scenes"][scene.name]
        inputs = {k: (repo / k).stat().st_size for k in entry["inputs"]}
        out[str(scene.relative_to(repo))] = (inputs, sum(f.stat().st_size for f in folder.iterdir() if f.is_file()))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", type=Path, default=ROOT / "samples")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        runs = {mode: measure(args.folder, Path(tmp), mode) for mode in ("reference", "copy")}
    print(f"{'scene':24} {'input B':>9} {'reference B':>12} {'ratio':>6} {'copy B':>9} {'ratio':>6}")
    shared: dict[str, int] = {}
    totals = {"reference": 0, "copy": 0}
    for scene, (inputs, lean) in runs["reference"].items():
        copied = runs["copy"][scene][1]
        size = sum(inputs.values())
        shared.update(inputs)
        totals["reference"] += lean
        totals["copy"] += copied
        print(f"{scene:24} {size:9d} {lean:12d} {lean / size:6.2f} {copied:9d} {copied / size:6.2f}")
    size = sum(shared.values())
    print(f"{'all (inputs once)':24} {size:9d} {totals['reference']:12d} {totals['reference'] / size:6.2f} "
          f"{totals['copy']:9d} {totals['copy'] / size:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
