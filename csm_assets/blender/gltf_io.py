"""The pieces of Blender's glTF add-on (io_scene_gltf2) the hooks build with, under their names
in Blender 4.3 and later and, before that, in 4.2 (whose modules carry ``gltf2_`` prefixes).

Export: the glTF property classes (``gltf2_io``), ``Extension``, ``BinaryData`` (bytes for the
.glb's buffer), ``ImageData`` (an image file beside the .gltf), ``set_real_uri`` (4.3+: names the
file now; None in 4.2, whose exporter names it when writing) and the Mapping node to
KHR_texture_transform conversion. Import: ``MaterialHelper``, ``texture`` (the importer's own
Image Texture setup), ``TextureInfo`` and ``BinaryData`` (an embedded image's bytes).
"""

from __future__ import annotations

import importlib
from types import SimpleNamespace


def _first(*names: str):
    """The first of the modules ``names`` (relative to io_scene_gltf2) that imports."""
    for name in names:
        try:
            return importlib.import_module(f"io_scene_gltf2.{name}")
        except ImportError:
            continue
    raise ImportError(f"Blender's glTF add-on has none of io_scene_gltf2.{' / '.join(names)}")


def exporter() -> SimpleNamespace:
    gltf2_io = importlib.import_module("io_scene_gltf2.io.com.gltf2_io")
    extensions = importlib.import_module("io_scene_gltf2.io.com.gltf2_io_extensions")
    binary = _first("io.exp.binary_data", "io.exp.gltf2_io_binary_data")
    image = _first("io.exp.image_data", "io.exp.gltf2_io_image_data")
    conversion = _first("blender.com.conversion", "blender.com.gltf2_blender_conversion")
    gather_image = _first("blender.exp.material.image", "blender.exp.material.gltf2_blender_gather_image")
    return SimpleNamespace(gltf2_io=gltf2_io, Extension=extensions.Extension, BinaryData=binary.BinaryData,
                           ImageData=image.ImageData, set_real_uri=getattr(gather_image, "set_real_uri", None),
                           texture_transform=conversion.texture_transform_blender_to_gltf)


def importer() -> SimpleNamespace:
    helpers = _first("blender.imp.material_utils", "blender.imp.gltf2_blender_material_utils")
    texture = _first("blender.imp.texture", "blender.imp.gltf2_blender_texture")
    gltf2_io = importlib.import_module("io_scene_gltf2.io.com.gltf2_io")
    binary = importlib.import_module("io_scene_gltf2.io.imp.gltf2_io_binary")
    return SimpleNamespace(MaterialHelper=helpers.MaterialHelper, texture=texture.texture,
                           TextureInfo=gltf2_io.TextureInfo, BinaryData=binary.BinaryData)
