"""Quadrant cones against the cheapest ``exact`` at the same budget, drawn by the shaders.

``python benchmarks/quadrant_trade.py [--size 128] [--px 64] [--json OUT] [MAP ...]``
(maps: the real depth maps of ``../shared/data`` when present, and ``terrain``; default all)

Per map (``size``² crop or resize, tiled, 8-bit, bilinear-safe maps, ``px``² renders at the six
views of ``verify`` from straight down to 10 degrees, against the exact tracer) the minimum
step is swept (:data:`STEPS` texels) for three families: ``exact`` (the paper's end of the
march on the conservative map), ``exact_interp`` (the interpolated end and the minimum step across
the texture, same map) and ``quadrant`` (the quadrant map). For each budget (p95 of the worst
view <= 0.25 and <= 1 texel, and at most 0.5% wrong-surface pixels at every view) it prints the
cheapest setting of each family by mean fetches (the shader's iterations) with its p99 and
8x4 block cost, and the saving of ``quadrant`` over the cheaper ``exact`` family.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import numpy as np  # noqa: E402

from csm_assets.bench import maps as bench_maps  # noqa: E402
from csm_assets.bench.trade import measure_trade  # noqa: E402
from csm_assets.packing import step_map  # noqa: E402
from csm_assets.verify.maps import DEFAULT_VIEWS  # noqa: E402

STEPS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
BUDGETS = (0.25, 1.0)
WRONG = 0.005  # the most wrong-surface pixels allowed at any view


def maps(n: int, data: Path) -> dict[str, np.ndarray]:
    real = bench_maps.real_maps(data)
    out = {k.replace("_disp", ""): bench_maps.load_real(v, n) for k, v in real.items()}
    out["terrain"] = bench_maps.terrain(n)
    return out


def sweep(h: np.ndarray, px: int) -> list[dict]:
    cons = step_map(h, bits=8, bilinear_safe=True)
    quad = step_map(h, bits=8, bilinear_safe=True, cones="quadrant")
    kw = dict(views=DEFAULT_VIEWS, size=px, draws=1)
    rows = []
    for w in STEPS:
        reps = [measure_trade(cons, configs=[("exact", 0), ("exact_interp", 0)], min_step=w, **kw),
                measure_trade(quad[..., :4], configs=[("quadrant", 0)], min_step=w, cones="quadrant",
                              second=quad[..., 4:], **kw)]
        for r in (row for rep in reps for row in rep.rows):
            rows.append(dict(family=r.variant, min_step=w, p95=r.p95_error, fetches=r.mean_iterations,
                             p99=r.p99_iterations, block=r.block_cost,
                             worst_wrong=max(v.wrong_share for v in r.views)))
    return rows


def cheapest(rows, family, budget):
    ok = [r for r in rows if r["family"] == family and r["p95"] <= budget and r["worst_wrong"] <= WRONG]
    return min(ok, key=lambda r: r["fetches"], default=None)


def summary(name, rows) -> list[str]:
    lines = []
    for budget in BUDGETS:
        best = {f: cheapest(rows, f, budget) for f in ("exact", "exact_interp", "quadrant")}
        parts = [f"{f} " + (f"{b['fetches']:.2f} fetches (p99 {b['p99']:.0f}, block {b['block']:.2f}) at "
                            f"min_step {b['min_step']:g}" if b else "none") for f, b in best.items()]
        base = min((b for f, b in best.items() if f != "quadrant" and b), key=lambda b: b["fetches"], default=None)
        q = best["quadrant"]
        if base and q:
            parts.append(f"quadrant saves {100 * (1 - q['fetches'] / base['fetches']):.0f}% fetches, "
                         f"{100 * (1 - q['block'] / base['block']):.0f}% block cost against {base['family']}")
        lines.append(f"{name}, p95 <= {budget:g}: " + "; ".join(parts))
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--px", type=int, default=64)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data",
                    help="folder of real depth maps (*_disp.*; default ../shared/data)")
    args = ap.parse_args(argv)
    every = maps(args.size, args.data)
    names = args.maps or list(every)
    result = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {platform.processor() or '?'}",
              "size": args.size, "px": args.px, "maps": {}}
    for name in names:
        t0 = time.perf_counter()
        rows = sweep(every[name], args.px)
        result["maps"][name] = rows
        print("\n".join(summary(name, rows)) + f"  [{time.perf_counter() - t0:.0f} s]", flush=True)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
