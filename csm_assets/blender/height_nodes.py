"""Where a Blender material's heights come from: its node tree read as data (no bpy import).

:func:`find_height` looks, in order, for a Displacement node wired to the active Material
Output's Displacement, a Bump node upstream of its Surface, then the material's custom
property ``csm_height`` naming an image (``csm_depth``, optional: its texture-space depth,
else 0.1 as ``convert --height``). The height must come from an Image Texture node (its Color,
or its Alpha, or one channel through Separate Color), sampled at a UV map (through a Point Mapping node,
carried as KHR_texture_transform); anything else is a
:class:`NoHeight` with the reason, which the exporter turns into a warning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..checks import FLOAT32_MAX as MAX_DEPTH
from ..height_source import DEFAULT_DEPTH

PROPERTY = "csm_height"        # material custom property: the name of a height image
DEPTH_PROPERTY = "csm_depth"   # material custom property: texture-space depth with csm_height
CHANNELS = {"Red": 0, "Green": 1, "Blue": 2, "R": 0, "G": 1, "B": 2}


class NoHeight(Exception):
    """A material whose relief cannot be converted, and why (a warning, not an error)."""


@dataclass
class HeightSource:
    """A material's height image and how the material uses it.

    node: "DISPLACEMENT", "BUMP" or "PROPERTY"; image: the bpy Image; channel: None (the Color
    output: luminance of a colour image), 0..2 through Separate Color, 3 the Alpha output;
    invert: heights are ``1 - value`` (Bump's Invert, a negative Scale); factor: Scale or
    Distance in model units per unit of value (None for PROPERTY: ``depth`` is texture-space);
    strength: Bump's Strength in (0, 1] (1 otherwise), which scales its Distance (:attr:`depth_factor`);
    space: "OBJECT" (Displacement's default) or "WORLD" (Bump, or Displacement in world space);
    midlevel: Displacement's; uv_map: the UV map's name (None: the active render one); mapping: a
    Mapping node's offset, Z rotation and scale between the UV map and the image; extension:
    the Image Texture node's (REPEAT, EXTEND, CLIP, MIRROR); image_node: that node (None for PROPERTY).
    """

    node: str
    image: object
    channel: int | None = None
    invert: bool = False
    factor: float | None = None
    depth: float | None = None
    space: str = "OBJECT"
    midlevel: float = 0.0
    uv_map: str | None = None
    mapping: dict | None = None
    extension: str = "REPEAT"
    image_node: object = None
    strength: float = 1.0

    @property
    def depth_factor(self) -> float | None:
        """The factor the relief's depth is measured from: Scale, or Distance times Strength (Bump
        blends its bumped normal with the surface's by Strength, which for gentle slopes is the
        same as scaling the heights)."""
        return None if self.factor is None else self.factor * self.strength


def find_height(material) -> HeightSource | None:
    """The height source of ``material`` (a bpy Material), None when it has none, NoHeight
    when it has one that cannot be converted."""
    tree = material.node_tree
    output = _output(tree) if tree is not None else None
    if output is not None:
        disp = _source(output.inputs.get("Displacement"))
        if disp is not None:
            node = disp[0]
            if node.bl_idname == "ShaderNodeDisplacement":
                return _displacement(node)
            raise NoHeight(f"its Material Output's Displacement comes from {_name(node)}, not a Displacement "
                           "node (vector displacement is not converted)")
        bump = _first_bump(output)
        if bump is not None:
            return _bump(bump)
    if material.get(PROPERTY) is not None:
        return _property(material)
    return None


def _output(tree):
    for target in ("ALL", "EEVEE", "CYCLES"):
        node = tree.get_output_node(target)
        if node is not None:
            return node
    return None


def _source(socket):
    """(node, output socket) feeding ``socket``, through reroutes; None when unlinked."""
    while socket is not None and socket.is_linked:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        return node, link.from_socket
    return None


def _name(node) -> str:
    return f"node {node.name!r} ({node.bl_idname})"


def _first_bump(output):
    """The first Bump node (breadth first) upstream of the output's Surface with its Height linked."""
    seen, queue = set(), [output]
    while queue:
        node = queue.pop(0)
        for socket in node.inputs:
            for link in socket.links:
                up = link.from_node
                if up.name in seen:
                    continue
                seen.add(up.name)
                if up.bl_idname == "ShaderNodeBump" and up.inputs["Height"].is_linked and not up.mute:
                    return up
                queue.append(up)
    return None


def _factor(node, name: str) -> float:
    socket = node.inputs[name]
    if socket.is_linked:
        raise NoHeight(f"{_name(node)} has its {name} wired to other nodes; only a fixed {name} is converted")
    value = float(socket.default_value)
    if not math.isfinite(value):
        raise NoHeight(f"{_name(node)} has {name} {value:g}; only a finite {name} is converted")
    return value


def _displacement(node) -> HeightSource:
    scale = _factor(node, "Scale")
    if scale == 0:
        raise NoHeight(f"{_name(node)} has Scale 0: it displaces nothing")
    source = _image_source(node.inputs["Height"], node)
    source.node = "DISPLACEMENT"
    source.factor, source.invert = abs(scale), scale < 0
    source.midlevel = _factor(node, "Midlevel")
    source.space = "WORLD" if node.space == "WORLD" else "OBJECT"
    return source


def _bump(node) -> HeightSource:
    distance, strength = _factor(node, "Distance"), _factor(node, "Strength")
    if not strength > 0 or distance == 0:
        what = f"Strength {strength:g}" if not strength > 0 else "Distance 0"
        raise NoHeight(f"{_name(node)} has {what}: it bumps nothing")
    source = _image_source(node.inputs["Height"], node)
    source.node, source.space, source.strength = "BUMP", "WORLD", min(strength, 1.0)
    source.factor, source.invert = abs(distance), (distance < 0) != bool(node.invert)
    return source


def depth_label(source: HeightSource) -> str:
    """What a material's texture-space depth came from, as the user set it (for messages)."""
    if source.factor is None:
        return f"its custom property {DEPTH_PROPERTY}"
    what = "Distance" if source.node == "BUMP" else "Scale"
    return f"the depth from its {source.node.title()} {what} {source.factor:g} (over the mesh's size per uv unit)"


def _property(material) -> HeightSource:
    import bpy

    name = material.get(PROPERTY)
    image = bpy.data.images.get(name) if isinstance(name, str) else None
    if image is None:
        raise NoHeight(f"its custom property {PROPERTY}={name!r} names no image of this file")
    depth = material.get(DEPTH_PROPERTY, DEFAULT_DEPTH)
    if isinstance(depth, bool) or not isinstance(depth, (int, float)) or not 0 < depth <= MAX_DEPTH:
        raise NoHeight(f"its custom property {DEPTH_PROPERTY}={depth!r} is no texture-space depth (a finite "
                       f"number > 0, at most {MAX_DEPTH:.4g})")
    return HeightSource("PROPERTY", image, depth=float(depth))


def _image_source(socket, consumer) -> HeightSource:
    found = _source(socket)
    if found is None:
        raise NoHeight(f"{_name(consumer)} has no height wired to it")
    node, out = found
    channel = None
    if node.bl_idname in ("ShaderNodeSeparateColor", "ShaderNodeSeparateRGB"):
        if getattr(node, "mode", "RGB") != "RGB":
            raise NoHeight(f"{_name(node)} separates {node.mode}, not RGB channels")
        channel = CHANNELS[out.name]
        found = _source(node.inputs[0])
        if found is None:
            raise NoHeight(f"{_name(node)} has no image wired to it")
        node, out = found
        if out.name != "Color":
            raise NoHeight(f"{_name(node)}'s {out.name} output is separated; only an image's Color is")
    if node.bl_idname != "ShaderNodeTexImage":
        raise NoHeight(f"its height comes from {_name(node)}, not an Image Texture node (procedural "
                       "heights are not converted: bake them to an image)")
    if node.image is None:
        raise NoHeight(f"{_name(node)} has no image")
    if out.name == "Alpha":
        channel = 3
    uv_map, mapping = _uv_map(node)
    return HeightSource("", node.image, channel=channel, uv_map=uv_map, mapping=mapping, extension=node.extension,
                        image_node=node)


def _uv_map(image_node) -> tuple[str | None, dict | None]:
    """(UV map, mapping) the image is sampled at: a UV Map node's (or a Geometry Attribute node's)
    name, None for the active render UV map (nothing wired, or a Texture Coordinate's UV); the
    Mapping node between, as ``{"offset", "rotation", "scale"}`` (Point type, rotation about Z only)."""
    found = _source(image_node.inputs["Vector"])
    mapping = None
    if found is not None and found[0].bl_idname == "ShaderNodeMapping":
        node = found[0]
        mapping = _mapping(node)
        found = _source(node.inputs["Vector"])
    if found is None:
        return None, mapping
    node, out = found
    if node.bl_idname == "ShaderNodeUVMap":
        return node.uv_map or None, mapping
    if node.bl_idname == "ShaderNodeTexCoord" and out.name == "UV":
        return None, mapping
    if node.bl_idname == "ShaderNodeAttribute" and node.attribute_type == "GEOMETRY" and node.attribute_name:
        return node.attribute_name, mapping
    raise NoHeight(f"{_name(image_node)} is sampled at {_name(node)}'s {out.name}, not at a UV map (the relief "
                   "needs texture coordinates)")


def _mapping(node) -> dict:
    """A Mapping node's transform, where glTF's KHR_texture_transform can say it."""
    if node.vector_type != "POINT":
        raise NoHeight(f"{_name(node)} is of type {node.vector_type}; only a Point mapping is carried to the "
                       "step map (as KHR_texture_transform)")
    inputs = [node.inputs[k] for k in ("Location", "Rotation", "Scale") if k in node.inputs]
    if any(i.is_linked for i in inputs):
        raise NoHeight(f"{_name(node)} has inputs wired to other nodes; only fixed values are carried")
    loc, rot, scale = (node.inputs[k].default_value for k in ("Location", "Rotation", "Scale"))
    if rot[0] or rot[1]:
        raise NoHeight(f"{_name(node)} rotates about X or Y; only a rotation about Z is carried")
    if scale[0] == 0 or scale[1] == 0:
        raise NoHeight(f"{_name(node)} scales the UVs by 0")
    return {"offset": [loc[0], loc[1]], "rotation": rot[2], "scale": [scale[0], scale[1]]}
