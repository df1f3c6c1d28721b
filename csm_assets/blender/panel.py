"""The add-on's sub-panels in the glTF exporter's and importer's file dialogs (drawn by
io_scene_gltf2 through ``exporter_extension_layout_draw`` and the module's ``draw_import``)."""

from __future__ import annotations

from .options import OPTIONS

EXPORT_SETTINGS = "csm_assets_gltf"
IMPORT_SETTINGS = "csm_assets_gltf_import"


def draw_export(context, layout) -> None:
    props = getattr(context.scene, EXPORT_SETTINGS, None)
    if props is None:
        return
    header, body = layout.panel("CSM_assets_gltf_export", default_closed=False)
    header.use_property_split = False
    header.prop(props, "enabled")
    if body is not None:
        body.active = props.enabled
        body.use_property_split = True
        for option in OPTIONS:
            body.prop(props, option.name)


def draw_import(context, layout) -> None:
    props = getattr(context.scene, IMPORT_SETTINGS, None)
    if props is None:
        return
    header, body = layout.panel("CSM_assets_gltf_import", default_closed=False)
    header.use_property_split = False
    header.prop(props, "enabled")
    if body is not None:
        body.active = props.enabled
        body.use_property_split = True
        body.prop(props, "node")
