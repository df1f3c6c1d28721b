"""The CSM material parameters, once, in the order of the schema
(``docs/EXT_materials_cone_step_mapping.schema.json``).

Every writer and reader of a CSM material goes through :data:`PARAMETERS`: the glTF
extension ``EXT_materials_cone_step_mapping`` (property ``name``), the USD shader
``CsmConeStepSurface`` (input ``name``; ``tile`` as the ints ``tileU``/``tileV``) and the MTL
statements (``mtl``). A parameter that is ``optional`` is written only when it differs from its
default, so materials converted before it existed stay byte-identical. Values read back are
checked here too (:func:`read_values`): a wrong type, a number out of range, NaN or infinity
is a FormatError (exit 3) naming the file and the material.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..checks import non_negative, number, positive, short_repr
from ..errors import FormatError

GLTF_EXTENSION = "EXT_materials_cone_step_mapping"


@dataclass(frozen=True)
class CsmParam:
    """One CSM material parameter (a row of :data:`PARAMETERS`).

    Attributes:
        name (str): the glTF property and USD input (``depthScale``).
        attr (str): the attribute of :class:`~csm_assets.scene.CsmSettings` and ``StoredCsm``.
        kind (str): ``"number"``, ``"integer"``, ``"boolean"``, ``"string"`` or ``"tile"`` (two
            booleans).
        default (Any): the value when absent; None: required.
        mtl (str): the MTL statement (``csm_depth``).
        rule (str): the range (``">0"``, ``"finite"``, ...; see :func:`problem`).
        doc (str): one sentence for the schema and the docs.
        optional (bool): left out of a material when at its default.
        shader_default (Any): what the shader takes when a USD input is not authored (None:
            ``default``).
    """

    name: str
    attr: str
    kind: str
    default: Any
    mtl: str
    rule: str
    doc: str
    optional: bool = False
    shader_default: Any = None

    @property
    def fallback(self):
        """What a reader takes when the parameter is absent: ``shader_default``, else ``default``."""
        return self.default if self.shader_default is None else self.shader_default


PARAMETERS: tuple[CsmParam, ...] = (
    CsmParam("depthScale", "depth_scale", "number", None, "csm_depth", ">=0",
             "Depth of the relief in texture space: uv units per unit of height (1 = as deep as the texture "
             "is wide).", shader_default=0.1),
    CsmParam("maxRatio", "max_ratio", "number", 1.0, "csm_max_ratio", ">0", "The cone ratio that G = 1 stands for."),
    CsmParam("tile", "tile", "tile", (True, True), "csm_tile", "", "Whether the cones wrap around along u and v."),
    CsmParam("heightScale", "height_scale", "number", 1.0, "csm_height_scale", "finite",
             "How the step map's R maps back to the source height texture's values (its "
             "normalization): raw = heightOffset + heightScale * R. Not the scene's displacement "
             "factor, which depthScale holds."),
    CsmParam("heightOffset", "height_offset", "number", 0.0, "csm_height_offset", "finite",
             "The normalization's offset: raw = heightOffset + heightScale * R (see heightScale; not "
             "a displacement bias)."),
    CsmParam("variant", "variant", "string", "exact", "csm_variant", "variant",
             "Shader variant: exact, loop, fixed, parallax, pom, relief, relaxed or quadrant (quadrant "
             "step maps only, with their second image)."),
    CsmParam("steps", "steps", "integer", 0, "csm_steps", "steps",
             "Steps of the stepped variants (1..127): loop and fixed cone steps, pom and relief "
             "linear steps, relaxed search steps; 0 for exact and parallax, which take none."),
    CsmParam("minStep", "min_step", "number", 1.0, "csm_min_step", "min_step",
             "The minimum step in texels of exact, relaxed and the self-shadow march (the paper: 1; "
             "0.25 for bilinear-safe step maps, whose G is the 3x3 minimum)."),
    CsmParam("selfShadow", "self_shadow", "boolean", False, "csm_self_shadow", "",
             "Whether the surface shades itself: a shadow ray from each hit toward the light, stepped "
             "with the same cones.", optional=True),
    CsmParam("lightSize", "light_size", "number", 0.0, "csm_light_size", ">=0",
             "The light's angular radius in radians for self-shadowing: 0 = hard shadows, > 0 = a soft "
             "penumbra.", optional=True),
)
"""The CSM material parameters in the schema's order; every writer and reader of a CSM
material goes through this table."""
BY_NAME = {p.name: p for p in PARAMETERS}
""":data:`PARAMETERS` by ``name``."""


def written(csm) -> list[tuple[CsmParam, Any]]:
    """``(parameter, value)`` of a material's settings (any object with the ``attr`` attributes,
    e.g. :class:`~csm_assets.scene.CsmSettings`) in schema order, optional ones at their default
    left out; tiles as ``(bool, bool)``, booleans as bool. ValueError for a number that is not
    finite (the writers' last check: a material never holds Infinity or NaN)."""
    out = []
    for p in PARAMETERS:
        v = getattr(csm, p.attr)
        v = (bool(v[0]), bool(v[1])) if p.kind == "tile" else bool(v) if p.kind == "boolean" else v
        if p.kind in ("number", "integer") and not math.isfinite(v):  # never written (JSON has no Infinity)
            raise ValueError(f"{p.name} {v} is not a finite number; nothing was written")
        if p.optional and v == p.default:
            continue
        out.append((p, v))
    return out


# the extension's textureInfo properties: the step map, a quadrant map's second image, their levels
GLTF_TEXTURES = ("stepMapTexture", "stepMap2Texture", "stepMapLevelsTexture", "stepMap2LevelsTexture")


def gltf_properties(csm) -> dict[str, Any]:
    """The properties of ``EXT_materials_cone_step_mapping`` but the textures (:data:`GLTF_TEXTURES`),
    as JSON values
    (:func:`written`: schema order, optional ones at their default left out; tiles as lists)."""
    return {p.name: list(v) if p.kind == "tile" else v for p, v in written(csm)}


# the MTL statements naming a converted material's images: the step map, a quadrant map's second
# image, their levels images (docs/reference/levels.md), as GLTF_TEXTURES and USD's asset inputs
MTL_IMAGES = ("csm_map", "csm_map2", "csm_map_levels", "csm_map2_levels")


def mtl_lines(csm, step_map_name: str) -> list[str]:
    """The ``csm_*`` statements of a converted MTL material: ``csm_map``, a quadrant map's
    ``csm_map2`` (its second image, ``csm.step_map2``, beside the first), the levels images'
    ``csm_map_levels`` and ``csm_map2_levels`` (``csm.levels_images``), then :func:`written`."""
    second = getattr(csm, "step_map2", None)
    lines = [f"csm_map {step_map_name}", *([f"csm_map2 {second.name}"] if second is not None else [])]
    lines += [f"{key} {path.name}" for key, path in zip(MTL_IMAGES[2:], getattr(csm, "levels_images", []))]
    for p, v in written(csm):
        lines.append(f"{p.mtl} {format_text(p, v)}")
    return lines


def format_text(p: CsmParam, v) -> str:
    """Value ``v`` of parameter ``p`` as an MTL statement's text (``1 0`` for a tile, ``1`` for True)."""
    if p.kind == "tile":
        return f"{int(v[0])} {int(v[1])}"
    if p.kind == "boolean":
        return str(int(v))
    if p.kind == "number":
        return f"{v:.9g}"
    return str(v)


def parse_text(p: CsmParam, text: str):
    """An MTL statement's argument as the value :func:`problem` checks (ValueError when it is
    none of the kind's spellings: booleans ``0``/``1``, tiles two of them)."""
    words = text.split()
    if p.kind == "tile":
        if len(words) != 2 or any(w not in ("0", "1") for w in words):
            raise ValueError(f"expected two of 0 and 1, got {text!r}")
        return [w == "1" for w in words]
    if p.kind == "boolean":
        if words not in (["0"], ["1"]):
            raise ValueError(f"expected 0 or 1, got {text!r}")
        return words[0] == "1"
    if p.kind == "integer":
        try:
            return int(text)
        except ValueError:
            raise ValueError(f"expected an integer, got {text!r}") from None
    if p.kind == "number":
        try:
            return float(text)
        except ValueError:
            raise ValueError(f"expected a number, got {text!r}") from None
    return text.strip()


def problem(p: CsmParam, v) -> str | None:
    """What is wrong with value ``v`` of ``p`` (its type, then its range), or None."""
    if p.kind == "tile":
        if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(t, bool) for t in v)):
            return f"{p.name} must be two booleans, got {short_repr(v)}"
        return None
    if p.kind == "boolean":
        return None if isinstance(v, bool) else f"{p.name} must be a boolean, got {short_repr(v)}"
    if p.kind == "string":
        if not isinstance(v, str):
            return f"{p.name} must be a string, got {short_repr(v)}"
        if p.rule == "variant":
            from ..render.renderer import VARIANTS

            if v not in VARIANTS:
                return f"variant {short_repr(v)} is none of {', '.join(VARIANTS)}"
        return None
    if p.kind == "integer":
        if isinstance(v, bool) or not (isinstance(v, int) or (isinstance(v, float) and v.is_integer())):
            return f"{p.name} must be an integer, got {short_repr(v)}"
        if p.rule == "steps":
            from ..verify.maps import MAX_STEPS

            if not 0 <= v <= MAX_STEPS:
                return f"steps {short_repr(v)} is outside 0..{MAX_STEPS}"
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):  # text is no number in a material
        return f"{p.name} must be a number, got {short_repr(v)}"
    check = {">0": positive, ">=0": non_negative}.get(p.rule, number)
    try:
        x = check(v, p.name)
    except ValueError as e:
        return str(e)
    if p.rule == "min_step" and not 0 < x <= 1:
        return f"minStep {short_repr(v)} is outside (0, 1] texels"
    return None


def read_values(get, path, where: str, *, fallback: bool = False) -> dict[str, Any]:
    """``{attr: value}`` of every parameter, ``get(param)`` giving its stored value or None when
    absent (then its default; with ``fallback``, the shader's default, as a USD input not authored).
    FormatError naming ``path`` and ``where`` (the material) listing every problem."""
    values, problems = {}, []
    for p in PARAMETERS:
        raw = get(p)
        if raw is None:
            raw = p.fallback if fallback else p.default
            if raw is None:
                problems.append(f"no {p.name}")
                continue
        bad = problem(p, raw)
        if bad:
            problems.append(bad)
            continue
        values[p.attr] = (tuple(raw) if p.kind == "tile" else int(raw) if p.kind == "integer"
                          else float(raw) if p.kind == "number" else raw)
    if problems:
        raise FormatError(path, f"{where}: {'; '.join(problems)}")
    return values
