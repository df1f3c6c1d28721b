"""Tangents of converted meshes and what makes them doubtful (degenerate triangles,
non-manifold edges); triangle areas, which the depth of a material also uses."""

from __future__ import annotations

import numpy as np

from .. import depth
from ..scene import Scene


def make_tangents(scene: Scene, opts) -> list[str]:
    """MikkTSpace tangents for meshes whose material got a step map and that have none
    (or all, with ``regenerate_tangents``). Returns the names of the meshes done."""
    from .frames import mikktspace_tangents

    done = []
    for mesh in scene.meshes:
        if mesh.material is None or mesh.material.csm is None:
            continue
        if mesh.tangents is not None and not opts.regenerate_tangents:
            continue
        if mesh.normals is None:
            scene.warn("CSM201", "no normals, so no tangents (viewers ignore tangents without normals); "
                       "add normals to it", f"mesh {mesh.name}")
            continue
        mesh.corner_tangents = mikktspace_tangents(mesh.positions, mesh.normals, mesh.uvs, mesh.faces,
                                                   flip_v=mesh.uv_origin == "top-left")
        done.append(mesh.name)
    return done


def warn_mesh_problems(scene: Scene) -> None:
    """:func:`mesh_problems` of every converted mesh, one warning each, whether tangents are made
    for it or not (OBJ stores none; a glTF may bring its own): triangles without area are left
    out of the relief and of MikkTSpace, so they are counted, never dropped silently."""
    for mesh in scene.meshes:
        if mesh.material is not None and mesh.material.csm is not None:
            for code, problem in mesh_problems(mesh):
                scene.warn(code, problem, f"mesh {mesh.name} (material {mesh.material.name!r})")


def warn_clamped_uvs(scene: Scene, margin: float = 1e-4) -> None:
    """One warning per converted mesh whose triangles have uvs outside [0, 1] (beyond
    ``margin``) along an axis its step map does not tile: the shader treats rays there as
    leaving the relief (they miss), and ``verify`` can measure none of those pixels."""
    for mesh in scene.meshes:
        if mesh.material is None or mesh.material.csm is None or mesh.material.csm.tiles:  # UDIM: CSM108
            continue
        corners = mesh.uvs[mesh.faces.reshape(-1)]
        out = [f"{int(n)} of {len(corners)} along {axis}" for k, axis in enumerate("uv")
               if not mesh.material.csm.tile[k]
               and (n := ((corners[:, k] < -margin) | (corners[:, k] > 1 + margin)).sum())]
        if out:
            scene.warn("CSM210", f"triangle corners with uvs outside [0, 1] on an axis that does not tile "
                       f"({', '.join(out)}): the relief is cut off there (rays miss) and verify cannot measure it; "
                       "if the texture repeats, convert with --tile",
                       f"mesh {mesh.name} (material {mesh.material.name!r})")


def mesh_problems(mesh) -> list[tuple[str, str]]:
    """What in a mesh makes tangents doubtful, as (warning code, text): degenerate triangles (no
    area, or no uv area: MikkTSpace borrows their frames) and edges shared by more than two triangles."""
    area, uv_area = triangle_areas(mesh)
    problems = []
    if (area == 0).any() or (uv_area == 0).any():
        problems.append(("CSM205", f"{int((area == 0).sum())} triangle(s) without area and "
                         f"{int((uv_area == 0).sum())} without uv area: they show no relief, and their tangents "
                         "are borrowed from neighbours"))
    edges = np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if (counts > 2).any():
        problems.append(("CSM206", f"{int((counts > 2).sum())} non-manifold edge(s) (shared by more than two "
                         "triangles)"))
    return problems


def triangle_areas(mesh) -> tuple[np.ndarray, np.ndarray]:
    """World and uv areas of a mesh's triangles, float64 ``(F,)`` each
    (:func:`csm_assets.depth.triangle_areas`)."""
    return depth.triangle_areas(mesh.positions, mesh.uvs, mesh.faces)
