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

``python benchmarks/relaxed_trade.py --sweep [--plot PNG] [MAP ...]`` (default maps: the
real ones and the terrain) gives every family its best shot at the same error: the minimum
step (texels) is swept from 0.25 to 16 (above 1 only here: materials hold (0, 1]; a longer
step stops the cone steps sooner, the search of ``relaxed`` refines what ``exact`` only backs
off, and both skip more thin features), on bilinear-safe and paper (not safe) maps, for
``exact`` on conservative maps, ``relaxed`` 1 and 2 on relaxed maps, and ``relaxed`` 1 and 2
on conservative maps (what the search buys without relaxed cones), and ``relaxed`` 1 to 3 on
conservative maps whose every cone is widened 1.5, 2 and 4 times (unsafe: a bound on what
any wider cones could buy; not plotted). Per map: the fewest
fetches meeting 1 texel p95 in each family (with its setting and wrong-surface share), the
saving of the best relaxed-cone setting over the best ``exact`` one, and with ``--plot`` the
curves of fetches against p95 error. Fetches here are the shader's iterations (the first
fetch, at the entry point, which every variant makes, not counted); savings count it.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from csm_assets.bench import maps as bench_maps  # noqa: E402
from csm_assets.packing import SAFE_MIN_STEP, step_map  # noqa: E402
from csm_assets.bench.trade import measure_trade  # noqa: E402

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


SWEEP_STEPS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # minimum steps in texels


WIDEN = (1.5, 2.0, 4.0)  # factors of the unsafe widened-cone families


def widened(packed: np.ndarray, k: float) -> np.ndarray:
    """An 8-bit step map whose every cone ratio is ``k`` times its own (G scaled by sqrt(k),
    clipped): wider than any safe rule allows, to bound what wider cones could buy."""
    out = packed.copy()
    out[..., 1] = np.clip(np.round(packed[..., 1] * np.sqrt(k)), 0, 255).astype(np.uint8)
    return out


def sweep(h) -> list[dict]:
    """Every setting of the ``--sweep`` families on heights ``h``: dicts of family, safe,
    min_step, label, p95, fetches, wrong."""
    kw = dict(views=VIEWS, size=64, draws=1)
    out = []
    for safe in (True, False):
        cons = step_map(h, bits=8, bilinear_safe=safe)
        rel = step_map(h, bits=8, bilinear_safe=safe, cones="relaxed")
        search = [("relaxed", 1), ("relaxed", 2), ("relaxed", 3)]
        families = [("exact", cons, [("exact", 0)]), ("relaxed cones", rel, search[:2]),
                    ("relaxed on conservative", cons, search[:2])]
        families += [(f"conservative x{k:g} (unsafe)", widened(cons, k), search) for k in WIDEN]
        for w in SWEEP_STEPS:
            for family, packed, configs in families:
                for r in measure_trade(packed, configs=configs, min_step=w, **kw).rows:
                    out.append(dict(family=family, safe=safe, min_step=w, label=r.label,
                                    p95=round(r.p95_error, 3), fetches=round(r.mean_iterations, 2),
                                    wrong=round(r.wrong_share, 4)))
    return out


def cheapest(rows: list[dict], budget: float = 1.0) -> dict:
    """family -> the row with the fewest fetches whose p95 meets ``budget`` (absent if none)."""
    best = {}
    for r in rows:
        if r["p95"] <= budget and (r["family"] not in best or r["fetches"] < best[r["family"]]["fetches"]):
            best[r["family"]] = r
    return best


BUDGETS = (1.0, 0.5, 0.25)  # p95 errors (texels) the savings are read at


def saving(best: dict, family: str) -> str:
    """The share of total fetches (the shader's iterations plus the first fetch, which every
    variant makes) that ``family``'s cheapest setting saves over ``exact``'s."""
    e, f = best.get("exact"), best.get(family)
    if not e or not f:
        return "n/a"
    return f"{100 * (1 - (f['fetches'] + 1) / (e['fetches'] + 1)):.0f}%"


def plot_sweep(results: dict, path: str) -> None:
    """PNG: per map, fetches against p95 error (log), one curve per family, map kind and search."""
    from csm_assets.atomic import atomic_path
    from csm_assets.bench.trade_plot import require_matplotlib

    require_matplotlib()
    import matplotlib.pyplot as plt

    colors = {"exact": "#000000", "relaxed cones": "#d62728", "relaxed on conservative": "#1f77b4"}
    fig, axes = plt.subplots(1, len(results), figsize=(4.6 * len(results), 4.2), dpi=100, squeeze=False)
    for ax, (name, rows) in zip(axes[0], results.items()):
        for family in colors:
            for safe, style in ((True, "-"), (False, ":")):
                for label in dict.fromkeys(r["label"] for r in rows if r["family"] == family):
                    pts = sorted((r["fetches"], max(r["p95"], 1e-3)) for r in rows
                                 if r["family"] == family and r["safe"] == safe and r["label"] == label)
                    tag = f"{family} ({label.split()[-1]})" if family != "exact" else family
                    ax.plot(*zip(*pts), style, marker="o" if "2" not in label else "s", ms=3, lw=1.2,
                            color=colors[family], alpha=1.0 if "2" not in label else 0.55,
                            label=tag + ("" if safe else ", paper map") if ax is axes[0][0] else None)
        ax.axhline(1.0, color="grey", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("texture fetches per pixel (mean)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("p95 error of the worst view (texels)")
    fig.legend(loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle("minimum step swept 0.25..16 texels: fetches against error (dashed: 1 texel)", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 0.95))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def main_sweep(names, plot) -> int:
    every = maps()
    results = {}
    print("| map | `exact` | relaxed cones | `relaxed` on conservative cones | relaxed cones against `exact` |")
    print("|---|---|---|---|---|")
    for name in names or [k for k in every if k.endswith("_disp")] + ["terrain"]:
        rows = results[name] = sweep(every[name])
        best = cheapest(rows)
        cell = {f: (f"{r['fetches']:.2f} ({r['label']}, step {r['min_step']:g}, "
                    f"{'safe' if r['safe'] else 'paper'} map; p95 {r['p95']:.2f}, wrong {100 * r['wrong']:.2f}%)"
                    if (r := best.get(f)) else "none") for f in ("exact", "relaxed cones", "relaxed on conservative")}
        print(f"| {name} | {cell['exact']} | {cell['relaxed cones']} | {cell['relaxed on conservative']} | "
              f"{saving(best, 'relaxed cones')} |", flush=True)
    print("\n| map | budget (p95, texels) | relaxed cones against `exact` | `relaxed` on conservative cones "
          "against `exact` | conservative cones x1.5 / x2 / x4 (unsafe) against `exact` |\n|---|---|---|---|---|")
    for name, rows in results.items():
        for budget in BUDGETS:
            best = cheapest(rows, budget)
            widest = " / ".join(saving(best, f"conservative x{k:g} (unsafe)") for k in WIDEN)
            print(f"| {name} | {budget:g} | {saving(best, 'relaxed cones')} | "
                  f"{saving(best, 'relaxed on conservative')} | {widest} |")
    print(json.dumps(results))
    if plot:
        plot_sweep(results, plot)
    return 0


def main(argv=None) -> int:
    names = list(argv if argv is not None else sys.argv[1:])
    if "--sweep" in names:
        names.remove("--sweep")
        plot = None
        if "--plot" in names:
            k = names.index("--plot")
            plot = names[k + 1]
            del names[k:k + 2]
        return main_sweep(names, plot)
    every = maps()
    for name in names or list(every):
        t0 = time.perf_counter()
        res = measure(every[name])
        print(name, f"{time.perf_counter() - t0:.0f}s", json.dumps(res), flush=True)
        print(name, "at 1 texel p95 (exact, relaxed, saving):", gain(res), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
