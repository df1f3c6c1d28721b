"""This library's exact cones timed against the paper's preprocessor (``csm-assets bench cones``).

The peer is ``../shared/anchors/dummer_preproc.cpp`` next to the repository (or
``--peer-source``), built with ``g++ -O3 -march=native`` into a cache folder
under the system temp dir (never into the project); it is skipped, saying why,
when g++ or the file is missing. Both sides get the same uint8 maps; the peer
reads binary PGM. Times exclude file I/O on both sides: the peer's own
"cone search" clock (one thread, CPU time), ours the ``exact_ratios`` call after
numba's warm-up (wall time, all numba threads, including the auto choice).
Our results are checked against an independent brute force on sample texels.
"""

from __future__ import annotations

import dataclasses
import hashlib
import re
import shutil
import subprocess
import tempfile
import time
import tracemalloc
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np

from ..cones.exact import METHODS, choose_method, estimate_costs, exact_ratios
from . import maps as bench_maps


def _shared(*parts: str) -> Path:
    """``../shared/<parts>`` beside the checkout: found from the working directory (an
    installed package lives elsewhere), else from this file in a source checkout."""
    for repo in (Path.cwd(), Path(__file__).resolve().parents[2]):
        candidate = repo.parent.joinpath("shared", *parts)
        if candidate.exists():
            return candidate
    return Path.cwd().parent.joinpath("shared", *parts)


PEER_SOURCE = _shared("anchors", "dummer_preproc.cpp")
DATA = _shared("data")
SIZES = (256, 512, 1024, 2048)  # square map sizes timed by default


@dataclass
class ConeRun:
    """One map at one size. Times in seconds; None where not measured."""

    map: str
    size: int
    method: str                  # what "auto" chose (non-tiled)
    ours_s: float                # non-tiled
    ours_tiled_s: float
    peak_mb: float               # tracemalloc peak of our non-tiled call
    exact: bool                  # sample texels agree with the brute force (both tile modes)
    max_rel_err: float
    peer_s: float | None = None  # non-tiled, its own clock
    peer_note: str = ""          # "> 120 s", "skipped: ..."
    peer_wider: float | None = None  # fraction of its cones wider than exact (beyond its rounding)

    @property
    def speedup(self) -> float | None:
        return None if self.peer_s is None else self.peer_s / self.ours_s


@dataclass
class ConeBench:
    runs: list[ConeRun] = field(default_factory=list)
    threads: int = 1
    peer: str = ""               # how the peer was built, or why it was skipped
    note: str = ("times exclude file I/O; ours: wall time of exact_ratios after numba warm-up "
                 "(best of repeats, auto method choice included); peer: its 'cone search' clock "
                 "(CPU time, one thread, best of repeats); both non-tiled unless 'tiled'")

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        for run, r in zip(d["runs"], self.runs):
            run["speedup"] = r.speedup
        return d

    def table(self) -> str:
        head = (f"{'map':<14}{'size':>6} {'method':<8}{'ours s':>9}{'tiled s':>9}{'t/nt':>6}"
                f"{'peer s':>10}{'peer/ours':>10}{'peak MB':>9}  exact  peer wider")
        lines = [f"cone ratios, ours on {self.threads} numba threads; {self.note}",
                 f"peer: {self.peer}", head]
        for r in self.runs:
            peer = f"{r.peer_s:10.3f}" if r.peer_s is not None else f"{r.peer_note:>10}"
            if r.speedup is not None:
                ratio = f"{r.speedup:9.1f}x"
            elif r.peer_note.startswith(">"):
                ratio = f"{'>' + format(float(r.peer_note[1:].split()[0]) / r.ours_s, '.0f') + 'x':>10}"
            else:
                ratio = f"{'-':>10}"
            wider = "-" if r.peer_wider is None else f"{100 * r.peer_wider:.1f}%"
            lines.append(f"{r.map:<14}{r.size:>6} {r.method:<8}{r.ours_s:9.3f}{r.ours_tiled_s:9.3f}"
                         f"{r.ours_tiled_s / r.ours_s:6.2f}{peer}{ratio}{r.peak_mb:9.1f}  "
                         f"{'yes' if r.exact else 'NO':<5}  {wider}")
        return "\n".join(lines)


# ---------------------------------------------------------------- the peer
def build_peer(source: Path) -> tuple[dict[bool, Path] | None, str]:
    """Build the peer (tiled and non-tiled) into a cache folder; (exes by tile, message)."""
    if not source.is_file():
        return None, f"skipped: {source} not found"
    gxx = shutil.which("g++")
    if gxx is None:
        return None, "skipped: g++ not found"
    text = source.read_bytes()
    out = Path(tempfile.gettempdir()) / "csm-assets-peer" / hashlib.sha256(text).hexdigest()[:16]
    out.mkdir(parents=True, exist_ok=True)
    exes = {}
    for tile in (False, True):
        exe = out / ("dummer_tiled" if tile else "dummer_untiled")
        if not exe.exists():
            cmd = [gxx, "-O3", "-march=native", "-o", str(exe) + ".tmp", str(source)]
            if not tile:
                cmd.insert(1, "-DTILEABLE=false")
            done = subprocess.run(cmd, capture_output=True, text=True)
            if done.returncode != 0:
                return None, f"skipped: g++ failed on {source}: {done.stderr.strip()[:300]}"
            Path(str(exe) + ".tmp").replace(exe)
        exes[tile] = exe
    return exes, f"{source} built with g++ -O3 -march=native in {out}"


def run_peer(exe: Path, heights: np.ndarray, timeout: float, repeat: int):
    """(best 'cone search' seconds or None, note, its ratios (H, W) float64 or None)."""
    n_rows, n_cols = heights.shape
    best, ratio = None, None
    with tempfile.TemporaryDirectory(prefix="csm-bench-") as tmp:
        pgm, raw = Path(tmp) / "in.pgm", Path(tmp) / "out.rgba"
        pgm.write_bytes(b"P5 %d %d 255\n" % (n_cols, n_rows) + heights.tobytes())
        for _ in range(repeat):
            try:
                done = subprocess.run([str(exe), str(pgm), str(raw)], capture_output=True,
                                      text=True, timeout=timeout)
            except subprocess.TimeoutExpired:
                return None, f"> {timeout:g} s", None
            m = re.search(r"cone search ([0-9.]+) s", done.stderr)
            if done.returncode != 0 or m is None:
                return None, f"failed: {done.stderr.strip()[:100]}", None
            t = float(m.group(1))
            best = t if best is None else min(best, t)
            if t > 1.0:
                break
        g = np.fromfile(raw, np.uint8).reshape(n_rows, n_cols, 4)[..., 1]
        ratio = (g / 255.0) ** 2  # its G = round(255 sqrt(ratio / max_ratio)), max_ratio 1
    return best, "", ratio


# ---------------------------------------------------------------- our side
def brute_texels(h, rows, cols, tile_x, tile_y, max_ratio):
    """Exact ratios of texels (rows[i], cols[i]) by checking every texel (float64)."""
    n_rows, n_cols = h.shape
    dxs, dys = np.arange(n_cols), np.arange(n_rows)
    out = np.empty(len(rows))
    for i, (r, c) in enumerate(zip(rows, cols)):
        dx, dy = np.abs(dxs - c), np.abs(dys - r)
        if tile_x:
            dx = np.minimum(dx, n_cols - dx)
        if tile_y:
            dy = np.minimum(dy, n_rows - dy)
        dh = h - h[r, c]
        up = dh > 0
        d = np.sqrt((dx[None, :] / n_cols) ** 2 + (dy[:, None] / n_rows) ** 2)
        out[i] = min((d[up] / dh[up]).min(), max_ratio) if up.any() else max_ratio
    return out


def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel before timing."""
    h = np.random.default_rng(0).random((80, 80))
    for tile in (False, True):
        for method in METHODS:
            exact_ratios(h, tile, tile, 1.0, method=method)
        choose_method(h, tile, tile, 1.0)
        estimate_costs(h, tile, tile, 1.0)


def time_ours(h, tile, repeat):
    """(best seconds, ratios) of exact_ratios (auto) on ``h``."""
    best, ratio = None, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        ratio = exact_ratios(h, tile, tile, 1.0)
        t = time.perf_counter() - t0
        best = t if best is None else min(best, t)
        if t > 1.0:
            break
    return best, ratio


def peak_mb(h) -> float:
    """Peak MB of numpy allocations (tracemalloc) of exact_ratios (auto, non-tiled) on ``h``."""
    tracemalloc.start()
    try:
        exact_ratios(h, False, False, 1.0)
        return tracemalloc.get_traced_memory()[1] / 2 ** 20
    finally:
        tracemalloc.stop()


def bench_map(name, heights, exes, timeout, repeat, samples=24, log=None) -> ConeRun:
    h = heights.astype(np.float64) / 255.0
    n = h.shape[0]
    ours, ratio = time_ours(h, False, repeat)
    ours_t, ratio_t = time_ours(h, True, repeat)
    rng = np.random.default_rng(n)
    rows = np.concatenate([[0, n - 1, n // 2], rng.integers(0, n, samples)])
    cols = np.concatenate([[0, n - 1, n // 3], rng.integers(0, n, samples)])
    err = 0.0
    for tile, got in ((False, ratio), (True, ratio_t)):
        want = brute_texels(h, rows, cols, tile, tile, 1.0)
        err = max(err, float(np.max(np.abs(got[rows, cols] - want) / want)))
    run = ConeRun(map=name, size=n, method=choose_method(h, False, False, 1.0), ours_s=ours,
                  ours_tiled_s=ours_t, peak_mb=peak_mb(h), exact=err <= 1e-9, max_rel_err=err)
    if exes is not None:
        if log:
            log(f"  peer on {name} {n}x{n} (timeout {timeout:g} s)...")
        run.peer_s, run.peer_note, peer_ratio = run_peer(exes[False], heights, timeout, repeat)
        if peer_ratio is not None:
            exact_g = np.round(255.0 * np.sqrt(ratio))  # its own rounding of the exact cone
            run.peer_wider = float(np.mean(peer_ratio > (exact_g / 255.0) ** 2 * (1 + 1e-9)))
    else:
        run.peer_note = "skipped"
    return run


def bench_cones(sizes=SIZES, maps=None, timeout=120.0, repeat=3, peer=True, peer_source=PEER_SOURCE,
                data=DATA, log=None) -> ConeBench:
    """Time every map kind at every size, ours and the peer's; a :class:`ConeBench`."""
    real = bench_maps.real_maps(Path(data))
    kinds = list(real) + list(bench_maps.PROCEDURAL)
    maps = kinds if not maps else maps
    for m in maps:
        if m not in kinds:
            raise ValueError(f"unknown map {m!r}: expected one of {kinds} "
                             f"(real maps come from {data})")
    exes, how = build_peer(Path(peer_source)) if peer else (None, "skipped: --no-peer")
    report = ConeBench(threads=numba.get_num_threads(), peer=how)
    warm_up()
    for n in sizes:
        for name in maps:
            if log:
                log(f"{name} {n}x{n}...")
            report.runs.append(bench_map(name, bench_maps.make_map(name, n, real), exes,
                                         timeout, repeat, log=log))
    return report
