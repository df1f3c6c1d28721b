"""The error-against-cost plot of :mod:`csm_assets.bench.trade` (``bench trade --plot``).

The only module that imports matplotlib, an optional extra: ``pip install 'csm-assets[plot]'``.
"""

from __future__ import annotations

import math

import numpy as np

from ..atomic import atomic_path
from .trade import TradeReport, views_text


def require_matplotlib():
    """matplotlib with the Agg backend; ValueError saying what to install when it is absent."""
    try:
        import matplotlib
    except ImportError as e:
        raise ValueError("--plot needs matplotlib: pip install 'csm-assets[plot]'") from e
    matplotlib.use("Agg")
    return matplotlib


def plot_trade(reports, path, title=None) -> None:
    """PNG of p95 error (log) against mean iterations, one curve per variant, written atomically.

    Args:
        reports (TradeReport | list[TradeReport]): one report, or several of one map (e.g.
            8/16/32 bits: the first solid, the others dashed and dotted).
        path (str | os.PathLike): the PNG.
        title (str | None): the plot's title (None: from the report).

    Raises:
        ValueError: matplotlib is not installed (the ``[plot]`` extra).
        OutputError: the file cannot be written.
    """
    matplotlib = require_matplotlib()
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    reports = [reports] if isinstance(reports, TradeReport) else list(reports)
    floor = 1e-3
    colors = {"exact": "#000000", "loop": "#1f77b4", "fixed": "#17becf", "parallax": "#d62728",
              "pom": "#ff7f0e", "relief": "#2ca02c", "exact_interp": "#9467bd", "quadrant": "#e377c2"}
    markers = {"exact": "*", "loop": "o", "fixed": "s", "parallax": "X", "pom": "^", "relief": "D",
               "exact_interp": "P", "quadrant": "v"}
    styles = ("-", "--", ":")
    fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=100)
    top, bottom = floor, math.inf
    for k, rep in enumerate(reports):
        for variant in dict.fromkeys(r.variant for r in rep.rows):
            rows = sorted((r for r in rep.rows if r.variant == variant), key=lambda r: r.mean_iterations)
            x = [max(r.mean_iterations, 0.5) for r in rows]
            y = [max(r.p95_error, floor) if math.isfinite(r.p95_error) else np.nan for r in rows]
            top = max([top, *(v for v in y if np.isfinite(v))])
            bottom = min([bottom, *(v for v in y if np.isfinite(v))])
            label = variant if k == 0 else None
            ax.plot(x, y, styles[k % 3], marker=markers.get(variant, "o"), color=colors.get(variant, "grey"),
                    label=label, ms=10 if variant in ("exact", "parallax") else 8 if variant == "loop" else 4,
                    lw=4.0 if variant == "loop" else 1.4, alpha=(0.45 if variant == "loop" else 1.0) * (1.0 if k == 0
                                                                                                  else 0.6),
                    zorder=2 if variant == "loop" else 3)
            if k == 0 and variant in ("loop", "pom", "relief"):
                for r, xi, yi in zip(rows, x, y):
                    if np.isfinite(yi) and r.steps in (1, 4, 16, 64):
                        ax.annotate(str(r.steps), (xi, yi), textcoords="offset points", xytext=(4, 4),
                                    fontsize=7, color=colors[variant])
    names = {"uint8": "8-bit map", "uint16": "16-bit map", "float32": "float map"}
    for k, rep in enumerate(reports if len(reports) > 1 else []):
        ax.plot([], [], styles[k % 3], color="grey", label=names.get(rep.dtype, rep.dtype))
    ax.axhline(1.0, color="grey", lw=0.8, ls="-.")
    ax.annotate("1 texel", (1.0, 1.0), xycoords=("axes fraction", "data"), xytext=(-40, 3),
                textcoords="offset points", fontsize=7, color="grey")
    ax.set_xscale("log", base=2)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_yscale("log")
    ax.set_ylim(max(min(bottom, 1.0) / 2, floor * 0.8), top * 2)
    ax.set_xlabel("cost: mean texture steps per pixel (log; loop and fixed coincide: same steps)")
    ax.set_ylabel("p95 error, worst view (texels, log)")
    r0 = reports[0]
    ax.set_title(title or f"{r0.source}: {r0.shape[1]}x{r0.shape[0]}, depth {r0.depth:g}, "
                          f"views {views_text(r0.views)}", fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=8, ncol=2, loc="upper right")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
