"""The glTF exporter's user extension: every exported material with a height source gets its
step map and ``EXT_materials_cone_step_mapping`` (Blender's io_scene_gltf2 calls these hooks;
nothing of the exporter is changed).

- ``pre_export_hook`` (Blender 4.2: the module's ``glTF2_pre_export_callback``): tangents on (the
  exporter's MikkTSpace tangents are the ones written); on each mesh using a converted material,
  the UV map its heights use is made the active one for the export (Blender computes tangents of
  the active UV map), and put back afterwards (``post_export_hook``).
- ``gather_material_hook``: the material's heights (:mod:`.height_nodes`, :mod:`.images`), depth
  (:mod:`.geometry`, :func:`csm_assets.depth.texture_depth`), step map and properties
  (:func:`csm_assets.exporters.convert_material`), added as the exporter's own image, sampler and
  texture objects, so they land in the .gltf's folder or the .glb's buffer as its images do.
  With Max Error, the pick is confirmed on the meshes as exported
  (:func:`csm_assets.exporters.confirm_material`), as ``convert --max-error`` confirms it.

What cannot be converted is a warning in Blender's report (and in :data:`LAST_REPORT`), never a
failed export.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..depth import check_depth, texture_depth
from ..errors import FormatError, OptionError
from ..exporters import confirm_material, convert_material
from ..formats.csm_params import GLTF_EXTENSION
from ..render.gl_context import GLUnavailable
from . import geometry, gltf_io
from .height_nodes import HeightSource, NoHeight, depth_label, find_height
from .images import is_data, read_heights
from .options import OPTIONS, check_options

SETTINGS = "csm_assets_gltf"  # the Scene property holding the export options
TRANSFORM = "KHR_texture_transform"
LINEAR, REPEAT, CLAMP, MIRRORED = 9729, 10497, 33071, 33648
WRAPS = {"REPEAT": REPEAT, "EXTEND": CLAMP, "CLIP": CLAMP, "MIRROR": MIRRORED}


@dataclass
class ExportReport:
    """What the last export did: ``materials`` converted (name -> what was written: depthScale,
    variant, steps, texCoord, the node and factor it came from) and ``warnings``."""

    materials: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


LAST_REPORT = ExportReport()


def scene_options(scene) -> dict:
    """The export options' property values on ``scene`` (empty when the add-on is not registered)."""
    props = getattr(scene, SETTINGS, None)
    if props is None:
        return {}
    return {"enabled": props.enabled, **{o.name: getattr(props, o.name) for o in OPTIONS}}


class glTF2ExportUserExtension:  # noqa: N801 (the name glTF's exporter looks for)
    def __init__(self):
        import bpy

        global LAST_REPORT
        LAST_REPORT = self.report = ExportReport()
        values = scene_options(bpy.context.scene)
        self.enabled = values.pop("enabled", True)
        self.error = None
        try:
            self.options = check_options(values)
        except (OptionError, ValueError) as e:
            self.error = f"CSM: options refused ({e}); no CSM material is written"
        self.sources: dict = {}   # material (original) -> HeightSource | NoHeight
        self.restore: list = []   # (mesh, active UV map index) to put back after the export
        self.maps: dict = {}      # (image, channel, invert, tile) -> (heights, the first ExportedMaterial made of them)
        self.textures: dict = {}  # id(StepMap) -> (StepMap, the exporter's Texture): one image per map
        self.linearised: set = set()  # images warned about their colour space
        self.prepared = False     # pre_export_hook ran (Blender 4.3+ calls it, 4.2 the module's callback)

    def _warn(self, export_settings, message: str) -> None:
        self.report.warnings.append(message)
        export_settings["log"].warning(message, popup=True)

    def _source(self, material):
        key = material.original
        if key not in self.sources:
            try:
                self.sources[key] = find_height(material)
            except NoHeight as e:
                self.sources[key] = e
        return self.sources[key]

    def pre_export_hook(self, export_settings):
        import bpy

        if not self._usable(export_settings) or self.prepared:
            return
        self.prepared = True
        export_settings["gltf_tangents"] = True
        wanted: dict = {}  # mesh -> {uv map name: [materials]}
        for obj in bpy.context.scene.objects:
            if obj.type != "MESH":
                continue
            for slot in obj.material_slots:
                if slot.material is None or not isinstance(self._source(slot.material), HeightSource):
                    continue
                layer = geometry.uv_layer(obj.data, self.sources[slot.material.original].uv_map)
                if layer is not None:
                    wanted.setdefault(obj.data, {}).setdefault(layer.name, []).append(slot.material.original)
        for mesh, maps in wanted.items():
            name = next(iter(maps))
            for other, materials in list(maps.items())[1:]:
                for mat in materials:
                    self.sources[mat] = NoHeight(f"its heights use UV map {other!r} but mesh {mesh.name!r} also "
                                                 f"carries a relief on UV map {name!r}, and a mesh has one set of "
                                                 "tangents")
            layers = mesh.uv_layers
            if layers.active is None or layers.active.name != name:
                self.restore.append((mesh, layers.active_index))
                layers.active = layers[name]

    def post_export_hook(self, export_settings):
        while self.restore:
            mesh, index = self.restore.pop()
            mesh.uv_layers.active_index = index

    def _usable(self, export_settings) -> bool:
        """Enabled, with options a material can carry (else one warning, then off)."""
        if self.enabled and self.error:
            self._warn(export_settings, self.error)
            self.enabled = False
        return self.enabled

    def gather_material_hook(self, gltf2_material, blender_material, export_settings):
        if not self._usable(export_settings) or blender_material is None:
            return
        source = self._source(blender_material)
        if source is None:
            return
        name = blender_material.name
        if isinstance(source, NoHeight):
            self._warn(export_settings, f"CSM: material {name!r} not converted: {source}")
            return
        try:
            self._convert(gltf2_material, blender_material, source, export_settings)
        except (NoHeight, FormatError, OptionError, ValueError) as e:  # ValueError: a value the library refuses
            self._warn(export_settings, f"CSM: material {name!r} not converted: {e}")
        except GLUnavailable as e:  # Max Error measures with OpenGL
            self._warn(export_settings, f"CSM: material {name!r} not converted: Max Error needs an OpenGL "
                                        f"context ({e}); export without it")

    def _convert(self, gltf2_material, material, source: HeightSource, export_settings) -> None:
        objects = [o for o in _exported_objects(export_settings) if geometry.uses(o, material)]
        coords, parts, drawn = set(), [], []
        for obj, mesh in _meshes(objects, export_settings):
            tris = geometry.material_triangles(obj, mesh, material, source.uv_map, source.space,
                                               source.mapping["scale"] if source.mapping else (1.0, 1.0))
            if tris is None:
                which = f"UV map {source.uv_map!r}" if source.uv_map else "UV map"
                raise NoHeight(f"mesh {obj.name!r} has no {which} (the relief needs texture coordinates)")
            if geometry.has_ngons(mesh):
                raise NoHeight(f"mesh {obj.name!r} has faces of more than 4 corners, for which Blender computes no "
                               "tangents (the relief needs them): triangulate it, or add a Triangulate modifier "
                               "and export with Apply Modifiers")
            coords.add(geometry.tex_coord(mesh, source.uv_map))
            parts.append(tris)
            if self.options.max_error is not None:  # confirmed on the meshes as written, as convert does
                drawn.append(geometry.export_mesh(obj, mesh, material, source.uv_map))
        if not parts:
            return  # no exported mesh uses it
        if len(coords) > 1:
            raise NoHeight(f"its UV map is texCoord {' on some meshes and '.join(map(str, sorted(coords)))} on "
                           "others; one glTF material has one")
        wrap = WRAPS.get(source.extension, REPEAT)
        tile = (source.extension == "REPEAT",) * 2
        key = (source.image.original, source.channel, source.invert, tile)
        shared = self.maps.get(key)  # materials sharing one height image share its step map
        if shared is None:
            heights = read_heights(source.image, source.channel, source.invert)
            if not is_data(source.image) and source.image.original not in self.linearised:
                self.linearised.add(source.image.original)
                self._warn(export_settings, f"CSM: image {source.image.name!r} (material {material.name!r}) is in "
                                            f"colour space {source.image.colorspace_settings.name!r}, which Blender "
                                            "linearises; the step map keeps the stored values (set it to Non-Color)")
        else:
            heights = shared[0]
        height_scale = shared[1].height_scale if shared else float(heights.normalized().meta["height_scale"])
        depth = source.depth if source.factor is None else texture_depth(source.depth_factor, parts,
                                                                          height_scale=height_scale)
        shape = (shared[1].step_map.pixels if shared else heights.data).shape  # named as the user set it:
        depth = check_depth(depth, shape, depth_label(source))  # csm_depth, or the node's Scale/Distance
        made = convert_material(shared[1].step_map if shared else heights, depth, self.options, tile=tile,
                                height_wraps=(wrap, wrap), name=source.image.name)
        if shared is None:  # the map before confirmation: what others sharing it start from
            self.maps[key] = (heights, made)
        if drawn:
            made = confirm_material(made, [m for m in drawn if m is not None], self.options, heightfield=heights,
                                    name=material.name)
            for warning in made.warnings:
                self._warn(export_settings, f"CSM: material {material.name!r}: {warning}")
        texture = self.textures.get(id(made.step_map))
        if texture is None:
            texture = self.textures[id(made.step_map)] = (made.step_map, _texture(
                made, f"{Path(source.image.name).stem}_csm", export_settings))
        tex_coord = coords.pop()
        info = _texture_info(texture[1], tex_coord, source.mapping)
        body = made.gltf_extension(info)
        body["extras"] = {"blender": _extras(source, made)}
        if gltf2_material.extensions is None:
            gltf2_material.extensions = {}
        gltf2_material.extensions[GLTF_EXTENSION] = gltf_io.exporter().Extension(GLTF_EXTENSION, body, required=False)
        self.report.materials[material.name] = {
            "depthScale": made.depth_scale, "variant": made.variant, "steps": made.steps, "texCoord": tex_coord,
            "node": source.node, "factor": source.factor, "strength": source.strength, "image": source.image.name,
            "tile": list(made.tile)}


def pre_export_callback(export_settings) -> None:
    """The add-on module's ``glTF2_pre_export_callback``: Blender 4.2 has no ``pre_export_hook``."""
    for extension in export_settings.get("gltf_user_extensions", []):
        if isinstance(extension, glTF2ExportUserExtension):
            extension.pre_export_hook(export_settings)


def post_export_callback(export_settings) -> None:
    """The add-on module's ``glTF2_post_export_callback`` (the UV maps put back; idempotent)."""
    for extension in export_settings.get("gltf_user_extensions", []):
        if isinstance(extension, glTF2ExportUserExtension):
            extension.post_export_hook(export_settings)


def _extras(source: HeightSource, made) -> dict:
    """How the relief was set up in Blender, for the importer to set it up again: the node, its
    space, its midlevel in the step map's heights (raw = heightOffset + heightScale * R), Bump's Strength."""
    out = {"node": source.node, "space": source.space}
    if source.strength != 1:
        out["strength"] = source.strength
    if source.node == "DISPLACEMENT" and made.height_scale:
        out["midlevel"] = (source.midlevel - made.height_offset) / made.height_scale
    return out


def _exported_objects(export_settings):
    """The objects this export writes (the exporter's tree), else every object of the scene."""
    import bpy

    tree = export_settings.get("vtree")
    if tree is not None:
        objs = [n.blender_object for n in tree.nodes.values() if getattr(n, "blender_object", None) is not None]
        if objs:
            return list(dict.fromkeys(objs))
    return list(bpy.context.scene.objects)


def _meshes(objects, export_settings):
    """(object, mesh) as the exporter reads them: with modifiers applied (a copy of the evaluated
    mesh, removed afterwards: the exporter's own ``to_mesh`` of the object must stay), else the data."""
    import bpy

    for obj in objects:
        if export_settings.get("gltf_apply") and len(obj.modifiers):
            depsgraph = bpy.context.evaluated_depsgraph_get()
            mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph), preserve_all_data_layers=True,
                                                   depsgraph=depsgraph)
            try:
                yield obj, mesh
            finally:
                bpy.data.meshes.remove(mesh)
        else:
            yield obj, obj.data


def _texture(made, name: str, export_settings):
    """The exporter's Texture for the step map: an image (its bytes in the .glb's buffer, or a file
    beside the .gltf, named as the exporter names images), a LINEAR sampler without mipmaps and
    the map's wrap modes. One object per map: the exporter writes it once, however many use it."""
    io = gltf_io.exporter()
    if export_settings["gltf_format"] == "GLTF_SEPARATE":
        data = io.ImageData(made.data, made.mime_type, name)
        if io.set_real_uri is not None:  # Blender 4.3+ names the file here; 4.2 when writing it
            io.set_real_uri(data, export_settings)
        image = io.gltf2_io.Image(buffer_view=None, extensions=None, extras=None, mime_type=made.mime_type,
                                  name=name, uri=data)
    else:
        image = io.gltf2_io.Image(buffer_view=io.BinaryData(made.data), extensions=None, extras=None,
                                  mime_type=made.mime_type, name=name, uri=None)
    sampler = io.gltf2_io.Sampler(extensions=None, extras=None, mag_filter=LINEAR, min_filter=LINEAR, name=None,
                                  wrap_s=made.wraps[0], wrap_t=made.wraps[1])
    return io.gltf2_io.Texture(extensions=None, extras=None, name=None, sampler=sampler, source=image)


def _texture_info(texture, tex_coord: int, mapping):
    """The material's TextureInfo of the step map: its uv set, and a Mapping node as
    KHR_texture_transform (converted by the exporter's own function, as for its textures)."""
    io = gltf_io.exporter()
    extensions = None
    if mapping is not None:
        extensions = {TRANSFORM: io.Extension(TRANSFORM, io.texture_transform(mapping), required=False)}
    return io.gltf2_io.TextureInfo(extensions=extensions, extras=None, index=texture, tex_coord=tex_coord or None)
