"""What the renderer draws: :class:`Mesh` (triangles with a tangent frame) and the unit :func:`quad`.

World conventions of :func:`quad`: the polygon lies in the plane z = 0 facing +z,
u grows along +x and v along -y, so seen from above with y up the texture reads
as an image does; heights hang under it down to ``z = -depth``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Mesh:
    """Triangles with a tangent frame.

    positions, normals: float32 ``(N, 3)``; tangents: float32 ``(N, 4)`` (glTF:
    unit +u direction, w = +/-1 with the bitangent cross(normal, tangent) * w
    pointing up the image, towards -v, as MikkTSpace gives it on glTF uvs); uvs:
    float32 ``(N, 2)``; indices: uint32 ``(M, 3)``.
    """

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    uvs: np.ndarray
    indices: np.ndarray


def quad(size: float = 1.0) -> Mesh:
    """A ``size`` x ``size`` square centred on the origin in z = 0 (see module doc)."""
    s = 0.5 * float(size)
    pos = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]], np.float32)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    tan = np.tile(np.array([1, 0, 0, 1], np.float32), (4, 1))  # bitangent cross(z, x) = +y = -v
    return Mesh(pos, nrm, tan, uvs, np.array([[0, 1, 2], [0, 2, 3]], np.uint32))


def quad_field_to_world(size: float, depth: float) -> np.ndarray:
    """The ``(4, 4)`` matrix taking :func:`quad`'s texture space (u, v, height) to world."""
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1], m[2, 2], m[3, 3] = size, -size, depth, 1.0
    m[:3, 3] = [-0.5 * size, 0.5 * size, -depth]
    return m


def uv_scale(mesh: Mesh) -> float:
    """uv units per world unit of a mesh (square root of uv area over world area); 0 without area."""
    from ..depth import world_per_uv

    scale = world_per_uv([(mesh.positions, mesh.uvs, np.arange(len(mesh.positions)).reshape(-1, 3))])
    return 0.0 if scale is None else 1.0 / scale



def uv_frame(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """A Material's 2x2 ``uv_per_world`` from the surface derivatives: ``du``, ``dv`` world
    ``(..., 3)`` dP/du, dP/dv of the uvs the step map is placed by. It is their inverse written
    along the tangent (MikkTSpace's: along du) and the bitangent towards +v, ``(..., 2, 2)``;
    not diagonal where the placement shears the texture (a rotated, non-uniformly scaled
    texture transform puts u and v off right angles on the surface)."""
    du, dv = np.asarray(du, float), np.asarray(dv, float)
    lu = np.linalg.norm(du, axis=-1)
    along = np.sum(dv * du, axis=-1) / lu
    across = np.sqrt(np.maximum(np.sum(dv * dv, axis=-1) - along**2, 0.0))
    zero = np.zeros_like(lu)
    return np.linalg.inv(np.stack([np.stack([lu, along], -1), np.stack([zero, across], -1)], -2))


def uv_matrix(uv_per_world) -> np.ndarray:
    """A Material's ``uv_per_world`` as the shader's 2x2: a pair is its diagonal."""
    m = np.asarray(uv_per_world, float)
    return np.diag(m) if m.shape == (2,) else m
