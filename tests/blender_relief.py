"""Each material's relief in the open Blender file, read back as plain data, for the add-on's
tests (tests/test_blender.py, tests/test_blender_real.py)."""

from __future__ import annotations

import bpy
import numpy as np

CHANNELS = {"Red": 0, "Green": 1, "Blue": 2, "Alpha": 3}


def relief_nodes() -> dict:
    """Each material's relief as plain data: node kind, factor, space, midlevel, image, wrap, UV map,
    and ``red``: the heights it reads (the linked channel: Color's red, a Separate Color output,
    or the image's Alpha), in image order."""
    out = {}
    for mat in bpy.data.materials:
        if mat.node_tree is None:
            continue
        for node in mat.node_tree.nodes:
            if node.bl_idname not in ("ShaderNodeDisplacement", "ShaderNodeBump") or not node.inputs["Height"].links:
                continue
            link = node.inputs["Height"].links[0]
            sep, channel = link.from_node, CHANNELS.get(link.from_socket.name, 0)
            img = sep.inputs[0].links[0].from_node if sep.bl_idname == "ShaderNodeSeparateColor" else sep
            if img.bl_idname != "ShaderNodeTexImage":
                continue  # a procedural height
            uv = img.inputs["Vector"].links[0].from_node if img.inputs["Vector"].links else None
            mapping = None
            if uv is not None and uv.bl_idname == "ShaderNodeMapping":
                mapping = [tuple(uv.inputs[k].default_value) if k in uv.inputs else None
                           for k in ("Location", "Rotation", "Scale")]
                uv = uv.inputs["Vector"].links[0].from_node if uv.inputs["Vector"].links else None
            w, h = img.image.size
            if not w * h:
                continue  # an image Blender cannot read (the broken one)
            pixels = np.empty(w * h * img.image.channels, np.float32)
            img.image.pixels.foreach_get(pixels)
            out[mat.name] = {
                "node": "DISPLACEMENT" if node.bl_idname == "ShaderNodeDisplacement" else "BUMP",
                "factor": node.inputs["Scale" if "Scale" in node.inputs else "Distance"].default_value,
                "space": getattr(node, "space", "WORLD"), "extension": img.extension,
                "midlevel": node.inputs["Midlevel"].default_value if "Midlevel" in node.inputs else None,
                "uv_map": uv.uv_map if uv is not None and uv.bl_idname == "ShaderNodeUVMap" else None,
                "mapping": mapping, "image": img.image.name,
                "red": pixels.reshape(h, w, -1)[::-1, :, min(channel, img.image.channels - 1)].copy(),
                "colorspace": img.image.colorspace_settings.name}
    return out
