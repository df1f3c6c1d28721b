"""Quadrant cones against the cheapest ``exact`` at the same budget, drawn by the shaders.

``python benchmarks/quadrant_trade.py [--size N] [--px 128] [--json OUT] [--plot PNG] [MAP ...]``
(maps: the real depth maps of ``../shared/data`` when present at their own size, ``terrain``
(256², tiled) and ``terrain_crop`` (a 1024² crop of a 2048² terrain: it does not tile); default
all; ``--size N`` resizes every map to N² instead)

Per map (bilinear-safe maps, ``px``² renders at the six views of ``verify`` from
straight down to 10 degrees, against the exact tracer) the minimum step is swept
(:data:`STEPS`: 0.25 to 1 texel, the range a material holds, a factor sqrt(2) apart) for three families: ``exact`` (the paper's end of the
march on the conservative map), ``exact_interp`` (the interpolated end and the minimum step across
the texture, same map) and ``quadrant`` (the quadrant map). For each budget (p95 of the worst
view <= 0.25 and <= 1 texel, and at most 0.5% wrong-surface pixels at every view:
:mod:`csm_assets.bench.trade_budget`, as ``bench trade`` prints it) it prints the cheapest setting
of each family by mean fetches (the shader's iterations) with its p99 and 8x4 block cost, and the
saving of ``quadrant`` against ``exact`` and against ``exact_interp``. The maps' bits are those
``convert`` chooses by default (:func:`csm_assets.verify.bits.choose_bits` at verify's depth 0.1).
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
from PIL import Image  # noqa: E402

from csm_assets.bench import maps as bench_maps  # noqa: E402
from csm_assets.bench.trade import measure_trade  # noqa: E402
from csm_assets.bench.trade_budget import (BUDGETS, WRONG_SURFACE, budget_lines, budget_summary,  # noqa: E402
                                           cheapest_by_variant)
from csm_assets.packing import step_maps  # noqa: E402
from csm_assets.verify.bits import choose_bits  # noqa: E402
from csm_assets.verify.maps import DEFAULT_VIEWS  # noqa: E402

STEPS = tuple(round(0.25 * 2 ** (k / 2), 3) for k in range(5))  # 0.25 .. 1 texel: what a material holds
DEPTH = 0.1  # texture-space depth, verify's default


def maps(n: int, data: Path) -> dict[str, tuple[np.ndarray, bool]]:
    """``{name: (uint8 heights, tiles)}``: at their own size, or n² when n > 0."""
    out = {}
    for k, v in bench_maps.real_maps(data).items():
        with Image.open(v) as im:
            out[k.replace("_disp", "")] = (bench_maps.load_real(v, n or max(im.size)), True)
    out["terrain"] = (bench_maps.terrain(n or 256), True)
    crop = n or 1024
    out["terrain_crop"] = (bench_maps.terrain(2 * crop)[:crop, :crop], False)
    return out


def sweep(h: np.ndarray, tile: bool, px: int) -> tuple[int, list]:
    """(the maps' bits, the TradeRows of every family at every minimum step)."""
    chosen = []

    def bits(pack):  # as convert chooses them by default (verify's depth and views)
        chosen.append(choose_bits(lambda b: pack(b, "conservative"), DEPTH, tile=tile, min_step=0.25).bits)
        return chosen[0]

    made = step_maps(h, bits=bits, bilinear_safe=True, tile=tile, cones=("conservative", "quadrant"))
    cons, quad = made["conservative"], made["quadrant"]
    kw = dict(views=DEFAULT_VIEWS, size=px, draws=1, tile=tile, depth=DEPTH)
    rows = []
    for w in STEPS:
        rows += measure_trade(cons, configs=[("exact", 0), ("exact_interp", 0)], min_step=w, **kw).rows
        rows += measure_trade(quad[..., :4], configs=[("quadrant", 0)], min_step=w, cones="quadrant",
                              second=quad[..., 4:], **kw).rows
    return chosen[0], rows


def as_dict(r) -> dict:
    return dict(family=r.variant, min_step=r.min_step, p95=r.p95_error, fetches=r.mean_iterations,
                p99=r.p99_iterations, block=r.block_cost, worst_wrong=max(v.wrong_share for v in r.views))


def summary(rows) -> list[str]:
    """Per budget: each family's cheapest setting within it, and quadrant's saving against exact
    and against exact_interp (the new end of the march alone)."""
    lines = budget_lines(rows)
    for b in BUDGETS:
        best = cheapest_by_variant(rows, b)
        q, e = best.get(("quadrant", "quadrant")), best.get(("exact_interp", "conservative"))
        if q and e:
            lines.append(f"  p95 <= {b:g}: quadrant against exact_interp: "
                         f"{100 * (1 - q.mean_iterations / e.mean_iterations):.0f}% fewer fetches, "
                         f"{100 * (1 - q.block_cost / e.block_cost):.0f}% lower block cost")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*")
    ap.add_argument("--size", type=int, default=0, help="resize every map to N x N (default: their own sizes)")
    ap.add_argument("--px", type=int, default=128)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--plot", type=Path, help="PNG: p95 error against mean fetches, a panel per map")
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data",
                    help="folder of real depth maps (*_disp.*; default ../shared/data)")
    args = ap.parse_args(argv)
    every = maps(args.size, args.data)
    names = args.maps or list(every)
    result = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {platform.processor() or '?'}",
              "size": args.size, "px": args.px, "maps": {}}
    for name in names:
        t0 = time.perf_counter()
        h, tile = every[name]
        bits, rows = sweep(h, tile, args.px)
        result["maps"][name] = dict(shape=list(h.shape), tile=tile, bits=bits, rows=[as_dict(r) for r in rows],
                                    budgets=budget_summary(rows))
        print(f"{name} ({h.shape[1]}x{h.shape[0]}, {'tiled' if tile else 'not tiled'}, {bits}-bit, "
              f"{time.perf_counter() - t0:.0f} s):\n" + "\n".join(summary(rows)), flush=True)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    if args.plot:
        plot(result, args.plot)
    return 0


def plot(result: dict, path: Path) -> None:
    """p95 error of the worst view against mean fetches, one panel per map, one curve per family;
    hollow markers: more than 0.5% wrong-surface pixels at some view (outside every budget)."""
    from csm_assets.bench.trade_plot import require_matplotlib

    require_matplotlib()
    import matplotlib.pyplot as plt

    names = list(result["maps"])
    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names), 3.6), dpi=100, squeeze=False)
    colors = {"exact": "#000000", "exact_interp": "#1f77b4", "quadrant": "#d62728"}
    for ax, name in zip(axes[0], names):
        m = result["maps"][name]
        for family, color in colors.items():
            rows = sorted((r for r in m["rows"] if r["family"] == family), key=lambda r: r["fetches"])
            ax.plot([r["fetches"] for r in rows], [max(r["p95"], 1e-3) for r in rows], "-", color=color, lw=1,
                    label=family)
            for ok in (True, False):
                pts = [r for r in rows if (r["worst_wrong"] <= WRONG_SURFACE) == ok]
                ax.plot([r["fetches"] for r in pts], [max(r["p95"], 1e-3) for r in pts], "o", color=color, ms=4,
                        mfc=color if ok else "none", ls="none")
        for b in BUDGETS:
            ax.axhline(b, color="grey", lw=0.7, ls="-.")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_title(f"{name} {m['shape'][1]}x{m['shape'][0]}, {m['bits']}-bit{'' if m['tile'] else ', not tiled'}",
                     fontsize=9)
        ax.set_xlabel("mean fetches per pixel", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
    axes[0][0].set_ylabel("p95 error, worst view (texels)", fontsize=8)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"{result['date']}, {result['px']}² px renders, 6 views 90-10°; hollow: > 0.5% wrong surface",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    sys.exit(main())
