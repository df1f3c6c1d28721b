"""csm-assets' Blender add-on: Blender's own glTF exporter writes Cone Step Mapping materials, and
its importer turns them back into a relief node setup (through io_scene_gltf2's user-extension
hooks; nothing of it is forked).

Install into a Blender: ``csm-assets blender install`` (:mod:`.install`). From a script (``bpy``
from PyPI too): ``csm_assets.blender.export_gltf("scene.glb", bits=16)`` and
``csm_assets.blender.import_gltf(...)`` (:mod:`.scripting`). Nothing here imports bpy until
Blender registers the add-on or a function is called, so the package imports anywhere.
"""

from __future__ import annotations

from .export_hooks import ExportReport, glTF2ExportUserExtension
from .export_hooks import post_export_callback as glTF2_post_export_callback
from .export_hooks import pre_export_callback as glTF2_pre_export_callback
from .import_hooks import ImportReport, glTF2ImportUserExtension
from . import panel
from .panel import EXPORT_SETTINGS, IMPORT_SETTINGS, draw_import
from .scripting import enable, export_gltf, import_gltf

bl_info = {
    "name": "csm-assets: Cone Step Mapping glTF",
    "author": "csm-assets",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "File > Export/Import > glTF 2.0 (Cone Step Mapping panel)",
    "description": "Writes EXT_materials_cone_step_mapping step maps for materials with Displacement or Bump "
                   "heights, and reads them back into relief nodes",
    "category": "Import-Export",
}
DRAW_KEY = "csm-assets"

# The export panel is registered into io_scene_gltf2.exporter_extension_layout_draw (Blender 4.3+ draws only
# those); this module has no ``draw_export`` attribute, or Blender 4.2, which also adds the one of every
# add-on with hooks, would draw it twice. The importer finds ``draw_import`` here.
__all__ = ["ExportReport", "ImportReport", "bl_info", "draw_import", "enable", "export_gltf",
           "glTF2ExportUserExtension", "glTF2ImportUserExtension", "glTF2_post_export_callback",
           "glTF2_pre_export_callback", "import_gltf", "register", "unregister"]


def register() -> None:
    import bpy

    from . import props

    for cls in props.CLASSES:
        bpy.utils.register_class(cls)
    setattr(bpy.types.Scene, EXPORT_SETTINGS, bpy.props.PointerProperty(type=props.CsmExportSettings))
    setattr(bpy.types.Scene, IMPORT_SETTINGS, bpy.props.PointerProperty(type=props.CsmImportSettings))
    try:
        from io_scene_gltf2 import exporter_extension_layout_draw
    except ImportError:  # Blender's glTF add-on is off: nothing to draw into
        return
    exporter_extension_layout_draw[DRAW_KEY] = panel.draw_export


def unregister() -> None:
    import bpy

    from . import props

    try:
        from io_scene_gltf2 import exporter_extension_layout_draw
        exporter_extension_layout_draw.pop(DRAW_KEY, None)
    except ImportError:
        pass
    for name in (EXPORT_SETTINGS, IMPORT_SETTINGS):
        if hasattr(bpy.types.Scene, name):
            delattr(bpy.types.Scene, name)
    for cls in reversed(props.CLASSES):
        bpy.utils.unregister_class(cls)
