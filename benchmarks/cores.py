"""How much faster ``csm-assets stepmap`` runs on all cores than on one, and where the time goes.

    python benchmarks/cores.py [--size 4096] [--kind terrain] [--cones conservative] [--repeat 3]
                               [--threads 0]

Each run is ``csm-assets stepmap MAP -o OUT --cones KIND -q`` in a child process (this script
with ``--child``), on one core and then on all, alternating, ``--repeat`` times. One core: the
child is pinned to one CPU (``os.sched_setaffinity``, as ``taskset -c``) with
``NUMBA_NUM_THREADS=1``, so its numba threads and the threads that write the images share that
CPU, as on a one-core machine (``NUMBA_NUM_THREADS=1`` alone no longer means one core: the
images are written on threads beside the cone search). All: every CPU this script may run on,
``--threads`` numba threads (0: one a CPU). The child times the stages of the run by wrapping the
functions that do them (:data:`STAGES`; a stage's time leaves out the stages inside it): wall
seconds, and CPU seconds of the whole process (every thread) while the stage runs, less what the
writer threads spent meanwhile; the writing stages (:data:`WRITERS`, on their own threads beside
the others) count their own thread's CPU time, and that of a PNG's bands deflated on threads of
their own (:func:`band_threads`). Printed: the median wall and CPU time of each run with the load
average (1 minute) around the runs, their ratio (the speed-up; also the median of each repeat's own
ratio), and a table of stages: CPU seconds and share of a one-core run, median
wall seconds on one core and on all, and the cores a stage kept busy on all (CPU / wall: about 1
for a serial stage, up to the thread count). "the rest" is what no stage covers (imports, the
wait for the last write); its wall time is the run's less the main thread's stages. ``serial`` is
Karp-Flatt's experimentally determined serial fraction of the whole run, ``(1/speedup - 1/p) /
(1 - 1/p)``. Other jobs on the machine slow the wall times (and a serial stage's CPU / wall falls
below 1); CPU times hold. Both runs must write the same bytes: the files are compared.
Maps: :mod:`csm_assets.bench.maps` as ``benchmarks/memory.py`` makes them (8-bit PNG).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout

# stage: the functions that do it, as the modules that call them look them up; nested stages are
# taken out of the stage around them (NESTED)
STAGES = {
    "reading the map": [("csm_assets.formats", "load_heightfield")],
    "max pyramid": [("csm_assets.packing", "pyramid_heights")],
    "method choice": [("csm_assets.cones.exact", "choose_method")],
    "cone search": [("csm_assets.packing", "cone_ratio_maps"), ("csm_assets.step_levels", "cone_ratio_maps")],
    "packing": [("csm_assets.packing", "pack_bands")],
    "bits choice (march, tracer)": [("csm_assets.verify.bits", "quad_error")],
    "level chain: filtering": [("csm_assets.step_levels", "next_level")],
    "level chain: packing": [("csm_assets.step_levels", "pack_bands")],
    "levels atlas": [("csm_assets.step_files", "atlas")],
    "writing the PNGs": [("csm_assets.formats.image", "_write_pixels")],
    "reading them back": [("csm_assets.formats.image", "_read_back")],
}
NESTED = {"cone search": ("max pyramid", "method choice"), "writing the PNGs": ("reading them back",)}
WRITERS = ("writing the PNGs", "reading them back")  # on threads of their own (formats.step_map_writes)


class Writers:
    """CPU seconds spent so far by the threads while they write (a running write read through its
    thread's clock)."""

    def __init__(self):
        self.lock, self.done, self.running = threading.Lock(), 0.0, {}

    def total(self) -> float:
        with self.lock:
            return self.done + sum(time.clock_gettime(c) - c0 for c, c0 in self.running.values())

    def run(self, f, *args, **kwargs):
        if threading.get_ident() in self.running:  # counted already (a band deflated on the writing thread)
            return f(*args, **kwargs)
        clock = time.pthread_getcpuclockid(threading.get_ident())
        with self.lock:
            self.running[threading.get_ident()] = (clock, time.clock_gettime(clock))
        try:
            return f(*args, **kwargs)
        finally:
            with self.lock:
                clock, c0 = self.running.pop(threading.get_ident())
                self.done += time.clock_gettime(clock) - c0


def band_threads(writers: Writers, spent: dict, lock: threading.Lock) -> None:
    """Count a PNG's bands deflated on threads of their own (``png_write._deflate_band``; one thread:
    on the writing thread, already counted) as the writers' CPU time, in ``spent``'s first writing stage."""
    from csm_assets.formats import png_write

    deflate = png_write._deflate_band

    def run(*args, **kwargs):
        if threading.get_ident() in writers.running:
            return deflate(*args, **kwargs)
        c = time.thread_time()
        try:
            return writers.run(deflate, *args, **kwargs)
        finally:
            with lock:
                spent[WRITERS[0]][1] += time.thread_time() - c
    png_write._deflate_band = run


def child(src: str, dst: str, cones: str) -> None:
    """Run stepmap here with every stage timed; print ``{"stages": {name: [wall, cpu]}, "wall", "cpu",
    "cpus"}``."""
    spent = {name: [0.0, 0.0] for name in STAGES}
    writers, lock = Writers(), threading.Lock()  # lock: spent is added to from several threads
    band_threads(writers, spent, lock)

    def timed(name, f):
        def run(*args, **kwargs):
            if name in WRITERS:  # its own thread's CPU time (its PNG's bands on other threads: band_threads)
                w, c = time.perf_counter(), time.thread_time()
                call = (lambda: writers.run(f, *args, **kwargs)) if name == WRITERS[0] else lambda: f(*args, **kwargs)
                clock = time.thread_time
            else:  # the process's, less the writers' meanwhile
                w, c = time.perf_counter(), time.process_time() - writers.total()
                call, clock = (lambda: f(*args, **kwargs)), lambda: time.process_time() - writers.total()
            try:
                return call()
            finally:
                wall, cpu = time.perf_counter() - w, clock() - c
                with lock:
                    spent[name][0] += wall
                    spent[name][1] += cpu
        return run

    from csm_assets.cli import main

    for name, where in STAGES.items():
        for module, attr in where:
            m = importlib.import_module(module)
            setattr(m, attr, timed(name, getattr(m, attr)))
    w, c = time.perf_counter(), time.process_time()
    code = main(["stepmap", src, "-o", dst, "--cones", cones, "-q"])
    wall, cpu = time.perf_counter() - w, time.process_time() - c
    if code:
        sys.exit(code)
    for outer, inner in NESTED.items():
        for k in (0, 1):
            spent[outer][k] -= sum(spent[i][k] for i in inner)
    rest = [wall - sum(s[0] for n, s in spent.items() if n not in WRITERS), cpu - sum(s[1] for s in spent.values())]
    print(json.dumps({"stages": {**spent, "the rest": rest}, "wall": wall, "cpu": cpu,
                      "cpus": len(os.sched_getaffinity(0))}))


def run_child(src: Path, dst: Path, cones: str, threads: int, cpus: set[int]) -> dict:
    """One child run pinned to ``cpus`` with ``threads`` numba threads (0: numba's default)."""
    env = dict(os.environ)
    env.pop("NUMBA_NUM_THREADS", None)
    if threads:
        env["NUMBA_NUM_THREADS"] = str(threads)
    load = os.getloadavg()[0]
    out = subprocess.run([sys.executable, __file__, "--child", str(src), str(dst), cones], env=env,
                         capture_output=True, text=True, check=True,
                         preexec_fn=lambda: os.sched_setaffinity(0, cpus)).stdout
    got = json.loads(out.strip().splitlines()[-1])
    got["load"] = (load + os.getloadavg()[0]) / 2
    return got


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=4096)
    p.add_argument("--kind", default="terrain", choices=["terrain", "noise"])
    p.add_argument("--cones", default="conservative", choices=["conservative", "relaxed", "quadrant"])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--threads", type=int, default=0, help="threads of the all-core runs (0: all cores)")
    p.add_argument("--child", nargs=3, metavar=("MAP", "OUT", "CONES"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    from memory import make_map  # benchmarks/memory.py, beside this file

    cpus = os.sched_getaffinity(0)
    many = args.threads or len(cpus)
    runs = {1: [], many: []}
    pinned = {1: {min(cpus)}, many: cpus}  # one core: one CPU; all: every CPU
    with tempfile.TemporaryDirectory(prefix="csm-cores-") as tmp:
        folder = Path(tmp)
        src = make_map(args.kind, args.size, 8, folder)
        run_child(make_map(args.kind, 64, 8, folder), folder / "warm.png", args.cones, 0, cpus)  # kernels compiled
        for threads in runs:  # the same file names (a quadrant map's first image names its second)
            (folder / str(threads)).mkdir()
        for _ in range(args.repeat):
            for threads in runs:
                runs[threads].append(run_child(src, folder / str(threads) / "out.png", args.cones, threads,
                                               pinned[threads]))
        same = all((folder / "1" / f.name).read_bytes() == f.read_bytes() for f in (folder / str(many)).iterdir())
    med = {t: statistics.median(r["wall"] for r in rs) for t, rs in runs.items()}
    speedup = med[1] / med[many]
    paired = statistics.median(a["wall"] / b["wall"] for a, b in zip(runs[1], runs[many]))
    print(f"stepmap {args.kind} {args.size}^2, {args.cones} cones, {args.repeat} runs each "
          f"(median), same bytes: {'yes' if same else 'NO'}")
    for t, rs in runs.items():
        walls = ", ".join(f"{r['wall']:.1f}" for r in rs)
        print(f"  {t} thread{'s' if t > 1 else ''} on {rs[0]['cpus']} CPU{'s' if rs[0]['cpus'] > 1 else ''}: "
              f"{med[t]:.1f} s wall, "
              f"{statistics.median(r['cpu'] for r in rs):.1f} s CPU, load {min(r['load'] for r in rs):.1f}"
              f"-{max(r['load'] for r in rs):.1f}  (walls: {walls})")
    serial = (1 / speedup - 1 / many) / (1 - 1 / many) if many > 1 else 1.0
    print(f"  speed-up {speedup:.2f}x (median of each repeat's: {paired:.2f}x); serial fraction "
          f"(Karp-Flatt) {serial:.1%}")
    cpu1 = statistics.median(r["cpu"] for r in runs[1])
    print(f"\n  {'stage':<30} {'CPU s (1)':>9} {'share':>6} {'wall 1':>7} {f'wall {many}':>7} {'cores':>6}")
    for name in runs[1][0]["stages"]:
        c1 = statistics.median(r["stages"][name][1] for r in runs[1])
        w1 = statistics.median(r["stages"][name][0] for r in runs[1])
        wn = statistics.median(r["stages"][name][0] for r in runs[many])
        cn = statistics.median(r["stages"][name][1] for r in runs[many])
        print(f"  {name:<30} {c1:>9.2f} {c1 / cpu1:>6.1%} {w1:>7.2f} {wn:>7.2f} {cn / max(wn, 1e-9):>6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
