"""A Blender scene built with bpy for the add-on's tests: meshes with Displacement and Bump
materials (object and world space, scaled objects), a material without height, mirrored uvs,
two uv sets (the relief on the second, which is not the active one), a material naming its
height image in a custom property, and materials the add-on must warn about (procedural height,
no uvs, a packed image that is no image, a Mapping node of Vector type, a cylinder's 16-sided caps,
for which Blender computes no tangents). Curved: a smooth UV sphere and a scaled cube. A Point Mapping node
(tiling the heights 2 x 3, turned and shifted) is carried as KHR_texture_transform."""

from __future__ import annotations

from pathlib import Path

import bmesh
import bpy

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
COBBLES = SAMPLES / "cobbles.png"          # 256x192, 16-bit grey
BRICKS = SAMPLES / "bricks_height.png"     # 128x128, 8-bit grey

# material -> (node, factor, object scale, space) as built below: what the files must carry
CONVERTED = {
    "displaced": ("DISPLACEMENT", 0.06, (2.0, 1.5, 1.0), "OBJECT"),
    "bumped": ("BUMP", 0.03, (3.0, 3.0, 1.0), "WORLD"),
    "mirrored": ("DISPLACEMENT", 0.04, (1.0, 1.0, 1.0), "OBJECT"),
    "second_uv": ("DISPLACEMENT", 0.05, (1.0, 1.0, 1.0), "OBJECT"),
    "by_property": ("PROPERTY", None, (1.0, 1.0, 1.0), "OBJECT"),
    "mapped": ("DISPLACEMENT", 0.05, (1.0, 1.0, 1.0), "OBJECT"),
    "sphere": ("DISPLACEMENT", 0.05, (1.0, 1.0, 1.0), "OBJECT"),
    "boxed": ("BUMP", 0.04, (1.0, 2.0, 0.5), "WORLD"),
}
MAPPING = {"Location": (0.25, 0.1, 0.0), "Rotation": (0.0, 0.0, 0.3), "Scale": (2.0, 3.0, 1.0)}  # of "mapped"
WARNED = ("procedural", "no_uvs", "broken_pack", "vector_mapped", "ngons")


def grid(name: str, *, n: int = 6, uvs: bool = True, location=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0)):
    """A flat n x n grid 2 x 2 units wide in object space, uvs [0, 1] across it."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    if uvs:
        bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_grid(bm, x_segments=n, y_segments=n, size=1.0, calc_uvs=uvs)
    bm.to_mesh(me)
    bm.free()
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.scale = location, scale
    bpy.context.scene.collection.objects.link(ob)
    return ob


def image_node(tree, path: Path, extension: str = "REPEAT", uv_map: str | None = None):
    img = tree.nodes.new("ShaderNodeTexImage")
    img.image = bpy.data.images.load(str(path), check_existing=True)
    img.image.colorspace_settings.name = "Non-Color"
    img.extension = extension
    if uv_map:
        uv = tree.nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_map
        tree.links.new(uv.outputs["UV"], img.inputs["Vector"])
    return img


def node_material(name: str):
    """A new material with its default node tree (Blender before 5.0 makes it without one)."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    return mat


def displaced(name: str, height_socket_of, scale: float, *, space: str = "OBJECT", midlevel: float = 0.5):
    mat = node_material(name)
    tree = mat.node_tree
    disp = tree.nodes.new("ShaderNodeDisplacement")
    disp.space = space
    disp.inputs["Scale"].default_value = scale
    disp.inputs["Midlevel"].default_value = midlevel
    tree.links.new(height_socket_of(tree), disp.inputs["Height"])
    tree.links.new(disp.outputs["Displacement"], tree.nodes["Material Output"].inputs["Displacement"])
    return mat


def bumped(name: str, path: Path, distance: float, extension: str):
    mat = node_material(name)
    tree = mat.node_tree
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = distance
    tree.links.new(image_node(tree, path, extension).outputs["Color"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], tree.nodes["Principled BSDF"].inputs["Normal"])
    return mat


def build() -> None:
    """The whole scene, in a fresh empty file."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    a = grid("disp_plane", scale=CONVERTED["displaced"][2])
    a.data.materials.append(displaced("displaced", lambda t: image_node(t, COBBLES).outputs["Color"], 0.06))

    b = grid("bump_plane", location=(7.0, 0.0, 0.0), scale=CONVERTED["bumped"][2])
    b.data.materials.append(bumped("bumped", BRICKS, 0.03, "EXTEND"))

    m = grid("mirror_plane", location=(0.0, 4.0, 0.0))
    uv = m.data.uv_layers["UVMap"]
    for loop in uv.data:  # the left half mirrors the right: u = |2u - 1|
        loop.uv = (abs(2.0 * loop.uv[0] - 1.0), loop.uv[1])
    m.data.materials.append(displaced("mirrored", lambda t: image_node(t, BRICKS).outputs["Color"], 0.04))

    two = grid("two_uvs", location=(0.0, -4.0, 0.0))
    first = two.data.uv_layers["UVMap"]
    detail = two.data.uv_layers.new(name="detail")
    for i, loop in enumerate(detail.data):  # the second set turned a quarter: its u runs along y
        u, v = first.data[i].uv
        detail.data[i].uv = (v, 1.0 - u)
    two.data.uv_layers.active = first  # the relief's uv set is not the active one
    two.modifiers.new("triangulate", "TRIANGULATE")  # exported as its evaluated mesh with export_apply
    two.data.materials.append(displaced(
        "second_uv", lambda t: image_node(t, COBBLES, uv_map="detail").outputs["Color"], 0.05))

    p = grid("property_plane", location=(4.0, 4.0, 0.0))
    mat = node_material("by_property")
    bpy.data.images.load(str(BRICKS), check_existing=True)
    mat["csm_height"] = BRICKS.name
    p.data.materials.append(mat)

    plain = grid("plain_plane", location=(-7.0, 0.0, 0.0))
    plain.data.materials.append(node_material("plain"))

    noise = grid("noise_plane", location=(-4.0, 4.0, 0.0))
    noise.data.materials.append(displaced("procedural", lambda t: t.nodes.new("ShaderNodeTexNoise").outputs["Fac"],
                                          0.05))
    bare = grid("bare_plane", uvs=False, location=(-4.0, -4.0, 0.0))
    bare.data.materials.append(displaced("no_uvs", lambda t: image_node(t, BRICKS).outputs["Color"], 0.05))

    broken = bpy.data.images.new("broken.png", 4, 4)
    broken.source = "FILE"
    broken.filepath = "//broken.png"
    broken.pack(data=b"not a png at all", data_len=16)

    def broken_socket(tree):
        img = tree.nodes.new("ShaderNodeTexImage")
        img.image = broken
        return img.outputs["Color"]

    bad = grid("broken_plane", location=(4.0, -4.0, 0.0))
    bad.data.materials.append(displaced("broken_pack", broken_socket, 0.05))

    def mapping_socket(kind):
        def socket(tree):
            img = image_node(tree, BRICKS)
            mapping = tree.nodes.new("ShaderNodeMapping")
            mapping.vector_type = kind
            for name, value in MAPPING.items():
                if name in mapping.inputs:
                    mapping.inputs[name].default_value = value
            tree.links.new(tree.nodes.new("ShaderNodeUVMap").outputs["UV"], mapping.inputs["Vector"])
            tree.links.new(mapping.outputs["Vector"], img.inputs["Vector"])
            return img.outputs["Color"]
        return socket

    mapped = grid("mapped_plane", location=(-7.0, 4.0, 0.0))
    mapped.data.materials.append(displaced("mapped", mapping_socket("POINT"), 0.05))
    vector = grid("vector_mapped_plane", location=(-7.0, -4.0, 0.0))
    vector.data.materials.append(displaced("vector_mapped", mapping_socket("VECTOR"), 0.05))

    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=1.0, location=(0.0, 8.0, 0.0))
    sphere = bpy.context.active_object
    sphere.data.polygons.foreach_set("use_smooth", [True] * len(sphere.data.polygons))
    sphere.data.materials.append(displaced("sphere", lambda t: image_node(t, COBBLES).outputs["Color"], 0.05))
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(4.0, 8.0, 0.0), scale=CONVERTED["boxed"][2])
    bpy.context.active_object.data.materials.append(bumped("boxed", BRICKS, 0.04, "REPEAT"))
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, location=(-4.0, 8.0, 0.0))
    bpy.context.active_object.data.materials.append(
        displaced("ngons", lambda t: image_node(t, BRICKS).outputs["Color"], 0.03))
