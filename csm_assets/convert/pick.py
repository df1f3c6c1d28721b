"""``convert --max-error E``: keep only picks that ``verify --max-error E`` then passes.

The quick pick (:func:`csm_assets.bench.trade.pick_settings`: a quad, 4 views, 48 px) ranks the
settings; this module confirms the chosen one on the scene itself with verify's own
measure, views and size (:func:`csm_assets.verify.scene.verify_primitives` at
:data:`csm_assets.verify.maps.DEFAULT_VIEWS`, the scene's cameras, 128 px: what ``verify``
does by default), at a slightly tighter budget (:data:`MARGIN`) so the written file's
float32 tangents cannot tip it over. When the pick fails there, the next settings in
order of cost are tried; when none passes with an 8-bit map, the map is made again at
16 bits and the search repeats, and the report says so.
"""

from __future__ import annotations

import math

from ..errors import OptionError
from ..formats.csm_material import StoredCsm
from ..scene import Texture

MARGIN = 0.95        # confirm at MARGIN * E
MAX_TRIES = 8        # settings confirmed per bit depth before giving up on it
# the minimum steps (texels) the pick measures the quadrant variant at, besides the map's own; a material
# holds (0, 1]. The quadrant variant measures its step across the texture (docs/reference/quadrant-cones.md)
QUADRANT_MIN_STEPS = (0.125, 0.25, 0.5, 1.0)


def pick(sm, name: str, depth: float, opts) -> tuple[str, int, float | None]:
    """The (variant, steps, minimum step) a material with :class:`~csm_assets.stepmap.StepMap` ``sm``
    gets: as given, or the cheapest meeting ``max_error`` on the quad (the most accurate when none
    does); :func:`confirm_picks` then checks it on the scene. The minimum step is None (the map's
    own, :attr:`~csm_assets.stepmap.StepMapSettings.min_step`) but for a quadrant map, whose
    variant is also measured at :data:`QUADRANT_MIN_STEPS`."""
    variant = checked_variant(opts)
    if opts.max_error is None or (variant != "auto" and opts.steps > 0):
        if variant == "auto":
            raise OptionError("variant 'auto' needs max_error (the budget it picks by)")
        from ..verify.maps import default_steps

        return variant, opts.steps or default_steps(variant), None
    configs = measured_configs(opts, variant)
    if not configs:
        raise OptionError(f"no measured setting has variant {variant!r} and steps {opts.steps}")
    if len(configs) == 1 and len(min_steps(sm.settings.cones, sm.min_step)) == 1:
        return (*configs[0], None)
    s = sm.settings
    return ranked_settings(sm.pixels, s.max_ratio, s.tile, depth, s.min_step, s.cones, opts, configs,
                           second=sm.second, source=name)[0]


def min_steps(cones: str, own: float) -> list[float | None]:
    """The minimum steps the pick measures a map of ``cones`` at: None (the map's ``own``) first,
    then for quadrant maps the other :data:`QUADRANT_MIN_STEPS`."""
    return [None, *(w for w in QUADRANT_MIN_STEPS if w != own and cones == "quadrant")]


ONLY_VARIANT = {"relaxed": "relaxed", "quadrant": "quadrant"}  # cones -> the one variant that draws them


def default_variant(max_error, cones: str = "conservative") -> str:
    """The variant when none is named (``--variant`` left out): "auto" with a ``max_error``
    budget (it picks), "relaxed" for relaxed cones and "quadrant" for quadrant cones (the only
    variants that draw them), else "exact"."""
    return "auto" if max_error is not None else ONLY_VARIANT.get(cones, "exact")


def checked_variant(opts) -> str:
    """``opts.variant`` ("auto" when None); OptionError for a variant that cannot draw the
    cones ``opts.cones`` makes (relaxed cones: only the relaxed variant; quadrant cones, two
    images: only the quadrant variant, which draws nothing else)."""
    variant = opts.variant or "auto"
    cones = getattr(opts, "cones", "conservative")
    only = ONLY_VARIANT.get(cones)
    if only == "relaxed" and variant not in ("auto", "relaxed"):
        raise OptionError(f"relaxed cones are drawn only by the relaxed variant, not {variant!r} "
                          "(rays would pass through the surface): use variant 'relaxed'")
    if only == "quadrant" and variant not in ("auto", "quadrant"):
        raise OptionError(f"quadrant cones are drawn only by the quadrant variant, not {variant!r} "
                          "(it reads the map's two images): use variant 'quadrant'")
    if only is None and variant == "quadrant":
        raise OptionError(f"the quadrant variant draws only quadrant cones, not {cones} cones "
                          "(it reads a second image): use cones 'quadrant'")
    return variant


def measured_configs(opts, variant) -> list[tuple[str, int]]:
    """The measured settings of ``variant`` ("auto": all) and ``opts.steps`` (0: all) that
    can draw the maps ``opts.cones`` makes: every one for conservative cones (the relaxed
    variant included), the relaxed variant's for relaxed cones, the quadrant variant's for
    quadrant cones."""
    from ..bench.trade import DEFAULT_CONFIGS, QUADRANT_CONFIGS

    cones = getattr(opts, "cones", "conservative")
    if cones == "quadrant":
        return [(v, n) for v, n in QUADRANT_CONFIGS if variant in ("auto", v) and opts.steps in (0, n)]
    relaxed = cones == "relaxed"
    return [(v, n) for v, n in DEFAULT_CONFIGS if variant in ("auto", v) and opts.steps in (0, n)
            and (v == "relaxed" or not relaxed)]


def shadow_light(opts):
    """The light the pick draws self-shadows with (their steps count in the cost) when the
    materials are converted with self-shadowing (``opts.self_shadow``), else None."""
    from ..verify.shadows import PICK_LIGHT

    return PICK_LIGHT if getattr(opts, "self_shadow", False) else None


def pick_configs(opts) -> list[tuple[str, int]] | None:
    """The settings ``--max-error`` picks among, or None when nothing is picked (a quadrant map's one
    variant is picked among minimum steps: :func:`min_steps`)."""
    variant = checked_variant(opts)
    if opts.max_error is None or (variant != "auto" and opts.steps > 0):
        return None
    configs = measured_configs(opts, variant)
    return configs if len(configs) > 1 or (configs and getattr(opts, "cones", "") == "quadrant") else None


def scene_cameras(scene):
    """The scene's own cameras and mesh world matrices, as verify finds them."""
    from ..verify.views import gltf_cameras, usd_cameras

    if scene.format in ("gltf", "glb"):
        return gltf_cameras(scene.source)
    if scene.format in ("usda", "usdc", "usdz", "usd"):
        return usd_cameras(scene.source)
    return [], {}


def stored_of(mat) -> StoredCsm:
    c = mat.csm
    second = None if c.step_map2 is None else Texture(c.step_map2.stem, path=c.step_map2)
    return StoredCsm(mat.name, Texture(c.step_map.stem, path=c.step_map), c.depth_scale, c.max_ratio,
                     tuple(c.tile), c.variant, c.steps, c.min_step, mat.height.tex_coord, step_map2=second)


def candidates(path, mat, opts, configs) -> list[tuple[str, int, float | None]]:
    """:func:`ranked_settings` of a scene material's step map (in memory, else read from ``path``)."""
    from ..formats import read_step_map

    c = mat.csm
    pixels = c.map.pixels if c.map is not None else read_step_map(path)
    second = None if c.step_map2 is None else c.map.second if c.map is not None else read_step_map(c.step_map2)
    return ranked_settings(pixels, c.max_ratio, c.tile, c.depth_scale, c.settings.min_step, c.settings.cones, opts,
                           configs, second=second)


def ranked_settings(pixels, max_ratio, tile, depth, min_step, cones, opts, configs, *, second=None,
                    source="<array>") -> list[tuple[str, int, float | None]]:
    """Settings (variant, steps, minimum step: None for the map's ``min_step``, see :func:`min_steps`)
    in the order to try for a step map (packed ``pixels``, a quadrant map's ``second`` image, its max
    ratio, tiling, min step and cones) at texture-space ``depth``: those meeting ``opts.max_error``
    on the quad by cost (``opts.pick_cost``: mean fetches or the block cost), then the rest by error
    (at most :data:`MAX_TRIES`)."""
    from ..bench.trade import pick_settings

    rows = []
    for w in min_steps(cones, min_step):
        _, _, report = pick_settings(pixels, opts.max_error, configs=configs, max_ratio=max_ratio, tile=tile,
                                     depth=max(depth, 1e-6), min_step=w or min_step, cones=cones, second=second,
                                     shadow_light=shadow_light(opts), source=source)
        rows += [(r, w) for r in report.rows]
    block = getattr(opts, "pick_cost", "fetches") == "block"  # the GPU-like cost, else mean fetches
    ok = sorted((x for x in rows if x[0].p95_error <= opts.max_error),
                key=lambda x: (x[0].block_cost if block else x[0].mean_iterations, x[0].frame_ms))
    rest = sorted((x for x in rows if x[0].p95_error > opts.max_error),
                  key=lambda x: (x[0].p95_error if math.isfinite(x[0].p95_error) else math.inf, x[0].mean_iterations))
    return [(r.variant, r.steps, w) for r, w in ok + rest][:MAX_TRIES]


def confirm_choice(first, bits: int, passes, ranked, remake=None) -> tuple[tuple[str, int] | None, bool]:
    """The search that confirms one material's pick: ``first`` (variant, steps) when
    ``passes(variant, steps)``, else the first of ``ranked()`` that passes; when none does with an
    8-bit map and ``remake`` is given, ``remake(16)`` makes the map again at 16 bits and the search
    repeats. Returns (the settings found or None, whether the map was made again)."""
    if passes(*first):
        return first, False
    bits_options = [bits] + ([16] if bits == 8 and remake is not None else [])
    for b in bits_options:
        if b != bits:
            remake(b)
        found = next((c for c in ranked() if (b != bits or c != first) and passes(*c)), None)
        if found:
            return found, b != bits
    return None, len(bits_options) > 1


def confirm_picks(scene, opts, configs_of, remake_map, *, generate_tangents: bool, progress=None) -> list:
    """Confirm each picked material on its own primitives; returns the step map paths made anew;
    ``progress("confirm", done, total)`` by material.

    configs_of(mat): the (variant, steps) settings the pick may choose for ``mat`` (None when it
    was not picked); remake_map(mat, bits): makes a step map at ``bits``, points ``mat.csm`` at it, returns its path."""
    from ..render.renderer import Renderer
    from ..verify.maps import DEFAULT_VIEWS, RENDER_SIZE
    from ..verify.scene import primitives, verify_primitives

    cams, models = scene_cameras(scene)
    made, maps = [], {}
    with Renderer((RENDER_SIZE, RENDER_SIZE)) as r:
        for done, mat in enumerate(scene.materials):
            if progress:
                progress("confirm", done, len(scene.materials))
            configs = configs_of(mat) if mat.csm is not None else None
            if not configs:
                continue

            def passes(variant, steps, min_step=None):
                mat.csm.variant, mat.csm.steps, mat.csm.picked_min_step = variant, steps, min_step
                if mat.csm.map is not None:  # the map in memory: never read back from the stage
                    maps[mat.csm.step_map] = mat.csm.map.pixels
                    if mat.csm.step_map2 is not None:
                        maps[mat.csm.step_map2] = mat.csm.map.second
                prims = primitives(scene, {mat.ref: stored_of(mat)}, models, generate_tangents=generate_tangents,
                                   maps=maps)
                if not prims:
                    return True
                rep = verify_primitives(prims, size=RENDER_SIZE, views=DEFAULT_VIEWS, cameras=cams,
                                        max_error=MARGIN * opts.max_error, renderer=r)
                return rep.passed

            first = (mat.csm.variant, mat.csm.steps, mat.csm.picked_min_step)
            remake = (lambda bits: made.append(remake_map(mat, bits))) if remake_map is not None else None
            found, remade = confirm_choice(first, mat.csm.bits, passes,
                                           lambda: candidates(mat.csm.step_map, mat, opts, configs), remake)
            if found is None:
                mat.csm.variant, mat.csm.steps, mat.csm.picked_min_step = first
                scene.warn("CSM302", no_setting_message(opts.max_error, first), f"material {mat.name!r}")
            elif remade:
                scene.warn("CSM303", sixteen_bits_message(opts.max_error, found), f"material {mat.name!r}")
    return made


def no_setting_message(max_error: float, first) -> str:
    """CSM302's text: no setting meets the budget; ``first`` (variant, steps) is written."""
    return (f"no setting meets --max-error {max_error:g} texels at verify's views on its own primitives; "
            f"{first[0]} {first[1]} is written")


def sixteen_bits_message(max_error: float, found) -> str:
    """CSM303's text: only a 16-bit map meets the budget, with ``found`` (variant, steps)."""
    return (f"an 8-bit step map cannot meet --max-error {max_error:g} texels here; written at 16 bits "
            f"({found[0]} {found[1]})")
