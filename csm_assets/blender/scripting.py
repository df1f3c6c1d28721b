"""The add-on from a script (``bpy`` from PyPI, or Blender's own Python): :func:`enable`,
:func:`export_gltf`, :func:`import_gltf`."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..errors import FormatError
from . import export_hooks, import_hooks
from .options import BY_NAME, check_options, keyword_to_property
from .panel import EXPORT_SETTINGS, IMPORT_SETTINGS

PACKAGE = __name__.rpartition(".")[0]  # csm_assets.blender


def enable() -> str:
    """Register the add-on in this Blender session (and Blender's glTF add-on); idempotent.
    Returns the name it is enabled under (``csm_assets_gltf`` where ``csm-assets blender install``
    put it, else ``csm_assets.blender``)."""
    import addon_utils
    import bpy

    addon_utils.enable("io_scene_gltf2", default_set=True)
    for name in bpy.context.preferences.addons.keys():
        module = sys.modules.get(name)
        if getattr(module, "glTF2ExportUserExtension", None) is export_hooks.glTF2ExportUserExtension:
            return name
    module = sys.modules.get(PACKAGE)
    if module is not None and not hasattr(module, "__time__"):  # imported by the script: Blender need not reload it
        module.__time__ = os.path.getmtime(module.__file__)
    if addon_utils.enable(PACKAGE, default_set=True, persistent=True) is None:
        raise RuntimeError(f"Blender could not enable {PACKAGE} (see the messages above)")
    return PACKAGE


def export_gltf(filepath, *, enabled: bool = True, **options) -> export_hooks.ExportReport:
    """Export the scene with ``bpy.ops.export_scene.gltf`` and the CSM extension; returns the
    add-on's :class:`~csm_assets.blender.export_hooks.ExportReport` (materials converted, warnings).

    options: the add-on's (bits, variant, steps, max_error, cones, self_shadow, light_size, tile,
    max_ratio, bilinear_safe: see :data:`csm_assets.blender.options.OPTIONS`; ``variant=None``,
    ``max_error=None``, ``tile=None`` as in ``convert``), the rest go to Blender's exporter
    (``export_format`` follows the suffix: ``.glb`` GLB, else separate .gltf files; tangents are
    always exported). The scene's panel settings are put back afterwards.
    """
    import bpy

    ours = {k: keyword_to_property(k, v) for k, v in options.items() if k in BY_NAME}
    gltf = {k: v for k, v in options.items() if k not in BY_NAME}
    gltf.setdefault("export_format", "GLB" if str(filepath).lower().endswith(".glb") else "GLTF_SEPARATE")
    gltf["export_tangents"] = True
    enable()
    props = getattr(bpy.context.scene, EXPORT_SETTINGS)
    check_options({**{k: getattr(props, k) for k in BY_NAME}, **ours})  # refused before anything is written
    before = {k: getattr(props, k) for k in [*ours, "enabled"]}
    try:
        for k, v in {**ours, "enabled": enabled}.items():
            setattr(props, k, v)
        Path(filepath).parent.mkdir(parents=True, exist_ok=True)  # Blender 4.2's exporter does not make it
        result = bpy.ops.export_scene.gltf(filepath=str(Path(filepath)), **gltf)
    finally:
        for k, v in before.items():
            setattr(props, k, v)
    if result != {"FINISHED"}:
        raise RuntimeError(f"{filepath}: Blender's glTF exporter returned {result}")
    return export_hooks.LAST_REPORT


def import_gltf(filepath, *, enabled: bool = True, node: str = "AUTO", **options) -> import_hooks.ImportReport:
    """Import a glTF/GLB with ``bpy.ops.import_scene.gltf``; CSM materials get their relief nodes.
    node: "AUTO" (as exported; a Displacement node otherwise), "DISPLACEMENT" or "BUMP". Returns the
    add-on's :class:`~csm_assets.blender.import_hooks.ImportReport`. A file Blender's importer
    refuses (not glTF, malformed) is a one-line :class:`~csm_assets.errors.FormatError`; a material
    the add-on cannot set up is a warning in the report."""
    import bpy

    enable()
    props = getattr(bpy.context.scene, IMPORT_SETTINGS)
    before = (props.enabled, props.node)
    try:
        props.enabled, props.node = enabled, node
        result = bpy.ops.import_scene.gltf(filepath=str(Path(filepath)), **options)
    except RuntimeError as e:  # Blender's own importer refused the file (its traceback in the message)
        lines = [x.strip() for x in str(e).splitlines() if x.strip() and not x.startswith(("Location:", " "))]
        raise FormatError(filepath, f"Blender's glTF importer refused it ({lines[-1] if lines else e})") from None
    finally:
        props.enabled, props.node = before
    if result != {"FINISHED"}:
        raise FormatError(filepath, f"Blender's glTF importer returned {result}")
    return import_hooks.LAST_REPORT
