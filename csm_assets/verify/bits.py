"""The bit depth a step map needs: the fewest bits whose cost ``verify`` cannot see.

verify's renderer (Mesa llvmpipe) returns a bilinear sample of an 8-bit texture at 8-bit
precision: between texel centres the height the shader sees is rounded to the nearest of 256
levels, a terraced surface, while verify's reference is the smooth bilinear one. On a flat
patch seen at ``elevation`` that moves a hit by up to ``(0.5 / 255) * depth * W * cot(elevation)``
texels (:func:`rounding_bound`), whatever bits the source had: for
deep relief on a large texture at verify's grazing view (10 degrees) over a texel, so verify
FAILs the map. Steep relief hides the terraces, so most maps lose nothing at 8 bits. 16-bit
textures are filtered in float.

:func:`choose_bits` measures it: it packs the map at each candidate depth and marches the rays
of verify's views on the CPU as the exact variant does, 8-bit samples filtered in fixed point as
the renderer filters them (:func:`csm_assets.verify.march.quad_error`). It keeps the fewest bits whose p95
error is within :data:`BUDGET` (half of verify's default budget, the other half left to the
spread between this estimate and verify's pixels), or whose error exceeds the next depth's
by no more than :data:`BUDGET`, or when the next depth would not pass verify either (the rest
is the shader's own error, which more bits do not cure). A depth that stores some cones wider
than exact (CSM301: narrower than one step, as on a 65536x1 map at 8 bits) is never kept when
the next one stores them exactly.

A relief too deep or too shallow for anything to be measured on its texture
(:func:`csm_assets.depth.measurable`: only a library caller or a huge texture at ``stepmap``'s
fixed depth gets here; the commands refuse such depths up front) is not marched: its errors
are the rounding bound on a flat patch (:func:`rounding_bound`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field

from ..depth import depth_texels, measurable
from ..warning_codes import NarrowCones
from .march import quad_error
from .views import DEFAULT_VIEWS

BUDGET = 0.5  # texels: the most the bits may cost (p95 at any view), half of verify's default budget
STEP_BITS = (8, 16, 32)


def rounding_bound(bits: int, depth_texels: float, elevation: float) -> float:
    """How far (texels) half a level of ``bits`` moves a hit on a flat patch seen at ``elevation``
    degrees with relief ``depth_texels`` deep: ``(0.5 / (2**bits - 1)) * depth_texels * cot(elevation)``."""
    if bits >= 32:
        return 0.0
    return 0.5 / ((1 << bits) - 1) * depth_texels / math.tan(math.radians(max(elevation, 1e-3)))


@dataclass
class BitsChoice:
    """The bits a step map is made with and why.

    bits: 8, 16 or 32. given: True when the caller fixed them (``--bits``). reason: one line.
    errors: bits -> the p95 texel error foreseen at the worst of verify's views (those
    measured). depth: the texture-space depth used; depth_texels: depth times the texture's
    longer side; elevation: the lowest view elevation. warning: set when given bits cost more
    than :data:`BUDGET` over more bits (verify may then fail), or when no bits hold the budget.
    """

    bits: int
    given: bool
    reason: str
    depth: float
    depth_texels: float
    elevation: float
    errors: dict = field(default_factory=dict)
    warning: str = ""

    def to_dict(self) -> dict:
        d = asdict(self)
        d["errors"] = {str(k): round(v, 4) for k, v in self.errors.items()}
        return d


def choose_bits(pack, depth: float, *, allowed=(8, 16), given: int | None = None, views=DEFAULT_VIEWS,
                tile=True, max_ratio: float = 1.0, min_step: float = 1.0) -> BitsChoice:
    """The bits to make a step map with, for verify at ``depth`` (uv units per unit of height,
    verify's ``--depth``) and ``views``.

    pack: ``pack(bits)`` -> the packed ``(H, W, 4)`` map at those bits (cones already made).
    allowed: the bits the output can hold (a PNG 8 and 16, an EXR 32). given: bits fixed by the
    caller, kept, with a warning when they cost more than :data:`BUDGET` over the next depth.
    tile, max_ratio, min_step: the map's, as the exact variant draws it.
    """
    elevation = min(float(el) for el, _ in views)
    errors: dict[int, float] = {}
    narrow: dict[int, bool] = {}  # bits -> some cones stored wider than exact (CSM301)
    shape = []

    def cost(bits):
        if bits not in errors:
            with warnings.catch_warnings(record=True) as caught:  # the map made at the bits chosen says it
                warnings.simplefilter("always", NarrowCones)
                p = pack(bits)
            narrow[bits] = any(issubclass(w.category, NarrowCones) for w in caught)
            for w in caught:
                if not issubclass(w.category, NarrowCones):
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            shape[:] = p.shape[:2]
            if measurable(depth, shape):
                errors[bits] = quad_error(p, depth, views=views, max_ratio=max_ratio, tile=tile, min_step=min_step)
            else:  # nothing to march: the bound of flat patches
                errors[bits] = rounding_bound(bits, depth_texels(depth, shape), elevation)
        return errors[bits]

    def wider(bits):
        """Whether the map at ``bits`` stores some cones wider than exact (CSM301)."""
        cost(bits)
        return narrow[bits]

    def enough(bits, more):
        """bits store every cone exactly or more bits would not either, and hold the budget, or more
        bits would not lower their error by the budget, or would not bring it within verify's
        (2 x BUDGET): then the relief, not the bits, is what fails."""
        if wider(bits) and not wider(more):
            return False
        return cost(bits) <= BUDGET or cost(bits) - cost(more) <= BUDGET or cost(more) > 2 * BUDGET

    options = sorted(allowed)
    if given is not None:
        options = [given]
    chosen = options[0]
    for more in options[1:]:
        if enough(chosen, more):
            break
        chosen = more
    cost(chosen)
    common = dict(errors=errors, depth=float(depth), depth_texels=float(depth) * max(shape), elevation=elevation)
    if given is not None:
        more = next((b for b in STEP_BITS if b > given), None)
        choice = BitsChoice(given, True, "given", **common)
        if cost(given) > BUDGET and more is not None and not enough(given, more):
            choice.warning = (f"{given}-bit maps cost {cost(given) - cost(more):.2f} texels (p95) over {more}-bit "
                              f"ones at verify's views down to {elevation:g} degrees (its renderer samples 8-bit "
                              f"textures at 8-bit precision): verify may fail there; with --bits {more} it would not")
        return choice
    reason = reason_for(chosen, options, errors, elevation)
    fewer = [b for b in options if b < chosen]
    if fewer and narrow.get(fewer[-1]) and not wider(chosen):
        reason = (f"{fewer[-1]}-bit maps store some cones wider than exact (narrower than one step of "
                  f"max_ratio {max_ratio:g}, CSM301); {chosen} bits store them exactly")
    choice = BitsChoice(chosen, False, reason, **common)
    if not measurable(depth, shape):
        choice.reason = (f"the relief is {common['depth_texels']:.3g} texels deep, too "
                         f"{'deep' if common['depth_texels'] > 1 else 'shallow'} to measure (2^-24 to 2^24 texels): "
                         f"{choice.reason} on a flat patch")
    if cost(chosen) > 2 * BUDGET and len(options) == 1 and chosen == 8:
        choice.warning = (f"8-bit maps cost {cost(chosen):.2f} texels (p95) at verify's views down to {elevation:g} "
                          "degrees: verify may fail there; this output holds 8 bits only (a .png holds 16)")
    elif cost(chosen) > 2 * BUDGET:
        choice.warning = (f"no bit depth keeps the exact variant within verify's budget at its views down to "
                          f"{elevation:g} degrees ({cost(chosen):.2f} texels p95 at {chosen} bits): the relief is "
                          "deep for this texture there")
    return choice


def reason_for(bits, options, errors, elevation) -> str:
    """One line: why ``bits`` and not fewer or more."""
    if len(options) == 1:
        return "the only bits this output holds"
    where = f"at verify's views down to {elevation:g} degrees"
    fewer = [b for b in options if b < bits]
    if not fewer:
        if errors[bits] <= BUDGET:
            return f"{bits}-bit maps cost {errors[bits]:.2f} texels (p95) {where}, within {BUDGET:g}"
        more = next(b for b in options if b > bits)
        if errors[more] > 2 * BUDGET:
            return (f"{more} bits would not bring the error {where} within verify's budget either "
                    f"({errors[bits]:.2f} texels p95 at {bits} bits, {errors[more]:.2f} at {more})")
        return (f"{more} bits would lower the error {where} by {errors[bits] - errors[more]:.2f} texels only "
                f"({errors[bits]:.2f} at {bits} bits)")
    less = fewer[-1]
    return (f"{less}-bit maps cost {errors[less] - errors[bits]:.2f} texels (p95) more {where}: verify's "
            f"renderer samples 8-bit textures at 8-bit precision, which terraces deep relief")


def chooser(depth: float, *, views=DEFAULT_VIEWS, given: int | None = None, allowed=STEP_BITS, log=None):
    """A ``choose(pack, settings) -> BitsChoice`` for :func:`csm_assets.stepmap.make_step_maps`:
    :func:`choose_bits` at ``depth`` and ``views`` with the map's settings (tiling, max ratio,
    minimum step); each choice is also appended to ``log`` (a list) when given."""

    def choose(pack, settings) -> BitsChoice:
        choice = choose_bits(pack, depth, allowed=allowed, given=given, views=views, tile=settings.tile,
                             max_ratio=settings.max_ratio, min_step=settings.min_step)
        if log is not None:
            log.append(choice)
        return choice

    return choose
