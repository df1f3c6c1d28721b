"""The add-on's export options, once: the panel's properties, the scripting call's keywords and
the :class:`~csm_assets.convert.pipeline.ConvertOptions` they make are all drawn from
:data:`OPTIONS` (no bpy here).

Each option is one ``convert`` flag that decides the output; its value as a Blender property
(``prop``: enums are strings, "0" turns ``max_error`` off) and as a keyword (``value``: what
``ConvertOptions`` takes) are converted by :func:`keyword_to_property` and
:func:`convert_options`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..cones.relaxed import CONE_KINDS
from ..convert.pipeline import ConvertOptions
from ..errors import OptionError
from ..render.renderer import VARIANTS
from ..verify.maps import MAX_STEPS

DEFAULTS = ConvertOptions()


@dataclass(frozen=True)
class Option:
    """One export option: ``name`` (property and keyword), ``kind`` ("bool", "int", "float",
    "enum"), the property's ``default``, ``label``, ``doc``; ``items`` (enum values), ``low``/``high``
    (number bounds)."""

    name: str
    kind: str
    default: Any
    label: str
    doc: str
    items: tuple = ()
    low: float | None = None
    high: float | None = None


OPTIONS: tuple[Option, ...] = (
    Option("bits", "enum", "AUTO" if DEFAULTS.bits is None else str(DEFAULTS.bits), "Bits",
           "Step map bit depth: 8 or 16-bit PNG, or Auto: the fewest whose cost verify cannot see at the "
           "material's depth, as convert chooses them (convert --bits)", items=("AUTO", "8", "16")),
    Option("variant", "enum", "AUTO", "Variant",
           "Shader variant written into the materials (convert --variant); Auto: exact, relaxed with relaxed "
           "cones, picked by Max Error when that is set", items=("AUTO", *VARIANTS)),
    Option("steps", "int", 0, "Steps",
           "Steps of loop/fixed, linear steps of pom/relief, search steps of relaxed; 0: the variant's default "
           "(convert --steps)", low=0, high=MAX_STEPS),
    Option("max_error", "float", 0.0, "Max Error",
           "Per material, the cheapest variant and step count whose p95 error is at most this many texels on "
           "its own step map, confirmed on the exported meshes at verify's views; 0: off (convert --max-error)", low=0.0, high=1e6),
    Option("cones", "enum", DEFAULTS.cones, "Cones",
           "Conservative cones (every variant) or relaxed cones (the relaxed variant only) (convert --cones)",
           items=CONE_KINDS),
    Option("self_shadow", "bool", DEFAULTS.self_shadow, "Self Shadow",
           "Materials shade themselves: a shadow ray toward the light, stepped with the same cones "
           "(convert --self-shadow)"),
    Option("light_size", "float", DEFAULTS.light_size, "Light Size",
           "With Self Shadow, the light's angular radius in radians: 0 hard shadows, > 0 a soft penumbra "
           "(convert --light-size)", low=0.0, high=3.2),
    Option("tile", "enum", "AUTO", "Tile",
           "Whether the cones wrap around: Auto follows each image's extension (Repeat tiles), Tile and "
           "No Tile override it (convert --tile/--no-tile)", items=("AUTO", "TILE", "NO_TILE")),
    Option("max_ratio", "float", DEFAULTS.max_ratio, "Max Ratio",
           "The cone ratio a stored G of 1 stands for (convert --max-ratio)", low=1e-6, high=1e6),
    Option("bilinear_safe", "bool", DEFAULTS.bilinear_safe, "Bilinear Safe",
           "G holds each texel's 3x3 minimum and the minimum step is 0.25 texel; off: the paper's maps "
           "(convert --no-bilinear-safe)"),
)
BY_NAME = {o.name: o for o in OPTIONS}
TILE = {"AUTO": None, "TILE": True, "NO_TILE": False}


def keyword_to_property(name: str, value) -> Any:
    """A scripting keyword's value as the property holds it (TypeError for an unknown name,
    OptionError for a value the option cannot take)."""
    option = BY_NAME.get(name)
    if option is None:
        raise TypeError(f"unknown export option {name!r}; the options are {', '.join(BY_NAME)}")
    if name == "variant":
        value = "AUTO" if value in (None, "auto") else value
    elif name == "tile":
        value = {v: k for k, v in TILE.items()}.get(value, value)
    elif name == "max_error":
        value = 0.0 if value is None else value
    elif name == "bits":
        value = "AUTO" if value in (None, "auto") else str(value)
    if option.kind == "enum" and value not in option.items:
        raise OptionError(f"{name} must be one of {', '.join(map(repr, option.items))}, got {value!r}")
    if option.kind == "bool" and not isinstance(value, bool):
        raise OptionError(f"{name} must be True or False, got {value!r}")
    if option.kind in ("int", "float"):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (option.kind == "int" and not float(value).is_integer()):
            raise OptionError(f"{name} must be a number, got {value!r}")
        if not option.low <= value <= option.high:
            raise OptionError(f"{name} must be in {option.low:g}..{option.high:g}, got {value!r}")
    return value


def convert_options(values: dict) -> ConvertOptions:
    """The ConvertOptions of property values ``values`` (name -> value; missing ones at their
    default). The variant "AUTO" is left to :func:`csm_assets.convert.pick.default_variant`.
    Blender keeps float properties in 32 bits: a number is taken as the shortest decimal that
    gives that float (0.05, not 0.05000000074505806), as the user typed it."""
    v = {o.name: _typed(o, values.get(o.name, o.default)) for o in OPTIONS}
    return ConvertOptions(bits=None if v["bits"] == "AUTO" else int(v["bits"]), variant=None if v["variant"] == "AUTO" else v["variant"],
                          steps=int(v["steps"]), max_error=float(v["max_error"]) or None, cones=v["cones"],
                          self_shadow=bool(v["self_shadow"]), light_size=float(v["light_size"]),
                          tile=TILE[v["tile"]], max_ratio=float(v["max_ratio"]),
                          bilinear_safe=bool(v["bilinear_safe"]))


def _typed(option: Option, value):
    if option.kind == "float" and isinstance(value, float):
        return float(str(np.float32(value)))
    return value


def check_options(values: dict) -> ConvertOptions:
    """:func:`convert_options`, refused as ``convert`` refuses them (OptionError): steps out of range,
    a light size without self-shadowing, relaxed cones with another variant."""
    from ..convert.pick import checked_variant, default_variant
    from ..convert.pipeline import check_material_options

    opts = convert_options(values)
    if opts.variant is None:
        opts.variant = default_variant(opts.max_error, opts.cones)
    checked_variant(opts)
    if opts.variant == "auto" and opts.max_error is None:
        raise OptionError("variant 'auto' needs max_error (the budget it picks by)")
    check_material_options(opts)
    return opts
