"""``csm-assets bench cones`` (:func:`csm_assets.bench.cones.bench_cones`: exact cones against the
paper's preprocessor) and ``csm-assets bench trade`` (:func:`csm_assets.bench.trade.measure_trade`:
error against cost of every shader variant and step count on a map)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..bench import trade
from ..bench.trade_budget import budget_lines, budget_summary
from ..bench.cones import PEER_SOURCE, SIZES, bench_cones
from ..stepmap import DEFAULTS
from ..verify.maps import DEFAULT_VIEWS
from ..verify.shadows import PICK_LIGHT
from .common import BIT_DEPTHS, POSITIVE, add_map_kind, add_map_settings, add_views, default, number, stage_line, view

TIMEOUT, REPEAT = default(bench_cones, "timeout"), default(bench_cones, "repeat")
SIZE, DEPTH = default(trade.measure_trade, "size"), default(trade.measure_trade, "depth")
MAX_ITERATIONS = default(trade.measure_trade, "max_iterations")

CONES_DESCRIPTION = (
    "The peer is ../shared/anchors/dummer_preproc.cpp next to the repository (or --peer-source), built with "
    "g++ -O3 -march=native into a cache folder under the system temp dir; it is skipped, saying why, when g++ "
    "or the file is missing. Both sides get the same uint8 maps. Times exclude file I/O: the peer's own 'cone "
    "search' clock (one thread), ours the exact_ratios call after numba's warm-up (all numba threads). Our "
    "results are checked against a brute force on sample texels; exit 1 when they differ.")
TRADE_DESCRIPTION = (
    "Draw IN with every shader variant and step count (exact; loop and fixed at 1 to 64 steps; parallax; "
    "pom and relief at 4 to 64; relaxed at 1, 2 and 4 search steps; exact_interp; and for a height map also "
    "relaxed on its map of relaxed cones and quadrant on its quadrant map) at each view and compare every pixel "
    "with the exact tracer: texel error (mean, p95 of the worst view, max), wrong-surface and non-converged "
    "shares, mean, p99 and max iterations (the hardware-independent cost), the 8x4 block cost and the draw's "
    "frame time on this machine's renderer. Prints a table (or JSON), then each variant's cheapest setting "
    "within p95 0.25 and 1 texel with at most 0.5% wrong-surface pixels at every view and what quadrant cones "
    "save against exact; plots p95 error against mean iterations. Below the table, the distance columns: "
    "the conservative map far away, today's level-0 march against the level chain's (a flag leaves "
    "them out).")


def add(sub) -> None:
    b = sub.add_parser("bench", help="benchmarks (cones: against the paper's preprocessor; trade: "
                                     "speed against accuracy of the shader variants)")
    benches = b.add_subparsers(dest="bench", metavar="BENCH", required=True, parser_class=type(b))
    add_cones(benches.add_parser("cones", help="time exact cone ratios against the paper's preprocessor",
                                 description=CONES_DESCRIPTION))
    add_trade(benches.add_parser("trade", help="error against cost of every shader variant and step count "
                                               "on a map", description=TRADE_DESCRIPTION))


def add_cones(p) -> None:
    p.add_argument("--sizes", type=number(int, low=2), nargs="+", default=list(SIZES), metavar="N",
                   help=f"square map sizes, >= 2 (default {' '.join(map(str, SIZES))})")
    p.add_argument("--maps", nargs="+", metavar="MAP",
                   help="map kinds (default all: the *_disp maps in ../shared/data, terrain, tiles, noise)")
    p.add_argument("--timeout", type=POSITIVE, default=TIMEOUT, metavar="S",
                   help=f"seconds the peer may take per map (default {TIMEOUT:g})")
    p.add_argument("--repeat", type=number(int, low=1), default=REPEAT, metavar="K",
                   help=f"best of K runs for runs under a second (default {REPEAT})")
    p.add_argument("--no-peer", action="store_true", help="time only this library")
    p.add_argument("--peer-source", type=Path, default=PEER_SOURCE, metavar="CPP",
                   help=f"the paper's preprocessor (default {PEER_SOURCE})")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(run=run_cones)


def run_cones(args) -> int:
    log = None if args.json else (lambda s: print(s, file=sys.stderr, flush=True))
    report = bench_cones(args.sizes, args.maps, args.timeout, args.repeat, not args.no_peer,
                         args.peer_source, log=log)
    print(json.dumps(report.to_dict(), indent=2) if args.json else report.table())
    return 0 if all(r.exact for r in report.runs) else 1


def add_trade(p) -> None:
    p.add_argument("input", metavar="IN", help="a height map (any format stepmap reads) or a csm-assets step map")
    add_views(p, DEFAULT_VIEWS, "90: straight down")
    p.add_argument("--size", type=number(int, low=8), default=SIZE, metavar="PX",
                   help=f"render size in pixels, >= 8 (default {SIZE}, as verify)")
    p.add_argument("--depth", type=POSITIVE, default=DEPTH, metavar="D",
                   help=f"relief depth as a fraction of the texture's width (default {DEPTH:g}; 2^-24 to 2^24 "
                        "texels deep: D x the map's longer side)")
    p.add_argument("--bits", type=int, nargs="+", choices=BIT_DEPTHS, default=[DEFAULTS.bits], metavar="B",
                   help="bits of the step map made from a height map: 8, 16, 32, or several to "
                        f"compare quantization (default {DEFAULTS.bits})")
    add_map_kind(p)
    p.add_argument("--invert", action="store_true", help="IN is a depth map (white = deep)")
    p.add_argument("--no-tile", action="store_true", help="the texture does not repeat")
    add_map_settings(p, several=True)
    p.add_argument("--no-bilinear-safe", action="store_true",
                   help="make the step map of a height map with the paper's cones (exact at texel centres) and "
                        "exact's 1-texel minimum step, not convert's bilinear safety pass and 0.25 texel")
    p.add_argument("--max-iterations", type=number(int, low=1), default=MAX_ITERATIONS, metavar="N",
                   help=f"iteration cap of exact (default {MAX_ITERATIONS})")
    p.add_argument("--json", action="store_true", help="print the report(s) as JSON")
    p.add_argument("--plot", metavar="PNG", help="write the error-against-cost plot to PNG")
    light = "/".join(f"{x:g}" for x in PICK_LIGHT)
    p.add_argument("--shadows", nargs="?", type=view, const=PICK_LIGHT, metavar="EL/AZ",
                   help=f"draw with self-shadowing from a directional light at EL/AZ degrees (default {light}): "
                        "the shadow ray's steps count in the iterations (the cost)")
    far = ", ".join(f"{t:g}" for t in dict.fromkeys(v[0] for v in trade.DISTANCE_VIEWS))
    p.add_argument("--no-distance", action="store_true",
                   help=f"leave out the distance columns: the conservative map at {far} texels a pixel at "
                        f"{' and '.join(f'{e:g}' for e in dict.fromkeys(v[1] for v in trade.DISTANCE_VIEWS))} "
                        "degrees, today's level-0 march against the level chain's (measured as verify does far away: "
                        "image RMSE, flicker, fetches, cache tiles)")
    p.set_defaults(run=run_trade)


def run_trade(args) -> int:
    from ..bench.trade_plot import plot_trade, require_matplotlib

    if args.plot:
        require_matplotlib()  # before minutes of measuring
    line = stage_line(False, Path(args.input).name)  # on a terminal: the setting being measured
    try:
        reports = _measure(args, line)
    finally:
        if line is not None:
            line.close()
    if args.json:
        data = [{**r.to_dict(), "budgets": budget_summary(r.rows)} for r in reports]
        sys.stdout.write(json.dumps(data[0] if len(data) == 1 else data, indent=2) + "\n")
    else:
        sys.stdout.write("\n\n".join("\n".join([r.table(), *budget_lines(r.rows)]) for r in reports) + "\n")
    if args.plot:
        plot_trade(reports, args.plot)
    return 0


def _measure(args, line) -> list:
    """The trade reports of ``args.input``, one per bit depth (one only for a step map)."""
    reports = []
    for bits in dict.fromkeys(args.bits):
        if line is not None:
            line("reading")
        reports.append(trade.measure_file(Path(args.input), invert=args.invert, bits=bits,
                                          tile=False if args.no_tile else None, as_step_map=args.step_map,
                                          channel=args.channel, max_ratio=args.max_ratio,
                                          min_step=args.min_step, configs=trade.BENCH_CONFIGS,
                                          bilinear_safe=not args.no_bilinear_safe,
                                          views=args.views or list(DEFAULT_VIEWS), size=args.size,
                                          depth=args.depth, max_iterations=args.max_iterations,
                                          shadow_light=args.shadows, progress=line, depth_name="--depth",
                                          distance=None if args.no_distance or reports else trade.DISTANCE_VIEWS))
        if reports[-1].dtype == reports[0].dtype and len(reports) > 1:  # a step map: bits do not apply
            reports.pop()
            break
    return reports
