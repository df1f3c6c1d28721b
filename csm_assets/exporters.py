"""Library calls from exporters: one material's CSM conversion, without a scene file.

``convert`` reads a material's height texture and displacement factor from a file. An
exporter (a DCC's glTF exporter, such as the Blender add-on :mod:`csm_assets.blender`)
already has both in its own scene; :func:`convert_material` makes for one material what
``convert`` makes, from the same :class:`~csm_assets.convert.pipeline.ConvertOptions` and by
the same rules (the step map's settings, tiling, the variant and its steps, ``max_error``'s quick
pick): the packed step map as PNG bytes and the ``EXT_materials_cone_step_mapping`` properties;
:func:`confirm_material` then confirms a ``max_error`` pick on the material's own meshes, as
``convert --max-error`` confirms it on the scene.
The depth is the exporter's to compute with :func:`csm_assets.depth.texture_depth`.
:func:`read_material_extension` reads such an extension back (an importer), checked as
``verify`` checks it.
"""

from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .depth import check_depth
from .errors import FormatError, OptionError
from .stepmap import StepMap, make_step_map, save_step_map

GLTF_BITS = (8, 16)  # glTF images are PNG


@dataclass
class ExportedMaterial:
    """A material's CSM conversion: ``step_map`` (pixels and settings), ``data`` (the map as
    PNG bytes, its settings in the image description, as ``save_step_map`` writes it),
    ``depth_scale`` (texture-space depth), the shader ``variant`` and ``steps``, self-shadowing,
    and ``wraps``: the glTF sampler's (wrapS, wrapT) for the map (REPEAT on tiled axes);
    ``warnings``: what :func:`confirm_material` found (``convert``'s CSM302/CSM303 texts)."""

    step_map: StepMap
    data: bytes
    depth_scale: float
    variant: str
    steps: int
    self_shadow: bool = False
    light_size: float = 0.0
    wraps: tuple[int, int] = (10497, 10497)
    mime_type: str = "image/png"
    warnings: list[str] = field(default_factory=list)

    max_ratio = property(lambda self: self.step_map.settings.max_ratio)
    tile = property(lambda self: self.step_map.settings.tile)
    height_scale = property(lambda self: self.step_map.settings.height_scale)
    height_offset = property(lambda self: self.step_map.settings.height_offset)
    min_step = property(lambda self: self.step_map.settings.min_step)

    def gltf_extension(self, texture_info: dict | None = None) -> dict:
        """The ``EXT_materials_cone_step_mapping`` object: ``stepMapTexture`` (``texture_info``,
        the exporter's textureInfo of the map; left out when None, for exporters that add it
        as their own object) then the parameters in the schema's order, as ``convert`` writes them."""
        from .formats.csm_params import gltf_properties

        head = {} if texture_info is None else {"stepMapTexture": texture_info}
        return {**head, **gltf_properties(self)}


def convert_material(heightfield, depth_scale: float, options=None, *, tile=None, height_wraps=None,
                     name: str = "", **kwargs) -> ExportedMaterial:
    """The CSM conversion of one material whose heights are ``heightfield``.

    heightfield: a :class:`~csm_assets.Heightfield` (read it with :func:`csm_assets.load_heightfield`,
        ``invert=True`` for a depth map) or unit heights ``(H, W)`` in image order; or the
        :class:`~csm_assets.StepMap` of an :class:`ExportedMaterial` made before with the same
        options and tiling (materials sharing one height image share its map; OptionError when
        it was made with other settings, or with levels).
    depth_scale: texture-space depth (uv units per unit of height), e.g.
        :func:`csm_assets.depth.texture_depth` of the displacement factor.
    options: a :class:`~csm_assets.convert.pipeline.ConvertOptions` or its fields by keyword
        (bits 8 or 16, or None: chosen for verify at ``depth_scale`` as convert chooses them,
        max_ratio, tile, variant, steps, max_error, cones, bilinear_safe, self_shadow, light_size); variant None picks as the command line does
        (:func:`csm_assets.convert.pick.default_variant`). ``levels`` is not applied: an exported
        material carries one image, so its map has no level chain (docs/reference/levels.md).
    tile: the height texture's own (tile_u, tile_v) from its wrap modes (None: both repeat);
        ``options.tile`` overrides it. height_wraps: its glTF (wrapS, wrapT), which the map's
        sampler keeps on axes that do not tile (mirrored stays mirrored). name: the texture's
        name, stored in the map's settings.

    OptionError for options no material can carry (as ``convert`` refuses them), and for a
    ``depth_scale`` nothing can be measured at on this texture (:func:`csm_assets.depth.check_depth`:
    2^-24 to 2^24 texels deep; a huge Displacement Scale on a small mesh), before any map is made,
    so an exporter warns and skips the material; ``max_error`` needs an OpenGL context
    (:class:`~csm_assets.render.gl_context.NoGLError` without one).
    """
    from .convert.maps import resolve_tile, step_map_settings
    from .convert.pick import default_variant, pick
    from .convert.pipeline import check_material_options
    from .formats.gltf_write import step_map_wraps

    opts = _options(options, kwargs)
    if opts.cones == "quadrant":
        raise OptionError("quadrant cones are two step map images, which exported materials do not carry yet "
                          "(ExportedMaterial holds one); convert the exported scene with csm-assets convert "
                          "--cones quadrant")
    if opts.variant is None:
        opts.variant = default_variant(opts.max_error, opts.cones)
    if opts.bits is not None and opts.bits not in GLTF_BITS:
        raise OptionError(f"glTF step maps are 8 or 16-bit PNG, not {opts.bits}-bit")
    check_material_options(opts)
    data = heightfield.pixels if isinstance(heightfield, StepMap) else getattr(heightfield, "data", heightfield)
    if np.ndim(data) >= 2:  # (else make_step_map refuses it)
        depth_scale = check_depth(depth_scale, np.shape(data), "depth_scale (the texture-space depth)")
    resolved = resolve_tile(tile, opts)
    settings = step_map_settings(opts, resolved, name).replace(levels="none")  # one image: no levels image
    if isinstance(heightfield, StepMap):
        sm, made_with = heightfield, heightfield.settings
        bits = made_with.bits if opts.bits is None else settings.bits  # chosen bits: the map's own stand
        wanted = (settings.max_ratio, settings.tile, bits, settings.bilinear_safe, settings.cones)
        if wanted != (made_with.max_ratio, made_with.tile, made_with.bits, made_with.bilinear_safe, made_with.cones) \
                or heightfield.levels:
            raise OptionError(f"the step map given for {name or 'the material'} was made with other settings "
                              f"({made_with}) than these options and tiling ask for")
    else:  # bits None: the fewest whose cost verify cannot see at this depth (verify.bits), as convert does
        from .verify.bits import chooser

        choose = chooser(float(depth_scale), allowed=GLTF_BITS) if opts.bits is None else None
        sm = make_step_map(heightfield, settings, choose=choose)
    variant, steps, _ = pick(sm, name, depth_scale, opts)  # a picked minimum step: quadrant maps only
    return ExportedMaterial(sm, step_map_png(sm), float(depth_scale), variant, steps, opts.self_shadow,
                            opts.light_size, tuple(step_map_wraps(resolved, height_wraps)))


def _options(options, kwargs):
    """A copy of ``options`` (a ConvertOptions), or one made of ``kwargs``."""
    from .convert.pipeline import ConvertOptions

    if options is not None and kwargs:
        raise TypeError("give the options as a ConvertOptions or as keywords, not both")
    return dataclasses.replace(options) if options is not None else ConvertOptions(**kwargs)


def confirm_material(made: ExportedMaterial, meshes, options=None, *, heightfield=None, name: str = "",
                     cameras=(), **kwargs) -> ExportedMaterial:
    """``made`` (from :func:`convert_material` with the same options) with its ``max_error`` pick
    confirmed on the material's own ``meshes``, as ``convert --max-error`` confirms it on the scene
    (:mod:`csm_assets.convert.pick`): drawn with verify's measure, views and size at
    :data:`~csm_assets.convert.pick.MARGIN` times the budget; when the pick fails there, the next
    settings in order of cost are tried; when none passes with an 8-bit map and ``heightfield``
    (what ``made`` was made from) is given, the map is made again at 16 bits and the search
    repeats. What convert would warn about (CSM302: none passes, the pick is kept; CSM303: 16 bits)
    is in the returned material's ``warnings``. ``made`` itself when nothing was picked
    (no ``max_error``, or a variant and steps given).

    meshes: :class:`csm_assets.scene.Mesh` objects as the exporter writes them (positions,
    normals, uvs in glTF's convention, ``uv_origin="top-left"``, faces; tangents ``(V, 4)``, or
    None: MikkTSpace's are generated). cameras: ``[(name, Camera)]`` also drawn, as convert draws
    the scene's own. Needs an OpenGL context
    (:class:`~csm_assets.render.gl_context.GLUnavailable` without one).
    """
    from .convert.pick import (MARGIN, confirm_choice, no_setting_message, pick_configs, ranked_settings,
                               sixteen_bits_message)
    from .formats.csm_material import StoredCsm
    from .render.renderer import Renderer
    from .scene import Texture
    from .verify.maps import DEFAULT_VIEWS, RENDER_SIZE
    from .verify.scene import Primitive, mesh_frame, render_mesh, uv_scale, verify_primitives

    opts = _options(options, kwargs)
    configs = pick_configs(opts)
    if not configs:
        return made
    drawn = [(mesh.name, *render_mesh(mesh, generate_tangents=True)) for mesh in meshes]
    drawn = [(n, rm, why or "", uv_scale(rm), mesh_frame(rm)) for n, rm, why in drawn if rm is not None]
    drawn = [d for d in drawn if d[3] > 0 and d[4] is not None]  # the meshes verify can measure, drawn once for every try
    sm, texture = made.step_map, Texture(f"{name or 'material'}_csm")
    with Renderer((RENDER_SIZE, RENDER_SIZE)) as r:
        def passes(variant, steps, _min_step=None):  # quadrant maps' minimum steps: not here
            s = sm.settings
            stored = StoredCsm(name, texture, made.depth_scale, s.max_ratio, tuple(s.tile), variant, steps, s.min_step)
            prims = [Primitive(n, stored, sm.pixels, rm, why, None, scale, frame=frame)
                     for n, rm, why, scale, frame in drawn]
            return not prims or verify_primitives(prims, size=RENDER_SIZE, views=DEFAULT_VIEWS, cameras=cameras,
                                                  max_error=MARGIN * opts.max_error, renderer=r).passed

        def remake(bits):
            nonlocal sm
            sm = make_step_map(heightfield, dataclasses.replace(sm.settings, bits=bits))

        first = (made.variant, made.steps, None)
        found, remade = confirm_choice(
            first, sm.settings.bits, passes, lambda: ranked_settings(sm.pixels, sm.settings.max_ratio, sm.settings.tile,
                                                                     made.depth_scale, sm.settings.min_step,
                                                                     sm.settings.cones, opts, configs),
            remake if heightfield is not None else None)
    if found is None:
        warning = f"CSM302 {no_setting_message(opts.max_error, first)}"
    else:
        warning = f"CSM303 {sixteen_bits_message(opts.max_error, found)}" if remade else None
    variant, steps = (found or first)[:2]
    data = step_map_png(sm) if sm is not made.step_map else made.data
    return dataclasses.replace(made, step_map=sm, data=data, variant=variant, steps=steps,
                               warnings=[*made.warnings, *([warning] if warning else [])])


def step_map_png(sm: StepMap) -> bytes:
    """``sm`` as the bytes of the PNG file :func:`csm_assets.save_step_map` writes."""
    with tempfile.TemporaryDirectory(prefix="csm-") as tmp:
        path = Path(tmp) / "step_map.png"
        save_step_map(sm, path)
        return path.read_bytes()


def read_material_extension(extension, source, material: str) -> dict:
    """The checked parameters of an ``EXT_materials_cone_step_mapping`` object read from a file:
    ``{attr: value}`` as :data:`csm_assets.formats.csm_params.PARAMETERS` names them
    (``depth_scale``, ``max_ratio``, ``tile``, ...) plus ``texture``: its ``stepMapTexture``.
    FormatError naming ``source`` and ``material`` for a missing texture, a wrong type, a number
    out of range, NaN or infinity."""
    from .formats.csm_params import read_values

    where = f"material {material!r}"
    if not isinstance(extension, dict):
        raise FormatError(source, f"{where}: the extension is not a JSON object")
    info = extension.get("stepMapTexture")
    index = info.get("index") if isinstance(info, dict) else None
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise FormatError(source, f"{where}: stepMapTexture needs a texture index, got {info!r}")
    values = read_values(lambda p: extension.get(p.name), source, where)
    return {**values, "texture": info}
