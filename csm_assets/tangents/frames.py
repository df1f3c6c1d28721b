"""Tangent frames for triangle meshes (MikkTSpace), and corner welding for vertex buffers.

``mikktspace_tangents`` gives the per-corner tangents and handedness that the reference
mikktspace.c computes (``genTangSpaceDefault``, see ``csm_assets.tangents.mikktspace``), which the
glTF specification and every major engine expect. Where MikkTSpace leaves a frame
undefined (a zero tangent; its default ``(1, 0, 0)`` with sign -1 on isolated degenerate
or zero-uv-area triangles; NaN input), ``orthonormalize=True`` (the default) projects the
tangent onto the normal's plane and falls back to the coordinate axis least aligned with
the normal, so every output is a finite unit vector orthogonal to the normal with
``w = +-1``; elsewhere that step changes nothing but float rounding. Quads are not
taken: triangulate first (MikkTSpace's frames then follow the chosen diagonal).

``weld_corners`` turns per-corner attributes into an indexed vertex buffer, splitting a
vertex only where an attribute differs (glTF holds one tangent per vertex).
"""

from __future__ import annotations

from typing import Mapping, NamedTuple

import numpy as np

from .mikktspace import mikktspace


def mikktspace_tangents(positions, normals, uvs, faces=None, *, flip_v: bool = False,
                        orthonormalize: bool = True) -> np.ndarray:
    """Per-corner MikkTSpace tangents of a triangle mesh.

    Args:
        positions: ``(V, 3)``, any float dtype (used as float32).
        normals: ``(V, 3)``, unit length (MikkTSpace assumes so; they also take part in
            identifying corners).
        uvs: ``(V, 2)``.
        faces: int ``(F, 3)`` indices into those arrays, or None when they are an unindexed
            triangle list (``V = 3F`` rows, or ``(F, 3, k)``).
        flip_v (bool): the uvs have glTF's origin (top-left, v down). MikkTSpace works in
            OpenGL's convention (v up), so the generator then sees ``(u, -v)``, which gives the
            same frames as ``(u, 1 - v)`` without rounding; tangents are unchanged and ``w``
            flips, so that ``cross(n, t) * w`` points up the image (glTF's +Y up).
        orthonormalize (bool): make every frame usable (see the module docstring); False
            returns MikkTSpace's values as they are (zero or non-orthogonal tangents possible).

    Returns:
        Float32 ``(F, 3, 4)``: xyz the tangent, w the handedness (+1 or -1).

    Raises:
        ValueError: arrays of the wrong shape, or indices out of range.
    """
    p, n, uv = _corner_arrays(positions, normals, uvs, faces)
    if flip_v:
        uv = uv * np.array([1, -1], dtype=np.float32)
    nf = p.shape[0] // 3
    if nf == 0:
        return np.zeros((0, 3, 4), np.float32)
    tang, orient = mikktspace(p, n, uv)
    out = np.empty((nf * 3, 4), np.float32)
    out[:, 3] = np.where(orient, 1.0, -1.0)
    out[:, :3] = _orthonormal(tang, n) if orthonormalize else tang
    return out.reshape(nf, 3, 4)


def _corner_arrays(positions, normals, uvs, faces):
    """float32 per-corner ``(3F, 3)``, ``(3F, 3)``, ``(3F, 2)`` arrays, validated."""
    arrays = []
    for name, a, k in (("positions", positions, 3), ("normals", normals, 3), ("uvs", uvs, 2)):
        a = np.asarray(a)
        if a.dtype.kind not in "fiu":
            raise ValueError(f"{name} must be numeric, got dtype {a.dtype}")
        if faces is None and a.ndim == 3:
            a = a.reshape(-1, a.shape[-1])
        if a.ndim != 2 or a.shape[1] != k:
            raise ValueError(f"{name} must have shape (N, {k}), got {a.shape}")
        arrays.append(a.astype(np.float32, copy=False))
    if faces is None:
        c = arrays[0].shape[0]
        if c % 3 or any(a.shape[0] != c for a in arrays):
            raise ValueError("an unindexed triangle list needs the same number of rows in "
                             f"positions, normals and uvs, a multiple of 3; got "
                             f"{[a.shape[0] for a in arrays]}")
        return [np.ascontiguousarray(a) for a in arrays]
    f = np.asarray(faces)
    if f.dtype.kind not in "iu" or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be integer (F, 3), got {f.dtype} {f.shape}")
    f = f.reshape(-1).astype(np.int64)
    for name, a in zip(("positions", "normals", "uvs"), arrays):
        if f.size and (f.min() < 0 or f.max() >= a.shape[0]):
            raise ValueError(f"faces index outside {name} (0 .. {a.shape[0] - 1})")
    return [np.ascontiguousarray(a[f]) for a in arrays]


def _orthonormal(t, n) -> np.ndarray:
    """Unit tangents float32 ``(C, 3)`` orthogonal to the normals, whatever the input."""
    t = t.astype(np.float64)
    n = n.astype(np.float64)
    with np.errstate(all="ignore"):
        nl = np.linalg.norm(n, axis=1, keepdims=True)
        nh = np.where(np.isfinite(nl) & (nl > 1e-30), n / nl, 0.0)
        nh = np.where(np.isfinite(nh), nh, 0.0)
        out = _reject(t, nh)
        bad = ~np.isfinite(out).all(axis=1)
        if bad.any():
            axis = np.eye(3)[np.argmin(np.abs(nh[bad]), axis=1)]
            out[bad] = _reject(axis, nh[bad])
    return out.astype(np.float32)


def _reject(v, nh):
    """``v`` minus its component along unit ``nh``, normalized; NaN rows where it vanishes."""
    r = v - nh * np.sum(v * nh, axis=1, keepdims=True)
    length = np.linalg.norm(r, axis=1, keepdims=True)
    return np.where(length > 1e-6 * np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30),
                    r / length, np.nan)


class Welded(NamedTuple):
    """An indexed vertex buffer made from per-corner attributes.

    Attributes:
        faces (numpy.ndarray): uint32 ``(F, 3)`` vertex indices.
        vertices (dict): name -> ``(V, ...)`` array, dtype kept.
        corner (numpy.ndarray): int64 ``(V,)``: the corner (``f * 3 + i``) each vertex was
            taken from.
    """

    faces: np.ndarray
    vertices: dict
    corner: np.ndarray


def weld_corners(corner_attributes: Mapping[str, np.ndarray]) -> Welded:
    """Merge corners whose attributes are all bitwise equal into one vertex.

    A vertex is split only where some attribute differs, as glTF needs one tangent per
    vertex. Vertices are numbered in order of first use. To keep attributes that are not
    passed (skin weights, colours) and never merge distinct source vertices, pass the source
    index too, e.g. ``{"source": faces, "tangent": t}``, and gather the rest with
    ``faces.reshape(-1)[welded.corner]``.

    Args:
        corner_attributes: name -> numeric array ``(F, 3)`` or ``(F, 3, ...)`` (e.g.
            positions, normals, uvs and the tangents of :func:`mikktspace_tangents`), one F.

    Returns:
        The Welded buffer.

    Raises:
        ValueError: no attribute, a shape other than ``(F, 3, ...)``, differing F, or a
            non-numeric array.
    """
    if not corner_attributes:
        raise ValueError("weld_corners needs at least one attribute")
    cols = []
    nf = None
    for name, a in corner_attributes.items():
        a = np.asarray(a)
        if a.ndim < 2 or a.shape[1] != 3 or (nf is not None and a.shape[0] != nf):
            raise ValueError(f"{name} must have shape (F, 3, ...) with the same F as the "
                             f"others, got {a.shape}")
        if a.dtype.hasobject:
            raise ValueError(f"{name} must be a numeric array, got dtype {a.dtype}")
        nf = a.shape[0]
        raw = np.ascontiguousarray(a).reshape(nf * 3, int(np.prod(a.shape[2:], dtype=np.int64)))
        cols.append(raw.view(np.uint8).reshape(nf * 3, raw.shape[1] * raw.itemsize))
    key = np.ascontiguousarray(np.concatenate(cols, axis=1))
    void = key.view(np.dtype((np.void, key.shape[1]))).reshape(-1)
    _, first, inverse = np.unique(void, return_index=True, return_inverse=True)
    # number vertices in order of first use
    rank = np.empty(len(first), np.int64)
    by_first = np.argsort(first)
    rank[by_first] = np.arange(len(first))
    corner = first[by_first]
    faces = rank[inverse.reshape(-1)].reshape(nf, 3).astype(np.uint32)
    vertices = {name: np.asarray(a).reshape((nf * 3,) + np.asarray(a).shape[2:])[corner]
                for name, a in corner_attributes.items()}
    return Welded(faces, vertices, corner)
