"""The cheapest setting of each variant within an error budget, and what quadrant cones save.

A row of :class:`~csm_assets.bench.trade.TradeReport` is *within* a budget of B texels when
the p95 error of its worst view is at most B and no view has more than :data:`WRONG_SURFACE`
of its pixels on a wrong surface (more than a texel off, or a hit where the tracer misses
and the reverse): a setting that skips thin walls must not win on p95 alone. ``bench trade``
prints, per budget of :data:`BUDGETS`, the cheapest row of each variant (by mean fetches,
then frame time) and how many fewer fetches, and how much lower a block cost (the mean over
8x4 pixel blocks of the block's largest count: a GPU warp waits for its slowest ray), the
quadrant variant needs than the ``exact`` variant.
"""

from __future__ import annotations

BUDGETS = (0.25, 1.0)
"""The budgets ``bench trade`` summarises, p95 texels: sub-texel and one texel."""
WRONG_SURFACE = 0.005
"""The largest wrong-surface share allowed at any view."""


def within(row, budget: float, wrong: float = WRONG_SURFACE) -> bool:
    """Whether ``row`` meets ``budget`` with at most ``wrong`` of the pixels on a wrong surface
    at every view.

    Args:
        row (TradeRow): a row of a TradeReport.
        budget: p95 texels of the worst view.
        wrong: the largest wrong-surface share allowed at any view.
    """
    return row.p95_error <= budget and all(v.wrong_share <= wrong for v in row.views)


def cheapest_by_variant(rows, budget: float, wrong: float = WRONG_SURFACE) -> dict:
    """Each variant's (on each cone kind) cheapest row within the budget, by mean fetches then
    frame time.

    Args:
        rows (list[TradeRow]): a TradeReport's rows.
        budget: p95 texels of the worst view.
        wrong: the largest wrong-surface share allowed at any view.

    Returns:
        ``{(variant, cones): row}``; variants with no row within the budget are left out.
    """
    best = {}
    for r in rows:
        key = (r.variant, r.cones)
        if within(r, budget, wrong) and (key not in best or (r.mean_iterations, r.frame_ms)
                                         < (best[key].mean_iterations, best[key].frame_ms)):
            best[key] = r
    return best


def quadrant_savings(rows, budget: float, wrong: float = WRONG_SURFACE) -> dict | None:
    """What the cheapest quadrant row within ``budget`` saves against the cheapest ``exact`` row
    (conservative cones).

    Args:
        rows (list[TradeRow]): a TradeReport's rows.
        budget: p95 texels of the worst view.
        wrong: the largest wrong-surface share allowed at any view.

    Returns:
        ``{"fetches": share, "block": share, "exact": row, "quadrant": row}`` (shares of
        exact's mean fetches and block cost; negative: quadrant costs more), or None when
        either has no row within the budget.
    """
    best = cheapest_by_variant(rows, budget, wrong)
    exact, quadrant = best.get(("exact", "conservative")), best.get(("quadrant", "quadrant"))
    if exact is None or quadrant is None:
        return None
    return {"fetches": 1 - quadrant.mean_iterations / exact.mean_iterations,
            "block": 1 - quadrant.block_cost / max(exact.block_cost, 1e-12), "exact": exact, "quadrant": quadrant}


def budget_lines(rows, budgets=BUDGETS, wrong: float = WRONG_SURFACE) -> list[str]:
    """The summary ``bench trade`` prints under its table.

    Args:
        rows (list[TradeRow]): a TradeReport's rows.
        budgets: p95 texels.
        wrong: the largest wrong-surface share allowed at any view.

    Returns:
        Lines: per budget, each variant's cheapest row within it (label, min step, mean
        fetches, p99, block cost) and the quadrant saving.
    """
    lines = []
    for b in budgets:
        best = cheapest_by_variant(rows, b, wrong)
        lines.append(f"cheapest within p95 <= {b:g} texel and <= {100 * wrong:g}% wrong surface at every view:")
        if not best:
            lines.append("  none")
        for r in sorted(best.values(), key=lambda r: r.mean_iterations):
            lines.append(f"  {r.label:24} min_step {r.min_step_text:6} fetches {r.mean_iterations:6.2f}  "
                         f"p99 {r.p99_iterations:4.0f}  block {r.block_cost:6.2f}")
        saved = quadrant_savings(rows, b, wrong)
        if saved is not None:
            lines.append(f"  quadrant against exact: {100 * saved['fetches']:.0f}% fewer fetches, "
                         f"{100 * saved['block']:.0f}% lower block cost")
    return lines


def budget_summary(rows, budgets=BUDGETS, wrong: float = WRONG_SURFACE) -> list[dict]:
    """:func:`budget_lines` as plain data for JSON.

    Args:
        rows (list[TradeRow]): a TradeReport's rows.
        budgets: p95 texels.
        wrong: the largest wrong-surface share allowed at any view.

    Returns:
        Per budget, the cheapest rows' (variant, cones, steps, min_step, fetches, p99, block)
        and the quadrant savings (or None).
    """
    out = []
    for b in budgets:
        best = cheapest_by_variant(rows, b, wrong)
        saved = quadrant_savings(rows, b, wrong)
        out.append({"budget": b, "wrong_surface": wrong,
                    "cheapest": [{"variant": r.variant, "cones": r.cones, "steps": r.steps, "min_step": r.min_step,
                                  "mean_iterations": r.mean_iterations, "p99_iterations": r.p99_iterations,
                                  "block_cost": r.block_cost, "p95_error": r.p95_error}
                                 for r in sorted(best.values(), key=lambda r: r.mean_iterations)],
                    "quadrant_saves": None if saved is None else {"fetches": saved["fetches"],
                                                                  "block_cost": saved["block"]}})
    return out
