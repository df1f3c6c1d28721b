"""The settings of one conversion (:class:`ConvertOptions`, the CLI's flags and the project
configuration's keys) and the checks of those no material can carry."""

from __future__ import annotations

import dataclasses
import json
import numbers
from dataclasses import dataclass, field
from pathlib import Path

from ..checks import non_negative
from ..errors import OptionError
from ..formats.csm_params import BY_NAME
from ..height_source import HeightSpec
from ..stepmap import DEFAULTS
from ..warning_codes import checked_codes
from .manifest import path_key

TEXTURES = ("reference", "copy")  # ConvertOptions.textures: see csm_assets.convert.links
PICK_COSTS = ("fetches", "block")  # what the --max-error pick minimises (ConvertOptions.pick_cost)
NOT_CONFIG = {"config": False}  # a field the project configuration does not set (see csm_assets.config)


@dataclass
class ConvertOptions:
    """Settings of one conversion (the CLI's flags).

    The project configuration (:mod:`csm_assets.config`) sets any field under its option's
    name (``max_error`` as ``max-error``; ``metadata["option"]`` where they differ) except
    those marked ``metadata["config"] = False``.

    Attributes:
        heights (dict): material name -> height texture (a path or a
            :class:`~csm_assets.height_source.HeightSpec`, which can say it is a depth map).
        depths (dict): material name -> texture-space depth of that material (before ``depth``).
        max_ratio (float): the cone ratio G = 1 stands for (> 0).
        bits (int | None): 8 or 16 (PNG step maps), or 32 (float EXR, for OBJ and USD scenes);
            None (the default): per step map, the fewest the scene's format holds whose
            rounding of the heights verify cannot see at the material's depth
            (:func:`csm_assets.verify.bits.choose_bits`; 8 for most). A bit depth the format
            cannot hold is an OptionError.
        tile (bool | None): wrap every texture (True/False); None: each texture's own wrap mode.
        depth (float | None): texture-space depth (uv units per unit of height) for every
            material, instead of the one derived from the file's displacement factor.
        regenerate_tangents (bool): replace tangents the file has.
        variant (str): the shader variant written into each material (``"auto"`` with
            ``max_error``: picked).
        steps (int): its step count (0: the variant's default).
        max_error (float | None): a budget in texels (p95 at every view): each material gets
            the cheapest (variant, steps) of :data:`csm_assets.bench.trade.DEFAULT_CONFIGS` that
            meets it on its own step map and depth (:func:`csm_assets.bench.trade.pick_settings`).
            ``variant`` "auto" (or None) picks among all variants, another name only among its
            step counts, and ``steps`` > 0 only among that step count; a variant and steps both
            given are taken as they are.
        allow_outside (bool): files outside the project root may be read.
        bilinear_safe (bool): G holds each texel's 3x3 minimum, and ``_exact``'s minimum step
            is 0.25 texel.
        cones (str): ``"conservative"`` (every variant), ``"relaxed"`` (the ``relaxed`` variant
            only) or ``"quadrant"`` (two images, the second with ``_q`` before the extension;
            the ``quadrant`` variant only). Another variant with them is an OptionError.
        levels (str): each step map's level chain (:mod:`csm_assets.step_levels`): ``"average"``
            (the default) or ``"max"``, one more image beside each step map image (``_levels``
            before the extension; not for UDIM sets: :mod:`csm_assets.convert.udim`), or ``"none"``.
        pick_cost (str): what the ``max_error`` pick minimises among the settings meeting the
            budget: ``"fetches"`` (mean texture fetches per pixel) or ``"block"`` (the mean over
            8x4 pixel blocks of the block's largest count), then the frame time.
        self_shadow (bool): each converted material shades itself (``selfShadow``).
        light_size (float): the light's angular radius in radians (0: hard shadows; >= 0,
            finite, only with ``self_shadow``, else an OptionError); written as ``lightSize``.
        textures (str | None): ``"reference"``: the output names the scene's textures where
            they are; ``"copy"``: copies them; None: reference beside the scene, else copy
            (:mod:`csm_assets.convert.links`).
        force (bool): convert even when the outputs are fresh.
        cache_dir (pathlib.Path | None): step maps shared between runs by content hash.
        strict (bool): warnings of severity ``warning`` are errors
            (:class:`~csm_assets.errors.StrictError`, nothing published).
        error_on (tuple[str, ...]): warning codes that are errors (``CSM205``, any case).
        ignore (tuple[str, ...]): warning codes neither reported nor failing.
        root (pathlib.Path | None): the project root; None: the configuration's folder, else
            the git repository's root, else the scene's folder.
        relief_only (bool): a scene without a height texture writes nothing (``skipped``
            "no relief").
        named_by (dict): material name -> where it was named (a configuration's
            ``file:line``), for the error when it is not a material of the scene.
        depth_names (dict): ``"depth"`` or a material's name -> how a message names the
            setting that gave it (``--depth``, ``depth (csm-assets.toml:3)``).
    """

    heights: dict = field(default_factory=dict, metadata=NOT_CONFIG)  # config keys height, depth-map
    depths: dict = field(default_factory=dict, metadata=NOT_CONFIG)   # config key depth (a table)
    max_ratio: float = DEFAULTS.max_ratio
    bits: int | None = None
    tile: bool | None = None
    depth: float | None = None
    regenerate_tangents: bool = False
    variant: str = "exact"
    steps: int = 0
    max_error: float | None = None
    allow_outside: bool = field(default=False, metadata={"option": "allow-outside-paths"})
    bilinear_safe: bool = DEFAULTS.bilinear_safe  # G = 3x3 minimum, and _exact's minimum step 0.25 texel
    cones: str = DEFAULTS.cones      # "conservative", "relaxed" or "quadrant" (their variant only)
    levels: str = DEFAULTS.levels    # the step maps' level chain: "none", "average" or "max" (step_levels)
    pick_cost: str = "fetches"       # what --max-error's pick minimises: "fetches" or "block" (PICK_COSTS)
    self_shadow: bool = BY_NAME["selfShadow"].default
    light_size: float = BY_NAME["lightSize"].default
    textures: str | None = None      # "reference" or "copy" (None: reference beside the scene, else copy)
    force: bool = field(default=False, metadata=NOT_CONFIG)  # convert even when the outputs are fresh
    cache_dir: Path | None = field(default=None, metadata=NOT_CONFIG)  # step maps shared by content hash
    strict: bool = False             # warnings that mean "may be wrong" are errors: StrictError
    error_on: tuple[str, ...] = ()   # warning codes that are errors
    ignore: tuple[str, ...] = ()     # warning codes neither reported nor failing
    root: Path | None = field(default=None, metadata=NOT_CONFIG)  # the project root (None: found)
    relief_only: bool = field(default=False, metadata=NOT_CONFIG)
    named_by: dict = field(default_factory=dict, metadata=NOT_CONFIG)
    depth_names: dict = field(default_factory=dict, metadata=NOT_CONFIG)  # "depth" or material -> its setting's name

    def settings(self, root=None) -> dict:
        """What decides the outputs (for the manifest): every field but force, cache_dir, the
        warning policy (strict, error_on, ignore), root, relief_only, named_by, depth_names; self_shadow,
        light_size, cones and pick_cost only when set, textures only when "reference" (manifests
        written before them stay fresh); levels always (a manifest without it was made without levels,
        the default before ``"average"``, and is stale, as it would be after any change of default).

        Args:
            root (pathlib.Path | None): the project root height textures are named relative to
                (see :func:`path_key`); None: as given.

        Returns:
            A JSON-ready dict.
        """
        d = dataclasses.asdict(self)
        for k in ("force", "cache_dir", "strict", "error_on", "ignore", "root", "relief_only", "named_by",
                  "depth_names"):
            d.pop(k)
        for k in ("self_shadow", "light_size", "cones", "pick_cost"):
            if d[k] == getattr(ConvertOptions, k):
                d.pop(k)
        if d["textures"] in (None, "copy"):  # as outputs were before the choice: copies
            d.pop("textures")
        d["heights"] = {k: height_key(v, root) for k, v in sorted(self.heights.items())}
        return json.loads(json.dumps(d))


def height_key(value, root) -> str:
    """A height texture as the manifest's settings name it: its path relative to ``root``."""
    spec = value if isinstance(value, HeightSpec) else None
    path = spec.path if spec else value if isinstance(value, (str, Path)) else None
    if root is None or path is None:
        return str(value)
    channel = getattr(spec, "channel", None)
    return (path_key(root, path) + (" (depth map)" if spec and spec.depth_map else "")
            + (f" (channel {channel})" if channel is not None else ""))


def check_material_options(opts: ConvertOptions) -> None:
    """OptionError (exit 2) for a setting no material can carry: ``steps`` not an integer in
    0..:data:`~csm_assets.verify.maps.MAX_STEPS` (0 or None: the variant's default), ``self_shadow``
    not a boolean, ``light_size`` not a finite number >= 0, or a light size without
    self-shadowing."""
    from ..verify.maps import MAX_STEPS

    if opts.steps is None:
        opts.steps = 0
    if isinstance(opts.steps, bool) or not isinstance(opts.steps, numbers.Integral) \
            or not 0 <= opts.steps <= MAX_STEPS:
        raise OptionError(f"steps must be an integer in 0..{MAX_STEPS} (loop, fixed, pom, relief; relaxed's "
                          f"search; 0: the variant's default), got {opts.steps!r}")
    if not isinstance(opts.self_shadow, bool):
        raise OptionError(f"self_shadow must be True or False, got {opts.self_shadow!r}")
    try:
        opts.light_size = non_negative(opts.light_size, "light_size")
    except ValueError as e:
        raise OptionError(f"{e} (the light's angular radius in radians)") from None
    if opts.light_size > 0 and not opts.self_shadow:
        raise OptionError("light_size is the soft shadows' light size: it needs self_shadow")
    if opts.textures not in (None, *TEXTURES):
        raise OptionError(f"textures must be one of {', '.join(TEXTURES)}, got {opts.textures!r}")
    if opts.pick_cost not in PICK_COSTS:
        raise OptionError(f"pick_cost must be one of {', '.join(PICK_COSTS)}, got {opts.pick_cost!r}")


def check_warning_options(opts: ConvertOptions, names=("error_on", "ignore")) -> None:
    """``error_on`` and ``ignore`` as tuples of known codes (upper case); OptionError (exit 2)
    naming ``names`` (the fields, or the flags that gave them) for an unknown code, or a code
    both promoted and ignored."""
    try:
        opts.error_on = checked_codes(opts.error_on, names[0])
        opts.ignore = checked_codes(opts.ignore, names[1])
    except ValueError as e:
        raise OptionError(str(e)) from None
    both = sorted(set(opts.error_on) & set(opts.ignore))
    if both:
        raise OptionError(f"warning code(s) {', '.join(both)} are both in {names[0]} and in {names[1]}; choose one")
