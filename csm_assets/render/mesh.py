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


def mesh_frame(mesh: Mesh) -> np.ndarray | None:
    """The 2x2 ``uv_per_world`` one draw of ``mesh`` marches with (see :func:`uv_frame`): the
    inverse of its triangles' dP/du, dP/dv written along each one's own tangent and bitangent
    (the shader's: the tangent made normal to the normal, the bitangent towards +v), averaged
    weighted by world area; None when no triangle has world area, uv area and a tangent off its
    normal. Exact on a flat mesh with affine uvs (a sheared KHR_texture_transform, uvs stretched
    unevenly along u and v); on a curved or unevenly stretched one the mean frame, as the engines
    build it per vertex."""
    f = np.asarray(mesh.indices, np.int64)
    p, uv = np.asarray(mesh.positions, float)[f], np.asarray(mesh.uvs, float)[f]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    area = np.linalg.norm(np.cross(e1, e2), axis=1)
    n = np.asarray(mesh.normals, float)[f].sum(1)
    t = np.asarray(mesh.tangents, float)[f].sum(1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    tg = t[:, :3] - n * np.sum(n * t[:, :3], axis=1, keepdims=True)
    lt = np.linalg.norm(tg, axis=1)
    ok = (np.abs(det) > 0) & (area > 0) & (lt > 1e-12 * np.maximum(np.linalg.norm(t[:, :3], axis=1), 1e-300))
    if not ok.any():
        return None
    det, e1, e2, d1, d2, n, area = det[ok], e1[ok], e2[ok], d1[ok], d2[ok], n[ok], area[ok]
    tg = tg[ok] / lt[ok, None]
    bt = -np.cross(n, tg) * np.where(t[ok, 3] < 0, -1.0, 1.0)[:, None]
    du = (e1 * d2[:, 1:] - e2 * d1[:, 1:]) / det[:, None]
    dv = (e2 * d1[:, :1] - e1 * d2[:, :1]) / det[:, None]
    world_per_uv = np.stack([np.stack([np.sum(du * tg, 1), np.sum(dv * tg, 1)], -1),
                             np.stack([np.sum(du * bt, 1), np.sum(dv * bt, 1)], -1)], -2)
    mean = np.einsum("i,ijk->jk", area, world_per_uv) / area.sum()
    if not (np.isfinite(mean).all() and abs(np.linalg.det(mean)) > 0):
        return None
    return np.linalg.inv(mean)


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
