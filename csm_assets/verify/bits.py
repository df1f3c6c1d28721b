"""The bit depth a step map needs: the fewest bits whose rounding of the heights ``verify`` cannot see.

An integer step map stores R, the height, rounded to ``2**bits - 1`` levels, while its cones
are exact for the heights before rounding. A ray then meets the stored surface up to half a
level away from where the cones lead it: about ``(0.5 / (2**bits - 1)) * depth * W * cot(elevation)``
texels on a flat patch, more where a grazing ray skims a ridge the rounding lowered and lands
behind it. For deep relief on a large texture at verify's grazing view (10 degrees) that is
over a texel at 8 bits, so verify FAILs the map; most maps (8-bit sources, shallow or small
ones) lose nothing at 8 bits.

:func:`rounding_error` measures it with the exact tracer: rays of each of verify's views
(:data:`~csm_assets.verify.views.DEFAULT_VIEWS`) are traced through the heights as rounded and
as given, and the p95 distance between the two hits in texels is the cost of those bits.
:func:`choose_bits` takes the fewest bits that cost at most :data:`BUDGET` (half of verify's
default 1-texel budget, leaving the other half to the shader's own error). Heights that are
already whole 8-bit (16-bit) codes cost nothing at 8 (16) bits and are not traced. G (the
cone) is rounded down, which never lets a ray through; only its one-step floor can, when a
cone is narrower than one step: ruled out by :func:`cone_floor_safe`. B and A (slopes) shade
and are not measured by verify.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..heightfield import tile_pair, unit_heights, whole_code_bits
from .trace import trace_heightfield
from .views import DEFAULT_VIEWS

BUDGET = 0.5  # texels: the most rounding may cost (p95 at any view), half of verify's default budget
RAYS = 64     # rays per side of the grid traced at each view (RAYS**2 rays)
STEP_BITS = (8, 16, 32)


@dataclass
class BitsChoice:
    """The bits a step map is made with and why.

    bits: 8, 16 or 32. given: True when the caller fixed them (``--bits``). reason: one line.
    errors: bits -> the p95 texel error their rounding costs at the worst view (0.0: the
    heights are whole codes at those bits, or float). depth: texture-space depth used;
    depth_texels: depth times the texture's longer side; elevation: the lowest view elevation.
    warning: set when given bits cost more than :data:`BUDGET` (verify may then fail).
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


def rounding_error(heights, bits: int, depth: float, *, views=DEFAULT_VIEWS, tile=True, rays: int = RAYS) -> float:
    """The p95 texel distance, at the worst of ``views`` ((elevation, azimuth) degrees), between
    the hits of the same rays on ``heights`` rounded to ``bits`` and on ``heights`` as given.

    heights: ``(H, W)`` uint8, uint16 or float in [0, 1]. depth: texture-space depth (uv units
    per unit of height, verify's ``--depth``). Rays start at height 1 from a jittered
    ``rays x rays`` grid over the map (seeded: the same answer every time) and go down at each
    view's angles, as verify's views of its quad do; a ray that hits one surface and misses the
    other counts as infinitely far, one that misses both is left out (as in verify). 32 bits (float)
    and whole codes cost 0.0.
    """
    if bits == 32 or whole_code_bits(heights) <= bits:
        return 0.0
    h = unit_heights(heights)
    top = (1 << bits) - 1
    rounded = np.rint(h * top) / top
    rows, cols = h.shape
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(rays), np.arange(rays)), -1).reshape(-1, 2)
    worst = 0.0
    for elevation, azimuth in views:
        uv = (grid + rng.random(grid.shape)) / rays
        origins = np.column_stack([uv, np.ones(len(uv))])
        e, a = math.radians(elevation), math.radians(azimuth)
        d = [math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e) / depth]
        dirs = np.tile(d, (len(uv), 1))
        got, _, hit_a = trace_heightfield(rounded, origins, dirs, tile=tile_pair(tile))
        want, _, hit_b = trace_heightfield(h, origins, dirs, tile=tile_pair(tile))
        both = hit_a & hit_b
        err = np.hypot((got - want)[both, 0] * cols, (got - want)[both, 1] * rows)
        err = np.concatenate([err, np.full(int((hit_a != hit_b).sum()), np.inf)])  # shared misses agree
        if err.size:
            worst = max(worst, float(np.percentile(err, 95, method="higher")))
    return worst


def cone_floor_safe(bits: int, shape, max_ratio: float) -> bool:
    """Whether no cone can fall under one ``bits`` step of G (stored one step wide, wider than
    exact): a cone ratio is at least one texel's uv over the whole height range, so
    ``max(H, W) * max_ratio <= (2**bits - 1)**2`` rules it out."""
    return bits == 32 or max(shape) * float(max_ratio) <= ((1 << bits) - 1) ** 2


def choose_bits(heights, depth: float, *, allowed=(8, 16), given: int | None = None, views=DEFAULT_VIEWS,
                tile=True, max_ratio: float = 1.0) -> BitsChoice:
    """The bits to make the step map of ``heights`` with, for verify at ``depth`` and ``views``.

    allowed: the bits the output can hold (a PNG 8 or 16; an EXR 32). given: bits the caller
    fixed: kept, with a warning when their rounding costs more than :data:`BUDGET`. Otherwise
    the fewest allowed bits costing at most :data:`BUDGET` whose G floor is safe, else the most
    allowed (with a warning).
    """
    h = np.asarray(heights)
    shape = h.shape
    elevation = min(float(el) for el, _ in views)
    depth_texels = float(depth) * max(shape)
    codes = whole_code_bits(h)
    errors: dict[int, float] = {}

    def cost(bits):
        if bits not in errors:
            errors[bits] = rounding_error(h, bits, depth, views=views, tile=tile)
        return errors[bits]

    def fits(bits):
        return cost(bits) <= BUDGET and cone_floor_safe(bits, shape, max_ratio)

    common = dict(depth=float(depth), depth_texels=depth_texels, elevation=elevation)
    if given is not None:
        choice = BitsChoice(given, True, "given", errors=errors, **common)
        if not fits(given):
            choice.warning = (f"{given}-bit heights {why_not(given, errors, shape, max_ratio, elevation)}: "
                              f"verify may fail there; {better(given, fits)}")
        return choice
    options = sorted(allowed)
    for bits in options:
        if fits(bits):
            return BitsChoice(bits, False, reason_for(bits, options, codes, errors, shape, max_ratio, elevation),
                              errors=errors, **common)
    bits = options[-1]
    return BitsChoice(bits, False, f"the most this output holds; {why_not(bits, errors, shape, max_ratio, elevation)}",
                      errors=errors, warning=f"{bits}-bit heights {why_not(bits, errors, shape, max_ratio, elevation)}: "
                                             "verify may fail there",
                      **common)


def why_not(bits, errors, shape, max_ratio, elevation) -> str:
    if not cone_floor_safe(bits, shape, max_ratio):
        return (f"cannot hold cones narrower than one step of G (a {max(shape)}-texel side at max_ratio "
                f"{max_ratio:g})")
    return (f"cost {errors[bits]:.2f} texels (p95) at verify's views down to {elevation:g} degrees, over "
            f"{BUDGET:g}")


def better(given, fits) -> str:
    for bits in STEP_BITS:
        if bits > given and fits(bits):
            return f"with --bits {bits} it would not" if bits < 32 else "with 32-bit float (.exr) it would not"
    return "no bit depth avoids it"


def reason_for(bits, options, codes, errors, shape, max_ratio, elevation) -> str:
    """One line: why ``bits`` (the first that fits) and not fewer."""
    if len(options) == 1:
        return "the only bits this output holds"
    if codes <= bits:
        why = f"the heights are whole {codes}-bit codes: {bits} bits hold them exactly"
    elif bits == 32:
        why = "float holds the heights exactly"
    else:
        why = (f"rounding to {bits} bits costs {errors[bits]:.2f} texels (p95) at verify's views down to "
               f"{elevation:g} degrees, within {BUDGET:g}")
    fewer = [b for b in options if b < bits]
    if fewer:
        why += f"; {fewer[-1]} bits " + why_not(fewer[-1], errors, shape, max_ratio, elevation)
    return why


def chooser(depth: float, *, views=DEFAULT_VIEWS, given: int | None = None, allowed=STEP_BITS, log=None):
    """A ``bits(heights, settings) -> int`` for :func:`csm_assets.map_file.load_step_maps`:
    :func:`choose_bits` at ``depth`` and ``views`` with the map's tiling and max ratio, each
    :class:`BitsChoice` appended to ``log`` (a list) when given."""

    def bits(heights, settings) -> int:
        choice = choose_bits(heights, depth, allowed=allowed, given=given, views=views, tile=settings.tile,
                             max_ratio=settings.max_ratio)
        if log is not None:
            log.append(choice)
        return choice.bits

    return bits
