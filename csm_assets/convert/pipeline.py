"""Scene conversion: a chain of small steps over the scene model.

read -> step maps (:mod:`csm_assets.convert.maps`, one per distinct height texture) -> tangents
(:mod:`csm_assets.tangents.mesh_checks`, only meshes whose material got a step map) -> write, into a staged
output folder (:mod:`csm_assets.convert.output_folder`, :mod:`csm_assets.convert.manifest`). A material without a height
texture costs nothing.
"""

from __future__ import annotations

import dataclasses
import json
import numbers
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .. import height_source
from ..atomic import atomic_path
from ..checks import non_negative
from ..cones.relaxed import CONE_KINDS
from ..errors import OptionError, OutputError, StrictError
from ..formats.csm_params import BY_NAME
from ..formats.registry import SCENE_FORMAT_ROWS, scene_module
from ..stepmap import DEFAULTS
from ..tangents.mesh_checks import make_tangents, mesh_problems, triangle_areas, warn_clamped_uvs
from ..warning_codes import Notice, Policy, checked_codes
from . import manifest
from . import output_folder as folder
from .maps import confirm_scene_picks, make_step_maps
from .pick import checked_variant

__all__ = ["SCENE_FORMATS", "ConvertOptions", "ConvertReport", "Progress", "convert", "make_step_maps",
           "make_tangents", "mesh_problems", "scene_module", "triangle_areas"]

# extension -> scene format module in csm_assets.formats
SCENE_FORMATS = {f.extension: f.module for f in SCENE_FORMAT_ROWS}
DEFAULT_DEPTH = height_source.DEFAULT_DEPTH  # texture-space depth when nothing states a factor
# progress(stage, done, total): stages "reading", "step maps", "pick", "tangents", "confirm",
# "writing" in that order (those the conversion needs); done/total count rows or materials, 0/0 none
Progress = Callable[[str, int, int], None]


@dataclass
class ConvertOptions:
    """Settings of one conversion (the CLI's flags).

    heights: material name -> height texture (a path or a
        :class:`~csm_assets.height_source.HeightSpec`, which can say it is a depth map).
    depth: texture-space depth (uv units per unit of height) for every material,
        instead of the one derived from the file's displacement factor.
    depths: material name -> texture-space depth of that material (before ``depth``).
    bits: 8 or 16 (PNG step maps), or 32 (float EXR, for OBJ and USD scenes); None (the default):
        per step map, the fewest the scene's format holds whose rounding of the heights verify
        cannot see at the material's depth (:func:`csm_assets.verify.bits.choose_bits`; 8 for most).
    variant, steps: the shader variant and its step count written into each material.
    self_shadow, light_size: the material's self-shadowing switch and the light's angular
        radius in radians (0: hard shadows), written into each converted material
        (``selfShadow``/``lightSize``; left out when off and 0, so outputs stay as before).
    max_error: a budget in texels (p95 at every view): each material gets the cheapest
        (variant, steps) of :data:`csm_assets.bench.trade.DEFAULT_CONFIGS` that meets it on its
        own step map and depth, measured by :func:`csm_assets.bench.trade.pick_settings`. Then
        ``variant`` "auto" (or None) picks among all variants, another name only among
        its step counts, and ``steps`` > 0 only among that step count; a variant and
        steps both given are taken as they are.
    cones: "conservative" (every variant) or "relaxed": step maps of relaxed cones, drawn
        only with the ``relaxed`` variant (``variant`` "relaxed", or "auto" with
        ``max_error``: picked among its step counts); another variant is an OptionError.
    strict, error_on, ignore: which warnings fail the conversion (:class:`~csm_assets.errors.StrictError`,
        nothing published): under ``strict`` those of severity ``warning``, the codes in
        ``error_on`` always; codes in ``ignore`` are neither reported nor failing
        (:class:`csm_assets.warning_codes.Policy`; codes as ``CSM205``, in any case).
    """

    heights: dict = field(default_factory=dict)
    depths: dict = field(default_factory=dict)
    max_ratio: float = DEFAULTS.max_ratio
    bits: int | None = None
    tile: bool | None = None
    depth: float | None = None
    regenerate_tangents: bool = False
    variant: str = "exact"
    steps: int = 0
    max_error: float | None = None
    allow_outside: bool = False
    bilinear_safe: bool = DEFAULTS.bilinear_safe  # G = 3x3 minimum, and _exact's minimum step 0.25 texel
    cones: str = DEFAULTS.cones      # "conservative" or "relaxed" (the relaxed variant only)
    self_shadow: bool = BY_NAME["selfShadow"].default
    light_size: float = BY_NAME["lightSize"].default
    force: bool = False              # convert even when the manifest says the outputs are fresh
    cache_dir: Path | None = None    # step maps shared by content hash across conversions
    strict: bool = False             # warnings that mean "may be wrong" are errors: StrictError
    error_on: tuple = ()             # warning codes that are errors
    ignore: tuple = ()               # warning codes neither reported nor failing

    def settings(self) -> dict:
        """What decides the outputs (for the manifest): every field but force, cache_dir and the
        warning policy (strict, error_on, ignore);
        self_shadow, light_size and cones only when set (manifests written before them stay fresh)."""
        d = dataclasses.asdict(self)
        for k in ("force", "cache_dir", "strict", "error_on", "ignore"):
            d.pop(k)
        for k in ("self_shadow", "light_size", "cones"):
            if d[k] == getattr(ConvertOptions, k):
                d.pop(k)
        d["heights"] = {k: str(v) for k, v in sorted(self.heights.items())}
        return json.loads(json.dumps(d))


@dataclass
class ConvertReport:
    """What a conversion did: files written, step maps made, warnings, seconds."""

    input: Path
    skipped: str | None = None  # why nothing was done (outputs fresh), else None
    written: list[Path] = field(default_factory=list)
    step_maps: dict[str, Path] = field(default_factory=dict)
    tangent_meshes: list[str] = field(default_factory=list)
    warnings: list[Notice] = field(default_factory=list)  # not ignored; see csm_assets.warning_codes
    picks: dict = field(default_factory=dict)  # material -> {"variant", "steps"} written
    seconds: float = 0.0

    @property
    def unchanged(self) -> bool:
        """Converted, but no material had a height texture: the scene was copied as it was."""
        return self.skipped is None and not self.step_maps


def picked(mat) -> dict:
    """What a converted material got, for the report: variant, steps, bits and why those bits."""
    c = mat.csm
    choice = getattr(c.map, "choice", None)  # None: made again at more bits by --max-error's confirmation
    why = f"made again at {c.bits} bits to meet --max-error" if choice is None else \
        "given" if choice.given else choice.reason
    return {"variant": c.variant, "steps": c.steps, "bits": c.bits, "bits_reason": why}


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


def convert(in_path, out_dir, options: ConvertOptions | None = None, *, progress: Progress | None = None,
            **kwargs) -> ConvertReport:
    """Convert the scene at ``in_path`` into ``out_dir`` (created if missing).

    Options come as a :class:`ConvertOptions` or as its fields by keyword. Outputs whose
    manifest shows them fresh are left alone (``report.skipped`` says why) unless
    ``force``. Everything is made in a staging folder inside ``out_dir`` and moved into
    place only when all of it succeeded, manifest last: a failure leaves no partial
    outputs, an interruption leaves each file old and intact or new and complete.
    Several scenes may be converted into one folder: each takes names no other scene's
    entry in the manifest holds (see :mod:`csm_assets.convert.output_folder`).
    Raises FormatError for an unreadable scene (:class:`~csm_assets.errors.StrictError`
    for warnings that are errors under ``strict``/``error_on``) and OutputError when an output
    would overwrite an input or another scene's output, or cannot be written.
    ``progress(stage, done, total)`` (:data:`Progress`) hears each stage as it starts and
    goes on; report.warnings holds the warnings not ignored, identical ones collapsed.
    """
    opts = options or ConvertOptions(**kwargs)
    start = time.perf_counter()
    in_path, out_dir = Path(in_path), Path(out_dir)
    module = scene_module(in_path)
    if out_dir.resolve() == in_path.parent.resolve():
        raise OutputError(out_dir, "is the input's folder: the converted scene would overwrite "
                                   f"{in_path.name}; choose another output folder")
    if opts.bits is not None and opts.bits not in module.STEP_MAP_BITS:
        raise OptionError(f"{in_path}: {in_path.suffix} scenes take {' or '.join(map(str, module.STEP_MAP_BITS))}"
                         f"-bit step maps, not {opts.bits}-bit (glTF images are PNG)")
    if opts.cones not in CONE_KINDS:
        raise OptionError(f"cones must be one of {', '.join(CONE_KINDS)}, got {opts.cones!r}")
    checked_variant(opts)  # relaxed cones: the relaxed variant only
    check_material_options(opts)
    check_warning_options(opts)
    policy, tell = Policy.of(opts), progress or _silent
    report = ConvertReport(in_path)
    with folder.locked(out_dir):
        folder.clean_dead_stages(out_dir)
        known = manifest.load(out_dir)
        mine = known["scenes"].get(in_path.name)
        if mine is not None and mine.get("source", manifest.source_key(in_path, out_dir)) != \
                manifest.source_key(in_path, out_dir):
            raise OutputError(out_dir / in_path.name, f"is the output of another scene ({mine['source']}); "
                                                      "convert this one into another folder")
        if not opts.force and in_path.is_file():
            if manifest.staleness(in_path, out_dir, opts.settings(), known) is None:
                report.skipped = "outputs are fresh"
                recorded = [Notice.from_dict(d) for d in mine.get("warnings", [])]
                report.warnings = policy.kept(recorded)
                report.picks = dict(mine.get("picks", {}))
                if failing := policy.failing(recorded):
                    raise StrictError(in_path, report.warnings, failing, policy.why(failing))
                report.seconds = time.perf_counter() - start
                return report
        tell("reading", 0, 0)
        scene = module.read(in_path, heights=opts.heights, allow_outside=opts.allow_outside)
        height_source.check_names(scene, [*opts.heights, *opts.depths])
        others = manifest.owned_by_others(known, in_path.name)
        scene.reserved = {manifest.NAME, in_path.name}
        scene.others = folder.other_files(others, out_dir)
        with folder.staging(out_dir) as stage:
            report.step_maps = make_step_maps(scene, stage, opts, module.STEP_MAP_BITS, tell)
            warn_clamped_uvs(scene)
            if module.STORES_TANGENTS:
                tell("tangents", 0, 0)
                report.tangent_meshes = make_tangents(scene, opts)
            if opts.max_error is not None:
                report.step_maps.update({p.stem: p for p in confirm_scene_picks(scene, stage, opts, module, tell)})
            embedded = getattr(module, "embeds_step_maps", lambda _: False)(scene)  # a GLB holds its own
            tell("writing", 0, 0)
            scene_files = module.write(scene, stage)
            staged = [*([] if embedded else report.step_maps.values()), *scene_files]
            if failing := policy.failing(scene.warnings):
                raise StrictError(in_path, policy.kept(scene.warnings), failing, policy.why(failing))
            names = [p.name for p in staged]
            inputs = [in_path, *scene.inputs]
            folder.check_names(stage, names, out_dir, inputs, others)
            report.picks = {m.name: picked(m) for m in scene.materials if m.csm is not None}
            known["scenes"][in_path.name] = manifest.entry(in_path, out_dir, scene.inputs, staged,
                                                           opts.settings(), report.picks,
                                                           [n.record() for n in scene.warnings])
            with atomic_path(stage / manifest.NAME) as tmp:
                manifest.write(tmp, known)
            report.written = folder.publish(stage, names + [manifest.NAME], out_dir)
        folder.remove_orphans(out_dir, set(mine["outputs"]) if mine else set(), set(names), set(others), inputs)
    report.step_maps = {k: out_dir / (scene_files[0] if embedded else v).name for k, v in report.step_maps.items()}
    report.warnings = policy.kept(scene.warnings)
    report.seconds = time.perf_counter() - start
    return report


def _silent(stage: str, done: int, total: int) -> None:
    """No progress wanted."""
