"""The add-on's settings as Blender properties (on the Scene, as glTF exporter extensions keep
theirs): ``scene.csm_assets_gltf`` (export, from :data:`.options.OPTIONS`) and
``scene.csm_assets_gltf_import`` (import)."""

from __future__ import annotations

import bpy

from .options import OPTIONS

IMPORT_NODES = (("AUTO", "As Exported", "The node the relief was exported from (a Displacement node for files "
                                        "from elsewhere)"),
                ("DISPLACEMENT", "Displacement", "A Displacement node into the Material Output"),
                ("BUMP", "Bump", "A Bump node into the shader's Normal"))


def _property(option):
    common = {"name": option.label, "description": option.doc, "default": option.default}
    if option.kind == "bool":
        return bpy.props.BoolProperty(**common)
    if option.kind == "int":
        return bpy.props.IntProperty(min=int(option.low), max=int(option.high), **common)
    if option.kind == "float":
        return bpy.props.FloatProperty(min=option.low, max=option.high, precision=3, **common)
    items = [(v, v.replace("_", " ").title() if v.isupper() else v, "") for v in option.items]
    return bpy.props.EnumProperty(items=items, **common)


CsmExportSettings = type("CsmExportSettings", (bpy.types.PropertyGroup,), {"__annotations__": {
    "enabled": bpy.props.BoolProperty(name="Cone Step Mapping", default=True,
                                      description="Write a CSM step map and EXT_materials_cone_step_mapping for "
                                                  "every material with a height source (csm-assets)"),
    **{o.name: _property(o) for o in OPTIONS}}})


class CsmImportSettings(bpy.types.PropertyGroup):
    enabled: bpy.props.BoolProperty(name="Cone Step Mapping", default=True,
                                    description="Turn EXT_materials_cone_step_mapping into a relief node setup")
    node: bpy.props.EnumProperty(name="Relief Node", items=IMPORT_NODES, default="AUTO",
                                 description="The node the step map's height feeds")


CLASSES = (CsmExportSettings, CsmImportSettings)
