"""Relaxed cones: ours against a port of the published brute force, in one run.

``python benchmarks/relaxed.py [--size 1024] [--maps terrain toy_box_disp] [--samples 1500]``

Ours: :func:`csm_assets.relaxed_cone_ratios` on the whole map, tiled and not (wall time
after numba's warm-up, both cores), with the conservative ``cone_ratios`` for scale. The
peer: a numba port of the falling-edge generator of Bán et al., "Robust Cone Step
Mapping" (EGSR 2024; the ``CONE_TYPE 4`` compute shader of Bundas102/robust-cone-map,
re-written here from its description): per texel, square rings outward until the ring is
beyond the cone's reach, a texel limiting when it is inside the cone and its cell away
from the apex has a falling edge; cells must lie inside the map (no tiling). It is run
on ``--samples`` random texels (its cost is O(N^2) per texel of a wide cone) and its
whole-map time extrapolated; its values are compared with ours (not tiled) there. The
rules differ (ours: the falling-direction rule with sub-cells, docs/reference/conventions.md), so
the comparison counts where ours is wider and narrower, and their mean ratios.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from csm_assets import cone_ratios, relaxed_cone_ratios  # noqa: E402
from csm_assets.bench import maps as bench_maps  # noqa: E402


@njit(cache=True)
def _peer_update(h, bi, bj, hb, i, j, di, dj, best):
    """The peer's test of texel (row i, col j) with its cell towards (di, dj)."""
    H, W = h.shape
    dist = math.hypot((i - bi) / H, (j - bj) / W)
    if dist >= best * (1.0 - hb):
        return best
    dh = h[i, j] - hb
    if dist >= best * dh:
        return best
    h00, h10, h01, h11 = h[i, j], h[i, j + dj], h[i + di, j], h[i + di, j + dj]
    if h00 > h10 or h00 > h01 or h10 > h11 or h01 > h11:
        best = min(best, dist / dh)
    return best


@njit(cache=True)
def peer_texels(h, rows, cols):
    """The peer's ratios (max 1) at texels (rows[k], cols[k]) of float64 heights h."""
    H, W = h.shape
    out = np.empty(len(rows))
    for k in range(len(rows)):
        bi, bj = rows[k], cols[k]
        hb = h[bi, bj]
        best = 1.0
        for r in range(1, max(H, W) + 1):
            if r / max(H, W) >= best * (1.0 - hb):
                break
            for di in (-1, 1):
                for dj in (-1, 1):
                    lo_i, hi_i = (0, H - 2) if di > 0 else (1, H - 1)
                    lo_j, hi_j = (0, W - 2) if dj > 0 else (1, W - 1)
                    # the side at column offset dj*r, rows bi .. bi+di*r
                    j = bj + dj * r
                    if lo_j <= j <= hi_j:
                        for s in range(r + 1):
                            i = bi + di * s
                            if not lo_i <= i <= hi_i:
                                break
                            best = _peer_update(h, bi, bj, hb, i, j, di, dj, best)
                    # the side at row offset di*r, columns bj .. bj+dj*(r-1)
                    i = bi + di * r
                    if lo_i <= i <= hi_i:
                        for s in range(r):
                            j = bj + dj * s
                            if not lo_j <= j <= hi_j:
                                break
                            best = _peer_update(h, bi, bj, hb, i, j, di, dj, best)
        out[k] = best
    return out


def timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return time.perf_counter() - t0, out


def bench_map(name: str, u8: np.ndarray, samples: int, seed: int = 0) -> dict:
    n = u8.size
    t_cons, _ = timed(cone_ratios, u8, tile=True)
    t_tiled, rel_t = timed(relaxed_cone_ratios, u8, tile=True)
    t_flat, rel = timed(relaxed_cone_ratios, u8, tile=False)
    h = u8 / 255.0
    rng = np.random.default_rng(seed)
    idx = rng.choice(n, size=min(samples, n), replace=False)
    rows, cols = (idx // u8.shape[1]).astype(np.int64), (idx % u8.shape[1]).astype(np.int64)
    t_peer, peer = timed(peer_texels, h, rows, cols)
    ours = rel[rows, cols].astype(np.float64)
    inner = (rows > 0) & (rows < u8.shape[0] - 1) & (cols > 0) & (cols < u8.shape[1] - 1)
    same = np.isclose(ours, peer, rtol=1e-6, atol=0)
    cons = cone_ratios(u8, tile=True)
    return {
        "map": name, "size": u8.shape[0], "conservative_s": round(t_cons, 3),
        "relaxed_tiled_s": round(t_tiled, 3), "relaxed_s": round(t_flat, 3),
        "peer_s_extrapolated": round(t_peer * n / len(idx), 1),
        "sampled": len(idx), "agree": float(same.mean()),
        "agree_inside_border": float(same[inner].mean()) if inner.any() else None,
        "ours_wider_than_peer": float((ours > peer * (1 + 1e-6)).mean()),
        "ours_narrower_than_peer": float((ours < peer * (1 - 1e-6)).mean()),
        "mean_sampled_peer": float(np.minimum(peer, 1.0).mean()), "mean_sampled_ours": float(ours.mean()),
        "mean_ratio_conservative": float(cons.mean()), "mean_ratio_relaxed": float(rel_t.mean()),
        "wider_texels": float((rel_t > cons).mean()),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=1024)
    p.add_argument("--maps", nargs="+", default=["terrain"])
    p.add_argument("--samples", type=int, default=1500)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    real = bench_maps.real_maps(Path(__file__).resolve().parents[2] / "shared" / "data")
    # warm up: compile or load every kernel first
    w = np.random.default_rng(1).integers(0, 256, (40, 40)).astype(np.uint8)
    relaxed_cone_ratios(w, tile=True), relaxed_cone_ratios(w, tile=False), cone_ratios(w)
    peer_texels(w / 255.0, np.zeros(1, np.int64), np.zeros(1, np.int64))
    runs = [bench_map(m, bench_maps.make_map(m, a.size, real), a.samples) for m in a.maps]
    if a.json:
        print(json.dumps(runs, indent=1))
    else:
        for r in runs:
            print(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                           for k, v in r.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
