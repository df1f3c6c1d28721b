"""Relaxed against conservative cones in the shader: safety and fetches per pixel.

``python benchmarks/relaxed_trade.py [MAP ...]`` (default: every map below)

Per map (128x128, tiled, 8-bit, bilinear-safe, 0.25-texel minimum step, 64 px renders at
six views from straight down to 10 degrees), each setting as (p95 error in texels of the
worst view, mean texture fetches per pixel, wrong-surface share) against the exact tracer:
the ``exact`` variant on the conservative map with the 45-degree cap (``max_ratio`` 1) and
lifted (4); the ``relaxed`` variant with 1, 2 and 4 search steps on the relaxed map at both
caps, and with 1 on the conservative map (the loop shape alone); and a ceiling no safe
rule can beat: ``relaxed`` on a map whose every cone is the cap (unsafe: rays pass through
walls). The last line per map: the fewest fetches meeting 1 texel p95, conservative
(``exact``) against relaxed (any cap), and the gain. Maps: the real depth maps of
``../shared/data`` (when present), a terrain, and adversarial ones: thin walls, single
spikes, white noise, terraces, a ramp whose tiled seam drops.
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


def measure(h) -> dict:
    """label -> [p95, fetches, wrong share] for the settings of the module doc."""
    kw = dict(views=VIEWS, size=64, draws=1, min_step=SAFE_MIN_STEP)
    res = {}
    for cap in (1.0, 4.0):
        cons = step_map(h, bits=8, bilinear_safe=True, max_ratio=cap)
        rel = step_map(h, bits=8, bilinear_safe=True, cones="relaxed", max_ratio=cap)
        for r in measure_trade(cons, configs=[("exact", 0)], max_ratio=cap, **kw).rows:
            res[f"exact, cap {cap:g}"] = row(r)
        for r in measure_trade(rel, configs=[("relaxed", k) for k in (1, 2, 4)], max_ratio=cap, **kw).rows:
            res[f"{r.label}, cap {cap:g}"] = row(r)
    cons = step_map(h, bits=8, bilinear_safe=True)
    res["relaxed 1, conservative map"] = row(measure_trade(cons, configs=[("relaxed", 1)], **kw).rows[0])
    wide = cons.copy()
    wide[..., 1] = 255
    for r in measure_trade(wide, configs=[("relaxed", k) for k in (2, 4, 6)], **kw).rows:
        res[f"ceiling {r.label}"] = row(r)
    return res


def gain(res: dict, budget: float = 1.0) -> tuple:
    """(fewest fetches of exact meeting the budget, of relaxed on relaxed maps, their
    labels, the relative saving); None where none meets it."""
    def best(keep):
        ok = [(v[1], k) for k, v in res.items() if keep(k) and v[0] <= budget]
        return min(ok, default=(None, None))
    ce, ke = best(lambda k: k.startswith("exact"))
    cr, kr = best(lambda k: k.startswith("relaxed") and "conservative" not in k)
    saving = None if ce is None or cr is None else round(1 - cr / ce, 3)
    return ce, ke, cr, kr, saving


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:])
    every = maps()
    for name in names or list(every):
        t0 = time.perf_counter()
        res = measure(every[name])
        print(name, f"{time.perf_counter() - t0:.0f}s", json.dumps(res), flush=True)
        print(name, "at 1 texel p95 (exact, relaxed, saving):", gain(res), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
