"""Peak memory (RSS) per texel and time of ``csm-assets stepmap``, measured from outside the process.

    python benchmarks/memory.py [--sizes 1024 2048 4096] [--kinds terrain noise]
                                [--cones conservative] [--bits 8] [--threads 1 0] [--levels none average]
                                [--before DIR [--before-bytes B]]

Every row of the large-maps table (docs/measurements/memory.md): ``--sizes 1024 4096 8192 16384
--threads 1 0 [--before DIR]``; a 16384^2 map peaks at about 7 GB (the before code, about 38 GB, is
then not run), so it runs on a 24 GB machine. The maps are made once, in a temporary folder (16384^2:
256 MiB each, a minute).

Each run is ``python -m csm_assets stepmap MAP -o OUT --cones KIND`` in a child process, its peak
RSS read from the kernel's accounting of that child (``ru_maxrss``, under a small launcher:
:mod:`csm_assets.bench.rss`), its CPU time
(user + system) and wall time beside it. Bytes per texel are ``(peak - base) / texels``, ``base``
the same command's peak on a 64 x 64 map (the interpreter and its libraries, about 200 MB): what
the map itself costs. ``--threads``: numba threads per run (``NUMBA_NUM_THREADS``; 0: all cores).
``load``: the machine's 1-minute load average after the row (other jobs slow the wall times, not
the CPU times). ``--before DIR``: also run the package found in DIR (a checkout of an older commit, e.g. ``git
worktree add /tmp/before d64b031``, the last to make a map whole in memory) on the same maps, for the
"before" columns, where its peak (``--before-bytes`` a texel) fits in the memory available (else
"not run"). ``same``: whether each row's pixels are those of the first run of that map and cones
(the before code's, where it ran, else the first thread count's): the check of the bands against
the in-memory result. ``--levels``: one run per mode of ``stepmap --levels`` (the "out MB"
column: the bytes of every file written, the levels' atlases included). Maps
(:mod:`csm_assets.bench.maps`, 16-bit: the 8-bit map times 257 plus noise below one 8-bit step;
float: the 8-bit map / 256 plus such noise) are written to a temporary folder as PNG (float: TIFF).
"""

from __future__ import annotations

import argparse
import hashlib
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
           *(["--levels", levels] if code is None else [])]  # the before code has no --levels (none)
    return rss.measure(cmd, cwd=dst.parent, env=env)


def warm_kernels() -> None:
    """Compile (or load) the march for every packed dtype here first, so that no measured run pays
    for a compile that its base run did not (a 16-bit map's march: tens of MB at its peak)."""
    from csm_assets.verify.march import march_exact

    for dtype in (np.uint8, np.uint16, np.float32):
        march_exact(np.ones((2, 2, 4), dtype), np.full((1, 2), 0.5), np.array([[0.0, 0.0, 1.0]]))


def pixels_hash(path: Path) -> str:
    """The sha256 of the pixels of ``path`` and of its second image (quadrant cones), if any."""
    digest = hashlib.sha256()
    for f in (path, path.with_name(f"{path.stem}_q{path.suffix}")):
        if f.exists():
            pixels = read_pixels(f)[0]
            digest.update(f"{pixels.dtype}{pixels.shape}".encode())
            digest.update(np.ascontiguousarray(pixels).data)
    return digest.hexdigest()


def available() -> int:
    """Bytes of memory available now (``MemAvailable`` of /proc/meminfo; 0 where there is none)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


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
    p.add_argument("--before-bytes", type=float, default=140.0, metavar="B",
                   help="bytes a texel the before code takes (default 140, the in-memory code's): it runs a map "
                        "only where that fits in 90%% of the memory available")
    args = p.parse_args(argv)
    codes = {"now": None, **({"before": args.before.resolve()} if args.before else {})}
    warm_kernels()
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
              + "  same  load", flush=True)
        for n in args.sizes:
            for kind in args.kinds:
                for bits in args.bits:
                    src = make_map(kind, n, bits, folder)
                    for cones in args.cones:
                        first = None  # the first pixels of this map and cones: every other run must equal them
                        for threads, levels in ((t, lv) for t in args.threads for lv in args.levels):
                            row = f"{kind + str(n):<16} {cones:<12} {bits:>4} {threads or 'all':>3} {levels:>7} "
                            outs, hashes = [], []
                            for name, code in codes.items():
                                skip = "" if name == "now" else "levels: none" if levels != "none" else \
                                    "run once" if first is not None else \
                                    "not run (memory)" if n * n * args.before_bytes > 0.9 * available() else ""
                                if skip:  # the before code runs each map once, at the first thread count
                                    row += f"{skip:>16} {'':>9} {'':>7} {'':>7} {'':>7}"
                                    continue
                                dst = folder / f"{src.stem}_{cones}_{name}.png"
                                m = measure(src, dst, cones, threads, code, levels)
                                per = (m["peak"] - base[name, cones]) / (n * n)
                                size = sum(f.stat().st_size for f in folder.glob(f"{dst.stem}*.png"))
                                row += (f"{per:>16.1f} {m['peak'] / 1e6:>9.0f} {m['cpu']:>7.1f} {m['wall']:>7.1f} "
                                        f"{size / 1e6:>7.2f}")
                                outs.append(dst)
                                if levels == "none":
                                    hashes.append(pixels_hash(dst))
                            said = "-"  # levels rows write more than the map: not compared
                            if hashes:
                                said = "yes" if first is not None or len(hashes) > 1 else "first"
                                first = first or hashes[0]
                                said = said if all(h == first for h in hashes) else "NO"
                            row += f"  {said:>5}"
                            print(row + f"  {os.getloadavg()[0]:.1f}", flush=True)
                            for dst in outs:
                                for f in folder.glob(f"{dst.stem}*.png"):
                                    f.unlink()
        print("base (64x64 map): " + ", ".join(f"{k[0]} {k[1]} {v / 1e6:.0f} MB" for k, v in base.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
