"""What would fix a failed verification: one line for the FAIL verdict (``report.fix``).

The causes are told apart by what the report and the map say, most specific first: an
8-bit map, whose samples verify's renderer rounds to 8 bits, where that rounding can move a
hit by a tenth of a texel at the views drawn (:func:`rounding_bound`; see
:mod:`csm_assets.verify.bits`); a cap on iterations; too few
steps of a stepped variant; a map that is not bilinear-safe drawn with the paper's 1-texel
step; else relief too deep for the texture at grazing views. More bits are advised only where
:func:`csm_assets.verify.bits.choose_bits` would take them for the map (:func:`stored_choice`):
where no bit depth passes, the fix line says what ``stepmap`` says (CSM304), not "16 bits".
"""

from __future__ import annotations

import math

import numpy as np

from ..packing import SAFE_MIN_STEP
from .bits import choose_bits, rounding_bound
from .maps import STEPPED

SUSPECT = 0.1  # texels: rounding that can move a hit this far is a suspect when a view fails
NONCONVERGED = 0.05  # a failing view with this share of pixels stopped by the cap: the cap is a cause


def bits_suspect(variants, max_error: float, bound: float) -> bool:
    """Whether 8-bit samples may be why ``variants`` (VariantReports) failed: their rounding can
    move a hit :data:`SUSPECT` texels and the exact variant failed (its own error is small),
    or it can move one half the budget (a stepped variant's misses are then not all its own)."""
    failed = [v for v in variants if v.worst_p95 > max_error]
    return bound >= SUSPECT and (any(v.variant == "exact" for v in failed) or bound >= max_error / 2)


def stored_choice(packed, second, settings, depth: float, views, min_step: float):
    """:func:`~csm_assets.verify.bits.choose_bits` for a stored 8-bit map ``packed`` (``(H, W, 4)``;
    ``second``: a quadrant map's second image, or None): its own samples at 8 bits, the same
    heights and cones in 16-bit samples at 16, at ``depth`` and ``views`` as verify drew them."""
    from ..stepmap import conservative_view

    p = np.asarray(packed) if second is None else conservative_view(np.concatenate([packed, second], axis=-1))
    return choose_bits(lambda bits: p if bits == 8 else p.astype(np.uint16) * 257, depth, views=views,
                       tile=settings.tile, max_ratio=settings.max_ratio, min_step=min_step)


def bits_fix(choice) -> str:
    """The fix line's part for a map that no bit depth lets pass (``choice`` keeps 8 bits): what
    ``stepmap`` warns (CSM304), '' when the choice raises no warning."""
    return f"{choice.warning} (CSM304): a smaller --depth, or a larger --max-error" if choice.warning else ""


def map_fix(report, settings, min_step: float, *, given_bits: bool, made_here: bool, choice_of=None) -> str:
    """The fix line of a failed :class:`~csm_assets.verify.maps.VerifyReport` of one map, whose
    :class:`~csm_assets.stepmap.StepMapSettings` are ``settings``, drawn with ``min_step`` texels;
    ``made_here``: verify made it from a height map (``given_bits``: with ``--bits``). choice_of:
    ``choice_of()`` -> the :class:`~csm_assets.verify.bits.BitsChoice` for the map (asked only where
    more bits may be the fix: they are advised only where it takes more than 8). '' when it passed."""
    if report.passed:
        return ""
    fixes = []
    elevation = min((s.elevation for v in report.variants for s in v.views), default=90.0)
    bound = rounding_bound(settings.bits, report.depth * max(report.shape), elevation)
    if settings.bits == 8 and bits_suspect(report.variants, report.max_error, bound):
        more = 16
        choice = choice_of() if choice_of is not None else None
        if choice is not None and choice.bits == 8:
            fixes.append(bits_fix(choice))
        elif made_here and given_bits:
            fixes.append(f"--bits {more}, or leave --bits out to have them chosen (its {settings.bits}-bit heights "
                         f"move hits up to {bound:.2f} texels on flat patches at {elevation:g} degrees)")
        elif not made_here:
            fixes.append(f"make the step map again at {more} bits from its height map (stepmap or convert "
                         f"--bits {more}; left out, they choose it for this relief): its {settings.bits}-bit heights "
                         f"move hits up to {bound:.2f} texels on flat patches at {elevation:g} degrees")
    fixes = [f for f in fixes if f] + shader_fixes(report.variants, report.max_error, min_step, settings.bilinear_safe)
    if not fixes:
        fixes.append("the relief is too deep for this texture at grazing views: a smaller --depth, or a larger "
                     "--max-error")
    return "; or ".join(fixes)


def shader_fixes(variants, max_error: float, min_step: float, bilinear_safe: bool) -> list[str]:
    """Fixes on the shader's side for the failing views of ``variants`` (VariantReports)."""
    fixes = []
    bad = [(v, s) for v in variants for s in v.views if s.p95_error > max_error]
    if any(s.nonconverged_share >= NONCONVERGED for _, s in bad):
        fixes.append("a larger --max-iterations (pixels stopped by the cap)")
    stepped = sorted({v.variant for v, _ in bad if v.variant in STEPPED or v.variant == "relaxed"})
    if stepped:
        fixes.append(f"more --steps for {', '.join(stepped)} (up to 127), or --variant exact")
    if any(v.variant == "exact" for v, _ in bad) and min_step > SAFE_MIN_STEP:
        fixes.append(f"--min-step {SAFE_MIN_STEP:g}" + ("" if bilinear_safe else " with a bilinear-safe map (made "
                                                                                 "without --no-bilinear-safe)"))
    return fixes


def scene_fix(report, settings_of, choice_of=None) -> str:
    """The fix line of a failed :class:`~csm_assets.verify.scene.SceneReport`: ``settings_of(name)``
    gives the StepMapSettings of a step map by its name (None when unknown); ``choice_of(p)``, the
    BitsChoice of a primitive report's map (see :func:`map_fix`; None: more bits are advised)."""
    if report.passed:
        return ""
    fixes, lacking, drawn_failing = [], [], False
    for p in report.primitives:
        if p.problem:  # not drawn: what it lacks (uv area, normals...), not a smaller depth
            lacking.append(f"{p.name} (material {p.material!r}): {p.problem}")
            continue
        if p.passed(report.max_error):
            continue
        drawn_failing = True
        settings = settings_of(p.step_map)
        bits = {"uint8": 8, "uint16": 16}.get(p.dtype, 32)
        elevation = min((s.elevation for v in p.variants for s in v.views if not math.isnan(s.elevation)),
                        default=10.0)
        bound = rounding_bound(bits, p.depth_scale * max(p.shape), elevation)
        suspect = bits == 8 and bits_suspect(p.variants, report.max_error, bound)
        choice = choice_of(p) if suspect and choice_of is not None else None
        if choice is not None and choice.bits == 8:
            fixes.append(bits_fix(choice))
        elif suspect:
            fixes.append(f"convert again with --bits 16 (material {p.material!r}: its {bits}-bit heights move "
                         f"hits up to {bound:.2f} texels on flat patches at {elevation:g} degrees)")
        bilinear = settings.bilinear_safe if settings is not None else True
        fixes += shader_fixes(p.variants, report.max_error, p.min_step, bilinear)
    fixes = list(dict.fromkeys(f for f in fixes if f))
    if not fixes and (drawn_failing or not lacking):
        fixes.append("the relief is too deep for its textures at grazing views: a smaller depth (convert "
                     "--depth), or a larger --max-error")
    return "; ".join(lacking + (["; or ".join(fixes)] if fixes else []))
