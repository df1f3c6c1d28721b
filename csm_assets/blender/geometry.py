"""The triangles of a material in Blender's scene, as :func:`csm_assets.depth.world_per_uv` takes
them; and which UV map (its glTF texCoord) a material's heights use on each mesh.

Exporter and importer measure the same way, so a relief exported and imported back keeps its
Scale/Distance: positions in object space for a Displacement node in object space (the mesh as
the glTF stores it, before its node's transform), in world space for a Bump node or a
Displacement node in world space.
"""

from __future__ import annotations

import numpy as np


def uses(obj, material) -> bool:
    """Whether mesh object ``obj`` has ``material`` in one of its slots."""
    return obj.type == "MESH" and any(_same(s.material, material) for s in obj.material_slots)


def _same(a, b) -> bool:
    return a is not None and b is not None and a.original == b.original


def uv_layer(mesh, uv_map: str | None):
    """The UV layer ``uv_map`` names (None: the active render one, as glTF's exporter takes it);
    None when the mesh has no such layer."""
    layers = mesh.uv_layers
    if uv_map is not None:
        return layers.get(uv_map)
    return next((layer for layer in layers if layer.active_render), layers[0] if len(layers) else None)


def has_ngons(mesh) -> bool:
    """Whether ``mesh`` has faces of more than 4 corners: Blender computes no tangents for it
    (``Mesh.calc_tangents`` takes triangles and quads only), so glTF's exporter writes none."""
    sizes = np.empty(len(mesh.polygons), np.int64)
    mesh.polygons.foreach_get("loop_total", sizes)
    return bool(len(sizes)) and int(sizes.max()) > 4


def tex_coord(mesh, uv_map: str | None) -> int | None:
    """The glTF texCoord of the UV map on ``mesh`` (glTF's exporter writes every UV map, in order)."""
    layer = uv_layer(mesh, uv_map)
    return None if layer is None else list(mesh.uv_layers).index(layer)


def material_triangles(obj, mesh, material, uv_map: str | None, space: str, uv_scale=(1.0, 1.0)):
    """``(positions (L, 3), uvs (L, 2), faces (T, 3))`` of the triangles of ``mesh`` (``obj``'s
    mesh data, or its evaluated copy) in the slots holding ``material``; faces index loops.
    space: "OBJECT" or "WORLD" (``obj.matrix_world`` applied). uv_scale: a texture transform's
    scale, applied to the uvs (the step map is sampled at transformed uvs: only their scale
    changes areas). None without the UV map."""
    layer = uv_layer(mesh, uv_map)
    if layer is None:
        return None
    slots = [i for i, s in enumerate(obj.material_slots) if _same(s.material, material)]
    mesh.calc_loop_triangles()
    n_tris, n_loops = len(mesh.loop_triangles), len(mesh.loops)
    tris = np.empty(n_tris * 3, np.int64)
    mesh.loop_triangles.foreach_get("loops", tris)
    mat_index = np.empty(n_tris, np.int64)
    mesh.loop_triangles.foreach_get("material_index", mat_index)
    faces = tris.reshape(-1, 3)[np.isin(mat_index, slots)]
    co = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    if space == "WORLD":
        m = np.array(obj.matrix_world, np.float64)
        co = co @ m[:3, :3].T + m[:3, 3]
    loop_vertex = np.empty(n_loops, np.int64)
    mesh.loops.foreach_get("vertex_index", loop_vertex)
    uvs = np.empty(n_loops * 2, np.float64)
    layer.data.foreach_get("uv", uvs)
    return co[loop_vertex], uvs.reshape(-1, 2) * np.asarray(uv_scale, np.float64), faces


def export_mesh(obj, mesh, material, uv_map: str | None):
    """The triangles of ``mesh`` holding ``material`` as glTF's exporter writes them, as a
    :class:`csm_assets.scene.Mesh` for :func:`csm_assets.exporters.confirm_material`: one vertex
    per loop, in object space, with Blender's normals, its MikkTSpace tangents of UV map ``uv_map``
    (``Mesh.calc_tangents``: w is the bitangent sign) and the uvs with v flipped (glTF's
    top-left origin). None without the UV map or with faces of more than 4 corners."""
    from ..scene import Mesh

    layer = uv_layer(mesh, uv_map)
    if layer is None or has_ngons(mesh):
        return None
    positions, uvs, faces = material_triangles(obj, mesh, material, uv_map, "OBJECT")
    mesh.calc_tangents(uvmap=layer.name)
    n = len(mesh.loops)
    normals, tangents, signs = np.empty(n * 3), np.empty(n * 3), np.empty(n)
    mesh.loops.foreach_get("normal", normals)
    mesh.loops.foreach_get("tangent", tangents)
    mesh.loops.foreach_get("bitangent_sign", signs)
    mesh.free_tangents()
    return Mesh(f"{obj.name} / {material.name}", positions, faces, normals.reshape(-1, 3),
                uvs * [1.0, -1.0] + [0.0, 1.0], np.column_stack([tangents.reshape(-1, 3), signs]))
