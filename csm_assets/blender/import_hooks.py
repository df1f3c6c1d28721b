"""The glTF importer's user extension: ``EXT_materials_cone_step_mapping`` back into a node setup
that shows the relief in Blender.

``gather_import_material_after_hook``: the step map as an Image Texture node (made by the
importer's own texture helper, so its UV map, wrap modes and KHR_texture_transform are set as for
any glTF texture; Non-Color), its red channel (the height) into a Displacement node (into the
Material Output) or a Bump node (into the shader's Normal), as the extension's
``extras.blender.node`` says or the import option chooses. ``gather_import_scene_after_nodes_hook``:
once the meshes exist, the node's Scale/Distance = depthScale times the world size of one uv unit
(:func:`csm_assets.depth.world_per_uv`, measured as the exporter measured it), and the
Displacement's Midlevel from ``extras.blender.midlevel`` (1 otherwise: the relief goes into the
surface, as CSM draws it); a Bump node's Strength from ``extras.blender.strength`` (1 otherwise),
its Distance then that depth over the Strength.

A material whose extension cannot be set up (:mod:`.import_checks`: a value its schema or glTF's
refuses, an image or sampler the file has not, a step map too big by its header, a depth past
32-bit floats) is a warning and gets no relief; a bad ``extras.blender`` hint is a warning and
its default is used. Nothing aborts the import.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..depth import world_per_uv
from ..errors import FormatError
from ..exporters import read_material_extension
from ..formats.csm_params import GLTF_EXTENSION
from . import geometry, gltf_io
from .import_checks import blender_extras, depth_problem, extras_value, step_map_problem
from .panel import IMPORT_SETTINGS


@dataclass
class ImportReport:
    """What the last import did: ``materials`` set up (name -> node, factor, image, tiling) and ``warnings``."""

    materials: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


LAST_REPORT = ImportReport()


@dataclass
class _Pending:
    material: object
    node: object
    depth_scale: float
    tex_coord: int
    space: str
    uv_scale: tuple = (1.0, 1.0)
    strength: float = 1.0


class glTF2ImportUserExtension:  # noqa: N801 (the name glTF's importer looks for)
    def __init__(self):
        import bpy

        global LAST_REPORT
        LAST_REPORT = self.report = ImportReport()
        props = getattr(bpy.context.scene, IMPORT_SETTINGS, None)
        self.enabled = props.enabled if props is not None else True
        self.node = props.node if props is not None else "AUTO"
        self.pending: list[_Pending] = []

    def _warn(self, gltf, message: str) -> None:
        self.report.warnings.append(message)
        gltf.log.warning(message)

    def gather_import_material_after_hook(self, pymaterial, vertex_color, mat, gltf):
        ext = (pymaterial.extensions or {}).get(GLTF_EXTENSION)
        if ext is None or not self.enabled:
            return
        try:
            values = read_material_extension(ext, gltf.filename, mat.name)
        except FormatError as e:
            self._warn(gltf, f"CSM: {e}; no relief set up")
            return
        info = values["texture"]
        why = step_map_problem(gltf, info, f"/materials/{_index_of(gltf, pymaterial)}/extensions/{GLTF_EXTENSION}/"
                                           "stepMapTexture") or depth_problem(values["depth_scale"])
        if why:
            self._warn(gltf, f"CSM: {gltf.filename}: material {mat.name!r}: {why}; no relief set up")
            return
        problems: list = []
        extras = blender_extras(ext, problems)
        hint = {key: extras_value(extras, key, problems) for key in ("node", "space", "midlevel", "strength")}
        for problem in problems:
            self._warn(gltf, f"CSM: {gltf.filename}: material {mat.name!r}: {problem}")
        kind = self.node if self.node != "AUTO" else hint["node"] or "DISPLACEMENT"
        space = hint["space"] if self.node == "AUTO" and hint["space"] else \
            "OBJECT" if kind == "DISPLACEMENT" else "WORLD"
        midlevel = 1.0 if hint["midlevel"] is None else hint["midlevel"]
        node = _relief_nodes(pymaterial, vertex_color, mat, gltf, info, kind, space, midlevel)
        transform = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
        strength = hint["strength"] if hint["strength"] is not None and kind == "BUMP" else 1.0
        if kind == "BUMP":
            node.inputs["Strength"].default_value = strength
        self.pending.append(_Pending(mat, node, values["depth_scale"], info.get("texCoord", 0), space,
                                     tuple(transform.get("scale", (1.0, 1.0))), strength))

    def gather_import_scene_after_nodes_hook(self, gltf_scene, blender_scene, gltf):
        import bpy

        bpy.context.view_layer.update()  # world matrices of the new objects
        for p in self.pending:
            parts = []
            for obj in blender_scene.objects:
                if not geometry.uses(obj, p.material) or p.tex_coord >= len(obj.data.uv_layers):
                    continue
                name = obj.data.uv_layers[p.tex_coord].name
                tris = geometry.material_triangles(obj, obj.data, p.material, name, p.space, p.uv_scale)
                if tris is not None:
                    parts.append(tris)
            scale = world_per_uv(parts)
            if scale is None:
                self._warn(gltf, f"CSM: material {p.material.name!r}: no triangles with uv area use it; its relief "
                                 "depth is depthScale taken as model units")
                scale = 1.0
            socket = "Scale" if p.node.bl_idname == "ShaderNodeDisplacement" else "Distance"
            factor = p.depth_scale * scale / p.strength
            if depth_problem(factor):  # a huge object: the node cannot hold it; the relief is left unwired
                self._warn(gltf, f"CSM: material {p.material.name!r}: its relief's {socket} {factor:g} (depthScale "
                                 f"{p.depth_scale:g} times {scale:g} model units per uv unit) is beyond Blender's "
                                 "32-bit float range; the relief node is left unconnected")
                for link in list(p.node.outputs[0].links):
                    p.material.node_tree.links.remove(link)
                continue
            p.node.inputs[socket].default_value = factor
            image = _step_map_image(p.node)
            self.report.materials[p.material.name] = {
                "node": "DISPLACEMENT" if socket == "Scale" else "BUMP", "factor": factor, "strength": p.strength,
                "space": p.space, "image": image.name if image else None, "texCoord": p.tex_coord}


def _relief_nodes(pymaterial, vertex_color, mat, gltf, texture_info, kind, space, midlevel):
    """Image Texture -> Separate Color (red: the height) -> Displacement or Bump; returns that node."""
    io = gltf_io.importer()
    tree = mat.node_tree
    nodes, links = tree.nodes, tree.links
    output = next((n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    x, y = (output.location.x, output.location.y - 500) if output is not None else (0.0, -500.0)
    sep = nodes.new("ShaderNodeSeparateColor")
    sep.location = x - 500, y
    sep.label = "CSM height (R)"
    mh = io.MaterialHelper(gltf, pymaterial, mat, vertex_color)
    io.texture(mh, io.TextureInfo.from_dict(dict(texture_info)), location=(x - 520, y), label="CSM step map",
               color_socket=sep.inputs[0], is_data=True)
    if kind == "DISPLACEMENT":
        node = nodes.new("ShaderNodeDisplacement")
        node.space = space
        node.inputs["Midlevel"].default_value = midlevel
        links.new(sep.outputs["Red"], node.inputs["Height"])
        if output is not None:
            links.new(node.outputs["Displacement"], output.inputs["Displacement"])
        mat.displacement_method = "BOTH"
    else:
        node = nodes.new("ShaderNodeBump")
        links.new(sep.outputs["Red"], node.inputs["Height"])
        shader = next((n for n in nodes if "Normal" in n.inputs and n.bl_idname.startswith("ShaderNodeBsdf")), None)
        if shader is not None:
            normal = shader.inputs["Normal"]
            if normal.is_linked:  # a normal map stays, under the bump
                links.new(normal.links[0].from_socket, node.inputs["Normal"])
            links.new(node.outputs["Normal"], normal)
    node.location = x - 200, y
    node.label = "CSM relief"
    return node


def _index_of(gltf, pymaterial) -> int | str:
    """The material's index in the file (for the JSON pointer of a problem), "?" when not found."""
    return next((i for i, m in enumerate(gltf.data.materials or []) if m is pymaterial), "?")


def _step_map_image(node):
    """The image of the Image Texture node feeding ``node``'s Height (through Separate Color)."""
    sep = node.inputs["Height"].links[0].from_node
    links = sep.inputs[0].links
    return links[0].from_node.image if links and links[0].from_node.bl_idname == "ShaderNodeTexImage" else None
