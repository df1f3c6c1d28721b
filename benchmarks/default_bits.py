"""Do default outputs pass their own proof? ``python benchmarks/default_bits.py MAP... [--deep D]``

For each height map (``PATH``, or ``PATH:invert`` for a depth map, white = deep): ``csm-assets
stepmap`` with its defaults, then ``csm-assets verify`` of the step map with its defaults
(depth 0.1 of the texture's width, views down to 10 degrees, budget 1 texel); where the bits
chosen are not 8, the 8-bit map the old default wrote is verified too. With ``--deep D`` each
map is also converted as the height texture of ``samples/brick_wall.gltf`` with ``--depth D``
and the scene verified with its defaults. Prints a Markdown table: map, size, depth in texels,
bits chosen (and why), worst p95 of the default output and of the 8-bit one.
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


def cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csm_assets", *map(str, args)], capture_output=True, text=True)


def worst_p95(verify_json: str) -> float:
    d = json.loads(verify_json)
    if "primitives" in d:
        return max(v["worst_p95"] for p in d["primitives"] for v in p["variants"])
    return max(v["worst_p95"] for v in d["variants"])


def one_map(path: Path, invert: bool, tmp: Path) -> dict:
    flags = ["--invert"] if invert else []
    r = cli("stepmap", path, "-o", tmp / "s.png", "--json", *flags)
    if r.returncode:
        return {"error": r.stderr.strip()}
    made = json.loads(r.stdout)
    v = cli("verify", tmp / "s.png", "--json")
    row = {"size": f"{made['width']}x{made['height']}", "depth": made["bits"]["depth_texels"],
           "bits": made["bits"]["bits"], "why": made["bits"]["reason"], "p95": worst_p95(v.stdout),
           "passed": v.returncode == 0, "warnings": r.stderr.strip()}
    if row["bits"] != 8:
        cli("stepmap", path, "-o", tmp / "s8.png", "--bits", "8", *flags)
        row["p95_8"] = worst_p95(cli("verify", tmp / "s8.png", "--json").stdout)
    return row


def one_scene(path: Path, invert: bool, depth: float, tmp: Path) -> dict:
    scene = tmp / "scene"
    shutil.rmtree(scene, ignore_errors=True)
    shutil.copytree(ROOT / "samples", scene, ignore=shutil.ignore_patterns("*.py", "*.obj", "*.mtl", "*.usda"))
    shutil.copy(path, scene / path.name)
    flag = "--depth-map" if invert else "--height"
    rows = {}
    for bits in ([], ["--bits", "8"]):
        out = tmp / ("out8" if bits else "out")
        shutil.rmtree(out, ignore_errors=True)
        r = cli("convert", scene / "brick_wall.gltf", "-o", out, flag, f"bricks={scene / path.name}", "--depth",
                depth, "--json", *bits)
        if r.returncode:
            return {"error": r.stderr.strip()}
        pick = json.loads(r.stdout)["results"][0]["picks"]["bricks"]
        v = cli("verify", out / "brick_wall.gltf", "--json")
        rows["8" if bits else "default"] = (pick, worst_p95(v.stdout), v.returncode == 0)
    (pick, p95, passed), (_, p95_8, _) = rows["default"], rows["8"]
    return {"bits": pick["bits"], "why": pick["bits_reason"], "p95": p95, "passed": passed, "p95_8": p95_8}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+", metavar="PATH[:invert]")
    ap.add_argument("--deep", type=float, help="also convert each map into brick_wall.gltf at this depth")
    args = ap.parse_args(argv)
    print("| map | size | depth (texels) | bits | worst p95 | 8-bit p95 | why |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        for spec in args.maps:
            path, _, kind = spec.partition(":")
            path, invert = Path(path), kind == "invert"
            row = one_map(path, invert, tmp)
            if "error" in row:
                print(f"| {path.name} | | | | error: {row['error']} | | |", flush=True)
                continue
            p8 = f"{row['p95_8']:.3f}" if "p95_8" in row else "(same)"
            mark = "" if row["passed"] else " FAIL"
            print(f"| {path.name}{' (depth map)' if invert else ''} | {row['size']} | {row['depth']:.1f} | "
                  f"{row['bits']} | {row['p95']:.3f}{mark} | {p8} | {row['why']} |", flush=True)
            if args.deep:
                w, h = map(int, row["size"].split("x"))
                s = one_scene(path, invert, args.deep, tmp)
                if "error" in s:
                    print(f"| {path.name} in a scene | | | | error: {s['error']} | | |", flush=True)
                    continue
                mark = "" if s["passed"] else " FAIL"
                print(f"| {path.name} in a scene, --depth {args.deep:g} | {row['size']} | "
                      f"{args.deep * max(w, h):.1f} | {s['bits']} | {s['p95']:.3f}{mark} | {s['p95_8']:.3f} | "
                      f"{s['why']} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
