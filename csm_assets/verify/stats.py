"""The numbers of a verification: per-pixel texel errors, their statistics, the text rows."""

from __future__ import annotations

import math

import numpy as np

from ..render.renderer import STATUS_CAP, STATUS_MISS


def pixel_errors(res, ref_uv, ref_hit, sel, shape) -> np.ndarray:
    """float64 ``(N,)``: texel distance of the render's hit from the reference's (inf where
    only one hits, NaN where not compared or both miss). shape: the map's (rows, cols)."""
    rows, cols = shape
    status = res.status.ravel()
    gpu_hit = sel & (status != STATUS_MISS)
    both = gpu_hit & ref_hit
    one = sel & (gpu_hit != ref_hit)
    err = np.full(status.shape, np.nan)
    diff = (res.hit_uv.reshape(-1, 2)[both] - ref_uv[both]) * [cols, rows]
    err[both] = np.hypot(diff[:, 0], diff[:, 1])
    err[one] = np.inf
    return err


def pixel_stats(err, status, iterations) -> dict:
    """The :class:`ViewStats` numbers over compared pixels (one view, or several pooled).

    err: float ``(N,)`` texels (inf: only one side hit; NaN: both missed, an agreement);
    status: int ``(N,)`` render status; iterations: int ``(N,)``."""
    err = np.asarray(err, np.float64)
    e = err[~np.isnan(err)]
    finite = err[np.isfinite(err)]
    n = int(err.size)
    return dict(
        pixels=n,
        mean_error=float(finite.mean()) if finite.size else 0.0,
        p95_error=float(np.percentile(e, 95, method="higher")) if e.size else 0.0,
        max_error=float(e.max()) if e.size else 0.0,
        wrong_share=float((e > 1.0).sum() / n) if n else 0.0,
        nonconverged_share=float((np.asarray(status) == STATUS_CAP).mean()) if n else 0.0,
        mean_iterations=float(np.mean(iterations)) if n else 0.0,
        max_iterations=int(np.max(iterations)) if n else 0,
        p99_iterations=float(np.percentile(iterations, 99, method="higher")) if n else 0.0,
    )


BLOCK = (8, 4)  # pixels (wide, high) that a GPU runs together: a warp of 32 waits for its slowest ray


def block_cost(iterations: np.ndarray, mask: np.ndarray, block=BLOCK) -> tuple[float, int]:
    """(sum over the 8x4 pixel blocks holding a pixel of ``mask`` of the block's largest
    iteration count among those pixels, number of such blocks); int ``(h, w)`` iterations,
    bool ``(h, w)`` mask. The mean (sum / blocks) is a GPU-like cost."""
    bw, bh = block
    h, w = iterations.shape
    H, W = -(-h // bh) * bh, -(-w // bw) * bw
    its = np.zeros((H, W), np.int64)
    its[:h, :w] = np.where(mask, iterations, 0)
    m = np.zeros((H, W), bool)
    m[:h, :w] = mask
    worst = its.reshape(H // bh, bh, W // bw, bw).max(axis=(1, 3))
    live = m.reshape(H // bh, bh, W // bw, bw).any(axis=(1, 3))
    return float(worst[live].sum()), int(live.sum())


def finite_or_none(x):
    """``x`` (nested dicts, lists, floats) with inf and NaN as None, for JSON."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_or_none(v) for v in x]
    return x


VIEW_COLUMNS = (f"{'elev':>5} {'azim':>5} {'pixels':>6} {'mean':>7} {'p95':>7} {'max':>7} {'wrong':>6} "
                f"{'nonconv':>7} {'iters':>6} {'max_it':>6}")


def view_line(s) -> str:
    """One row of the text table (after the variant columns)."""
    where = f"{s.camera[:11]:>11}" if s.camera else f"{s.elevation:5g} {s.azimuth:5g}"
    return (f"{where} {s.pixels:6d} {s.mean_error:7.3f} {s.p95_error:7.3f} {s.max_error:7.2f} "
            f"{100 * s.wrong_share:5.1f}% {100 * s.nonconverged_share:6.1f}% "
            f"{s.mean_iterations:6.1f} {s.max_iterations:6d}")


def steps_text(steps: int) -> str:
    """A variant's step count in a table: '-' for those that take none (exact, parallax: 0)."""
    return str(steps) if steps else "-"


def fit(text: str, width: int) -> str:
    """``text`` in at most ``width`` characters: long ones keep their start and, mostly, their
    end (where a primitive's and a material's names differ), '...' between."""
    if len(text) <= width:
        return text
    head = (width - 3) // 3
    return text[:head] + "..." + text[len(text) - (width - 3 - head):]


def format_report(report) -> str:
    """The report as a text table."""
    ty, tx = report.shape
    lines = [f"verify {report.source}: {tx}x{ty} {report.dtype}, tile {list(report.tile)}, max_ratio "
             f"{report.max_ratio:g}, depth {report.depth:g}, {report.size}x{report.size} px on "
             f"{report.renderer}",
             f"{'variant':8} {'steps':>5} {VIEW_COLUMNS}"]
    for v in report.variants:
        for s in v.views:
            lines.append(f"{v.variant:8} {steps_text(v.steps):>5} {view_line(s)}")
    verdict = "PASS" if report.passed else "FAIL"
    lines.append(f"{verdict}: worst p95 error " + ", ".join(
        f"{v.variant} {v.worst_p95:.3f}" for v in report.variants) + f" texels (budget {report.max_error:g})"
        + (f"; to fix: {report.fix}" if getattr(report, "fix", "") and not report.passed else ""))
    return "\n".join(lines)


