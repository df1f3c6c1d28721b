"""Quadrant cones against the conservative cones on one map, timed in one run.

``python benchmarks/quadrant.py [--size 1024] [--repeat 2] [--map terrain|tiles|noise]``
prints the best time of each (after a warm-up run that compiles the kernels), wall and CPU
(all threads), and the ratio quadrant / conservative; issue 24's target is at most 2 on a
1024² terrain. Wall times on a shared machine move with its load; the pyramid blocks the
quadrant search examines per texel do not (``quadrant_exact(..., seen=)``).
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from csm_assets import cone_ratios, quadrant_cone_ratios  # noqa: E402
from csm_assets.bench import maps  # noqa: E402
from csm_assets.cones.quadrant import quadrant_exact  # noqa: E402
from csm_assets.heightfield import unit_heights  # noqa: E402
from csm_assets.polling import thread_count  # noqa: E402


def best_time(fn, h, repeat):
    fn(h[:64, :64])  # compile (or load from the cache) on a small map first
    times, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn(h)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(times), min(cpu), out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--map", choices=maps.PROCEDURAL, default="terrain")
    args = ap.parse_args(argv)
    h = getattr(maps, args.map)(args.size)
    t_cons, c_cons, cons = best_time(cone_ratios, h, args.repeat)
    t_quad, c_quad, quad = best_time(quadrant_cone_ratios, h, args.repeat)
    if not np.array_equal(quad.min(axis=0), cons):
        print("error: the minimum over the quadrants differs from cone_ratios", file=sys.stderr)
        return 1
    widen = float(np.mean(quad / cons[None]))
    print(f"{args.map} {args.size}x{args.size}, {thread_count()} threads")
    seen = np.zeros(1, np.int64)
    quadrant_exact(unit_heights(h), True, True, 1.0, seen=seen)
    print(f"conservative cones: {t_cons:8.3f} s wall, {c_cons:8.3f} s CPU")
    print(f"quadrant cones:     {t_quad:8.3f} s wall, {c_quad:8.3f} s CPU")
    print(f"ratio quadrant / conservative: {t_quad / t_cons:.2f} wall, {c_quad / c_cons:.2f} CPU"
          " (target <= 2)")
    print(f"quadrant search: {seen[0] / h.size:.1f} pyramid blocks examined per texel")
    print(f"mean quadrant cone / conservative cone: {widen:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
