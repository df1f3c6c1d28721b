"""Peak memory (RSS) per texel and time of ``csm-assets stepmap``, measured from outside the process.

    python benchmarks/memory.py [--sizes 1024 2048 4096] [--kinds terrain noise]
                                [--cones conservative] [--bits 8] [--threads 1 0] [--levels none average]
                                [--before DIR]

Each run is ``python -m csm_assets stepmap MAP -o OUT --cones KIND`` in a child process, its peak
RSS read from the kernel's accounting of that child (``ru_maxrss``, under a small launcher:
:mod:`csm_assets.bench.rss`), its CPU time
(user + system) and wall time beside it. Bytes per texel are ``(peak - base) / texels``, ``base``
the same command's peak on a 64 x 64 map (the interpreter and its libraries, about 200 MB): what
the map itself costs. ``--threads``: numba threads per run (``NUMBA_NUM_THREADS``; 0: all cores).
``--before DIR``: also run the package found in DIR (a checkout of an older commit, e.g. ``git
worktree add /tmp/before d64b031``) on the same maps, for the "before" columns, and check that
both write the same pixels. ``--levels``: one run per mode of ``stepmap --levels`` (the "out MB"
column: the bytes of every file written, the levels' atlases included). Maps
(:mod:`csm_assets.bench.maps`, 16-bit: the 8-bit map times 257 plus noise below one 8-bit step;
float: the 8-bit map / 256 plus such noise) are written to a temporary folder as PNG (float: TIFF).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout

from csm_assets.bench import rss  # noqa: E402
from csm_assets.bench.maps import noise, terrain  # noqa: E402
from csm_assets.formats.image import _write_pixels, read_pixels  # noqa: E402

KINDS = {"terrain": terrain, "noise": noise}


def make_map(kind: str, n: int, bits: int, folder: Path) -> Path:
    """The ``kind`` map at n x n, ``bits`` 8 or 16 (a PNG) or 32 (float, a TIFF) in ``folder`` (made once)."""
    path = folder / f"{kind}{n}_{bits}.{'tif' if bits == 32 else 'png'}"
    if not path.exists():
        a = KINDS[kind](n)
        if bits == 16:
            a = a.astype(np.uint16) * 257 + np.random.default_rng(5).integers(0, 257, a.shape).astype(np.uint16)
        if bits == 32:
            a = a / np.float32(256) + np.random.default_rng(5).uniform(0, 1 / 256, a.shape).astype(np.float32)
        _write_pixels(a[:, :, None], path)
    return path


def measure(src: Path, dst: Path, cones: str, threads: int, code: Path | None = None, levels: str = "none") -> dict:
    """Peak RSS (bytes), CPU and wall seconds of one stepmap run in a child process
    (:func:`csm_assets.bench.rss.measure`; run in ``dst``'s folder: ``python -m`` puts the working
    directory first on the path, before ``code``)."""
    env = dict(os.environ)
    if threads:
        env["NUMBA_NUM_THREADS"] = str(threads)
    if code is not None:
        env["PYTHONPATH"] = str(code) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, "-m", "csm_assets", "stepmap", src, "-o", dst, "--cones", cones, "-q",
           *(["--levels", levels] if levels != "none" else [])]
    return rss.measure(cmd, cwd=dst.parent, env=env)


def same_pixels(a: Path, b: Path) -> bool:
    return np.array_equal(read_pixels(a)[0], read_pixels(b)[0])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[1024, 2048, 4096])
    p.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS))
    p.add_argument("--cones", nargs="+", default=["conservative"], choices=["conservative", "relaxed", "quadrant"])
    p.add_argument("--bits", type=int, nargs="+", default=[8], choices=[8, 16, 32],
                   help="bits of the input maps (32: float)")
    p.add_argument("--threads", type=int, nargs="+", default=[0], help="numba threads per run (0: all)")
    p.add_argument("--levels", nargs="+", default=["none"], choices=["none", "average", "max"],
                   help="stepmap --levels modes to run (the before code runs 'none' only)")
    p.add_argument("--before", type=Path, help="a checkout of the code to compare with (its package folder's parent)")
    args = p.parse_args(argv)
    codes = {"now": None, **({"before": args.before.resolve()} if args.before else {})}
    with tempfile.TemporaryDirectory(prefix="csm-memory-") as tmp:
        folder = Path(tmp)
        base = {}
        for name, code in codes.items():
            for cones in args.cones:
                small = make_map("terrain", 64, 8, folder)
                measure(small, folder / "small_csm.png", cones, 0, code)  # a first run may compile kernels
                base[name, cones] = measure(small, folder / "small_csm.png", cones, 0, code)["peak"]
        print(f"{'map':<16} {'cones':<12} {'bits':>4} {'thr':>3} {'levels':>7} "
              + "".join(f"{name + ' B/texel':>16} {name + ' MB':>9} {'cpu s':>7} {'wall s':>7} {'out MB':>7}"
                        for name in codes)
              + ("  same" if len(codes) > 1 else ""), flush=True)
        for n in args.sizes:
            for kind in args.kinds:
                for bits in args.bits:
                    src = make_map(kind, n, bits, folder)
                    for cones in args.cones:
                        for threads, levels in ((t, lv) for t in args.threads for lv in args.levels):
                            row = f"{kind + str(n):<16} {cones:<12} {bits:>4} {threads or 'all':>3} {levels:>7} "
                            outs = []
                            for name, code in codes.items():
                                if name == "before" and levels != "none":
                                    continue
                                dst = folder / f"{src.stem}_{cones}_{name}.png"
                                m = measure(src, dst, cones, threads, code, levels)
                                per = (m["peak"] - base[name, cones]) / (n * n)
                                size = sum(f.stat().st_size for f in folder.glob(f"{dst.stem}*.png"))
                                row += (f"{per:>16.1f} {m['peak'] / 1e6:>9.0f} {m['cpu']:>7.1f} {m['wall']:>7.1f} "
                                        f"{size / 1e6:>7.2f}")
                                outs.append(dst)
                            if len(outs) > 1:
                                row += f"  {'yes' if same_pixels(*outs) else 'NO'}"
                            print(row, flush=True)
                            for dst in outs:
                                for f in folder.glob(f"{dst.stem}*.png"):
                                    f.unlink()
        print("base (64x64 map): " + ", ".join(f"{k[0]} {k[1]} {v / 1e6:.0f} MB" for k, v in base.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
