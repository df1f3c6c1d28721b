"""Which shader variants draw which step maps: the rule verify, its scenes and its shadows share."""

from __future__ import annotations

from ..render.renderer import VARIANTS


def map_variants(cones: str, variants=None, material: str | None = None) -> list[str]:
    """The variants that draw a map of ``cones``.

    Args:
        cones: the map's cones: ``"conservative"``, ``"relaxed"`` or ``"quadrant"``.
        variants (list[str] | str | None): as given; None: the ``material``'s variant when it
            has one, else the map's own (``exact`` for conservative cones, ``relaxed`` for
            relaxed cones, ``quadrant`` for a quadrant map); ``"all"``: every variant that
            draws it (the map's own for relaxed and quadrant cones, else all but quadrant).
        material: a scene material's variant, or None.

    Returns:
        The variants, in order.

    Raises:
        ValueError: a variant that cannot draw the map (relaxed cones are drawn by the relaxed
            variant only, a quadrant map by the quadrant variant only, and the quadrant variant
            needs a quadrant map).
    """
    own = {"relaxed": "relaxed", "quadrant": "quadrant"}.get(cones)
    if variants == "all":
        return [own] if own else [v for v in VARIANTS if v != "quadrant"]
    if variants is None:
        return [material or own or "exact"]
    wrong = [v for v in variants if (v != own if own else v == "quadrant")]
    if wrong:
        what = (f"a map of {cones} cones is drawn by the {own} variant only" if own
                else "the quadrant variant draws quadrant maps (two images), and this map holds conservative cones")
        raise ValueError(f"{what}, not {', '.join(wrong)}")
    return list(variants)
