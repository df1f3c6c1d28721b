"""Relaxed against conservative cones in the shader: safety and fetches per pixel.

``python benchmarks/relaxed_trade.py [MAP ...]`` (default: every map below)

Per map (128x128, tiled, 8-bit, bilinear-safe, 0.25-texel minimum step, 64 px renders at
six views from straight down to 10 degrees): the ``exact`` variant on the conservative
map, the ``relaxed`` variant with 1 to 6 binary steps on the relaxed map (and with 6 on
the conservative map), each as (p95 error in texels of the worst view, mean texture
fetches per pixel, wrong-surface share) against the exact tracer. Maps: the real depth
maps of ``../shared/data`` (when present), a terrain, and adversarial ones: thin walls,
single spikes, white noise, terraces, a ramp whose tiled seam drops.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from csm_assets import bench_maps  # noqa: E402
from csm_assets.packing import SAFE_MIN_STEP, step_map  # noqa: E402
from csm_assets.trade import measure_trade  # noqa: E402

VIEWS = [(90, 0), (50, 120), (35, 200), (20, 290), (10, 45), (10, 225)]


def maps(n: int = 128) -> dict[str, np.ndarray]:
    real = bench_maps.real_maps(Path(__file__).resolve().parents[2] / "shared" / "data")
    rng = np.random.default_rng(4)
    out = {k: bench_maps.load_real(v, n) / 255.0 for k, v in real.items()}
    out["terrain"] = bench_maps.terrain(n) / 255.0
    walls = np.zeros((n, n))
    walls[:, ::16] = 1.0
    walls[::32, :] = 0.8
    out["thin_walls"] = walls
    spikes = np.zeros((n, n))
    spikes[rng.integers(0, n, 40), rng.integers(0, n, 40)] = 1.0
    out["spikes"] = spikes
    out["noise"] = rng.random((n, n))
    out["terraces"] = np.floor(bench_maps.terrain(n) / 255.0 * 6) / 6
    out["seam_ramp"] = np.tile(np.linspace(0, 1, n), (n, 1))
    return out


def row(r) -> list:
    return [round(r.p95_error, 3), round(r.mean_iterations, 2), round(r.wrong_share, 4)]


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:])
    every = maps()
    for name in names or list(every):
        h = every[name]
        t0 = time.perf_counter()
        kw = dict(views=VIEWS, size=64, draws=1, min_step=SAFE_MIN_STEP)
        cons = step_map(h, bits=8, bilinear_safe=True)
        rel = step_map(h, bits=8, bilinear_safe=True, cones="relaxed")
        res = {r.label: row(r) for r in measure_trade(cons, configs=[("exact", 0)], **kw).rows}
        res.update({r.label: row(r) for r in
                    measure_trade(rel, configs=[("relaxed", k) for k in (1, 2, 3, 4, 6)], **kw).rows})
        res["relaxed 6, conservative map"] = row(measure_trade(cons, configs=[("relaxed", 6)], **kw).rows[0])
        print(name, f"{time.perf_counter() - t0:.0f}s", json.dumps(res), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
