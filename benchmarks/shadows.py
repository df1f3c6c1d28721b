"""Self-shadows against exact shadows: the table of docs/measurements/accuracy.md and docs/shadows_*.png.

``python benchmarks/shadows.py [--maps bricks2_disp toy_box_disp terrain] [--size 128] [--json OUT]
[--image docs/shadows_bricks2.png [--image-size 256]]``

Per map (the real depth maps of ``../shared/data``, white = deep, at their own size, and
the procedural terrain of :mod:`csm_assets.bench.maps`), verify's six views and lights at
elevations 10..80 degrees x four azimuths, with the exact variant and the soft term at
light size 0.05 rad: :func:`csm_assets.verify.shadows.verify_shadows` against the exact
shadows. Prints a markdown table: the worst and mean disagreement of the hard answer
outside the edge band, the band's share, the soft term's mean and p95 error, and texture
fetches per relief pixel without shadows, with hard ones (light size 0: a second pass) and
with soft ones. The image: the map at one view
under three lights, the shader's colour (soft shadows) over the exact hard answer (white
lit, grey band, red disagreement).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from csm_assets.bench import maps as bench_maps  # noqa: E402
from csm_assets.verify import shadows as vs  # noqa: E402
from csm_assets.verify.maps import DEFAULT_VIEWS, load_packed, prepare, quad_view  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ELEVATIONS = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0)
AZIMUTHS = (0.0, 90.0, 200.0, 300.0)
IMAGE_VIEW = (50.0, 120.0)
IMAGE_LIGHTS = ((15.0, 0.0), (35.0, 200.0), (60.0, 300.0))


def load(name: str):
    """(packed step map, settings) of a named map, as convert makes them (8-bit, bilinear-safe)."""
    if name == "terrain":
        from csm_assets.stepmap import DEFAULTS, make_step_map

        sm = make_step_map(bench_maps.terrain(512).astype(np.float32) / 255.0, DEFAULTS)
        return sm.pixels, dict(max_ratio=sm.settings.max_ratio, tile=sm.settings.tile, min_step=sm.min_step)
    path = next(DATA.glob(name + ".*"))
    p, mr, tl, ms = load_packed(path, invert=True, as_step_map=False)
    return p, dict(max_ratio=mr, tile=tl, min_step=ms)


def summarize(name, report, hard, seconds) -> dict:
    v = report.views
    return dict(fetches_hard=float(np.mean([s.mean_fetches for s in hard.views])), map=name, draws=len(v), worst_disagreement=report.worst,
                mean_disagreement=float(np.mean([s.disagreement for s in v])),
                band_share=float(np.mean([s.band_share for s in v])),
                lit_share=float(np.mean([s.lit_share for s in v])),
                soft_mean_error=float(np.mean([s.soft_mean_error for s in v])),
                soft_p95_error=float(np.max([s.soft_p95_error for s in v])),
                fetches_without=float(np.mean([s.mean_fetches - s.mean_shadow_fetches for s in v])),
                fetches_with=float(np.mean([s.mean_fetches for s in v])),
                worst_case=max(v, key=lambda s: s.disagreement).__dict__, passed=report.passed, seconds=seconds)


def table(rows) -> str:
    lines = ["| map | draws | worst disagreement | mean | edge band | soft error mean / worst p95 | fetches/px "
             "without shadows | hard | soft |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['map']} | {r['draws']} | {100 * r['worst_disagreement']:.2f}% | "
                     f"{100 * r['mean_disagreement']:.2f}% | {100 * r['band_share']:.1f}% | "
                     f"{r['soft_mean_error']:.3f} / {r['soft_p95_error']:.3f} | {r['fetches_without']:.1f} | "
                     f"{r['fetches_hard']:.1f} | {r['fetches_with']:.1f} |")
    return "\n".join(lines)


def image(name: str, out: Path, size: int) -> None:
    """The figure: per light, the shader's colour beside the exact answer and the disagreement."""
    from PIL import Image

    from csm_assets.render.renderer import Renderer

    p, s = load(name)
    _, height, mat = prepare(p, s["max_ratio"], s["tile"], 0.1, s["min_step"])
    mat.light_size = vs.LIGHT_SIZE
    case = quad_view(height, *IMAGE_VIEW, mat.tile)
    rows = []
    with Renderer((size, size)) as r:
        for light in IMAGE_LIGHTS:
            px = {}
            res, _ = vs.measure_shadows(r, mat, case, *light, world_scale=(1, 1, 0.1),
                                        light_tex=vs.quad_light(vs.light_vector(*light), 0.1), pixels=px)
            colour = np.clip(res.color[..., :3] * 255 + 0.5, 0, 255).astype(np.uint8)
            exact = np.zeros(colour.shape, np.uint8)
            exact[px["exact"] == 1] = 255
            exact[px["band"].astype(bool)] = 128
            exact[px["disagree"].astype(bool)] = (255, 0, 0)
            rows.append(np.concatenate([colour, exact], axis=1))
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(rows, axis=0)).save(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", nargs="+", default=["bricks2_disp", "toy_box_disp", "terrain"])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--elevations", type=float, nargs="+", default=list(ELEVATIONS))
    ap.add_argument("--azimuths", type=float, nargs="+", default=list(AZIMUTHS))
    ap.add_argument("--json", metavar="OUT", help="write the summaries and per-draw numbers as JSON")
    ap.add_argument("--image", metavar="PNG", help="write the figure of the first map to PNG")
    ap.add_argument("--image-size", type=int, default=256, help="the figure's render size (default 256)")
    args = ap.parse_args(argv)
    lights = [(el, az) for el in args.elevations for az in args.azimuths]
    rows, reports = [], {}
    for name in args.maps:
        p, s = load(name)
        t = time.perf_counter()
        report = vs.verify_shadows(p, **s, views=DEFAULT_VIEWS, lights=lights, size=args.size, source=name)
        hard = vs.verify_shadows(p, **s, views=DEFAULT_VIEWS, lights=lights, size=args.size, source=name,
                                 light_size=0.0, soft_pixels=0)
        rows.append(summarize(name, report, hard, time.perf_counter() - t))
        reports[name] = report.to_dict()
        print(f"{name}: {rows[-1]['seconds']:.0f} s, worst {100 * report.worst:.2f}%", file=sys.stderr)
    print(table(rows))
    if args.json:
        Path(args.json).write_text(json.dumps(dict(summary=rows, reports=reports), indent=1))
    if args.image:
        image(args.maps[0], Path(args.image), args.image_size)
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
