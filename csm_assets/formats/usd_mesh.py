"""USD mesh geometry for conversion: triangles, uvs, normals and existing tangents of a
``UsdGeom.Mesh``, checked before use.

Counts are checked against :mod:`csm_assets.limits` (VERTICES) before any array of their size is
made here; negative or inconsistent ``faceVertexCounts``/``faceVertexIndices`` and
non-finite points, uvs or normals raise FormatError naming the file, the prim and the
attribute. Existing ``primvars:tangents`` are read in any form exporters write: float3
(with ``primvars:tangentSigns``, or signs from ``primvars:bitangents``, else +1) or float4
(w = sign), any interpolation, indexed or not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from ..errors import FormatError
from ..limits import check as check_limit
from ..scene import Material, Mesh, Scene


@dataclass
class MeshRef:
    """Where a Mesh came from: the prim, and for each triangle corner the face-vertex
    (index into ``faceVertexIndices``) it stands for, ``(F, 3)``; ``face_vertices``: N."""

    path: Sdf.Path
    corners: np.ndarray
    face_vertices: int


@dataclass
class Topology:
    """A mesh prim's checked ``points`` (P, 3), ``counts`` (faces) and ``indices`` (N)."""

    points: np.ndarray
    counts: np.ndarray
    indices: np.ndarray


def _array(scene: Scene, prim, attr: Usd.Attribute, what: str, limit_of=len):
    """An attribute's array value, its size checked against the vertex limit first."""
    value = attr.Get(Usd.TimeCode.EarliestTime())
    if value is None:
        return []
    check_limit(scene.path, "VERTICES", limit_of(value), f"{prim.GetPath()}.{attr.GetName()} ({what})")
    return value


def topology(scene: Scene, prim) -> Topology:
    """The checked points, face vertex counts and indices of a mesh prim (FormatError
    naming the file, prim and attribute when they are over the limits, negative,
    inconsistent or not finite)."""
    mesh = UsdGeom.Mesh(prim)
    where = f"mesh {prim.GetPath()}"
    counts = np.asarray(_array(scene, prim, mesh.GetFaceVertexCountsAttr(), "faces"), np.int64)
    if (counts < 0).any():
        raise FormatError(scene.path, f"{where}: faceVertexCounts holds negative counts")
    check_limit(scene.path, "VERTICES", int(counts.sum()), f"{where}.faceVertexCounts (face-vertices in all)")
    indices = np.asarray(_array(scene, prim, mesh.GetFaceVertexIndicesAttr(), "face-vertices"), np.int64)
    points = np.asarray(_array(scene, prim, mesh.GetPointsAttr(), "points"), np.float64).reshape(-1, 3)
    if counts.sum() != len(indices):
        raise FormatError(scene.path, f"{where}: faceVertexCounts add up to {int(counts.sum())} but "
                                      f"faceVertexIndices holds {len(indices)}")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(points)):
        raise FormatError(scene.path, f"{where}: faceVertexIndices holds indices outside its {len(points)} "
                                      f"points (min {indices.min()}, max {indices.max()})")
    if not np.isfinite(points[np.unique(indices)]).all():
        raise FormatError(scene.path, f"{where}.points holds NaN or infinite values")
    return Topology(points, counts, indices)


def read_mesh(scene: Scene, prim, mat: Material, st: str, subset=None) -> Mesh | None:
    """The triangles of ``prim`` bound to ``mat``: all of them, the faces of a GeomSubset
    ``(name, face indices)``, or every face but those (name ""). None (with a warning)
    when it has no usable uvs. A mesh without normals gets :func:`smooth_normals`."""
    mesh = UsdGeom.Mesh(prim)
    name = str(prim.GetPath()) + (f"/{subset[0]}" if subset and subset[0] else "")
    top = topology(scene, prim)
    points, counts, indices = top.points, top.counts, top.indices
    if (counts < 3).any():
        scene.warn("CSM207", f"{(counts < 3).sum()} face(s) with fewer than three vertices skipped "
                   f"({(counts == 0).sum()} with none)", f"mesh {name}")
    primvars = UsdGeom.PrimvarsAPI(prim)
    uv_pv = primvars.GetPrimvar(st)
    uvs = face_varying(scene, uv_pv, counts, indices, 2) if uv_pv and uv_pv.HasValue() else None
    if uvs is None:
        scene.warn("CSM202", f"no usable primvars:{st}; no tangents", f"mesh {name} (material {mat.ref!r})")
        return None
    normals = None
    n_pv = primvars.GetPrimvar("normals")
    if n_pv and n_pv.HasValue():
        normals = face_varying(scene, n_pv, counts, indices, 3)
    elif mesh.GetNormalsAttr().HasValue():
        values = np.asarray(_array(scene, prim, mesh.GetNormalsAttr(), "normals"), np.float64)
        normals = interpolate(values, str(mesh.GetNormalsInterpolation()), counts, indices, 3)
    corners, poly = fan(counts)
    if normals is None:
        normals = smooth_normals(points, indices, corners[:, [0, 2, 1]] if _left(mesh) else corners)
    scheme = str(mesh.GetSubdivisionSchemeAttr().Get() or "catmullClark")
    if scheme != "none":
        scene.warn("CSM208", f"a {scheme} subdivision surface; its tangents are made on the control cage (with "
                   "smooth normals where it has none) and approximate the limit surface's", f"mesh {name}")
    if subset is not None:
        chosen = np.isin(poly, subset[1])
        corners = corners[chosen if subset[0] else ~chosen]
        if len(corners) == 0:
            return None
    if _left(mesh):
        corners = corners[:, [0, 2, 1]]
    used = np.unique(corners)
    for label, values in ((f"primvars:{st}", uvs), ("normals", normals)):
        if values is not None and not np.isfinite(values[used]).all():
            raise FormatError(scene.path, f"mesh {prim.GetPath()}.{label} holds NaN or infinite values")
    tangents = existing_tangents(scene, prim, counts, indices)
    key = np.column_stack([indices[used], uvs[used]] + ([normals[used]] if normals is not None else []))
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    rep = used[first]  # one face-vertex per welded vertex
    lookup = np.empty(len(indices), np.int64)
    lookup[used] = inverse.reshape(-1)
    return Mesh(name, points[indices[rep]], lookup[corners], None if normals is None else normals[rep],
                uvs[rep], None if tangents is None else tangents[rep], mat, uv_origin="bottom-left",
                ref=MeshRef(prim.GetPath(), corners, len(indices)))


def _left(mesh: UsdGeom.Mesh) -> bool:
    return mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded


def smooth_normals(points: np.ndarray, indices: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Per face-vertex ``(N, 3)`` unit normals of a mesh that has none, as Hydra makes them:
    each point's area-weighted mean of its triangles' normals (``corners``: face-vertex
    triangles ``(F, 3)``, counter-clockwise). A point of no area gets (0, 0, 1)."""
    p = points[indices[corners]]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # length: twice the area
    acc = np.zeros_like(points)
    for k in range(3):
        np.add.at(acc, indices[corners[:, k]], face)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    unit = np.where(length > 0, acc / np.where(length > 0, length, 1), [0.0, 0.0, 1.0])
    return unit[indices]


def fan(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face-vertex indices ``(F, 3)`` of the fan triangulation of polygons of ``counts``,
    and the polygon of each triangle ``(F,)``."""
    starts = np.cumsum(counts) - counts
    ntri = np.maximum(counts - 2, 0)
    poly = np.repeat(np.arange(len(counts)), ntri)
    k = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = starts[poly]
    return np.stack([s, s + k, s + k + 1], 1).astype(np.int64), poly


def face_varying(scene: Scene, primvar: UsdGeom.Primvar, counts, indices, k: int | None) -> np.ndarray | None:
    """Per face-vertex values ``(N, k)`` of a primvar (``k`` None: its own tuple size),
    indexed or not, in any interpolation; None when they do not fit the mesh."""
    attr = primvar.GetAttr()
    check_limit(scene.path, "VERTICES", len(attr.Get(Usd.TimeCode.EarliestTime()) or []), f"{attr.GetPath()}")
    if primvar.IsIndexed():
        check_limit(scene.path, "VERTICES", len(primvar.GetIndices(Usd.TimeCode.EarliestTime()) or []),
                    f"{attr.GetPath()}:indices")
    try:
        values = primvar.ComputeFlattened(Usd.TimeCode.EarliestTime())
    except Exception:  # pxr raises Tf.ErrorException on out-of-range indices
        return None
    if values is None:
        return None
    try:
        array = np.asarray(values, np.float64)
    except (TypeError, ValueError):
        return None
    if array.ndim > 2:
        return None
    if k is None:
        k = array.shape[1] if array.ndim == 2 else 1
    return interpolate(array, str(primvar.GetInterpolation()), counts, indices, k)


def interpolate(values: np.ndarray, interpolation: str, counts, indices, k: int) -> np.ndarray | None:
    """Per face-vertex values ``(N, k)`` of a primvar of any interpolation (None when
    its length or tuple size does not fit)."""
    if values.size % k or (values.ndim == 2 and values.shape[1] != k):
        return None
    values = values.reshape(-1, k)
    need = {"constant": 1, "uniform": len(counts), "vertex": int(indices.max(initial=-1)) + 1,
            "varying": int(indices.max(initial=-1)) + 1, "faceVarying": len(indices)}.get(interpolation)
    if need is None or len(values) < need:
        return None
    if interpolation == "constant":
        return np.repeat(values[:1], len(indices), 0)
    if interpolation == "uniform":
        return np.repeat(values[: len(counts)], counts, 0)
    if interpolation in ("vertex", "varying"):
        return values[indices]
    return values[: len(indices)]


def existing_tangents(scene: Scene, prim, counts, indices, warn: bool = True) -> np.ndarray | None:
    """The tangents a mesh prim carries, per face-vertex ``(N, 4)`` (w = sign, +1 or -1),
    or None. Tangents that do not fit the mesh or hold non-finite or zero vectors are
    ignored (warned about when ``warn``): new ones are made."""
    primvars = UsdGeom.PrimvarsAPI(prim)
    pv = primvars.GetPrimvar("tangents")
    if not (pv and pv.HasValue()):
        return None
    where = f"mesh {prim.GetPath()}", f"primvars:tangents ({pv.GetTypeName()}, {pv.GetInterpolation()})"
    values = face_varying(scene, pv, counts, indices, None)
    if values is None or values.shape[1] not in (3, 4):
        return _ignored(scene, warn, where, "do not fit the mesh")
    if not np.isfinite(values).all() or (np.linalg.norm(values[:, :3], axis=1) == 0).any():
        return _ignored(scene, warn, where, "hold NaN, infinite or zero vectors")
    if values.shape[1] == 4:
        signs = values[:, 3]
    else:
        signs = _signs(scene, primvars, counts, indices, values)
    return np.column_stack([values[:, :3], np.where(signs < 0, -1.0, 1.0)])


def _signs(scene, primvars, counts, indices, tangents) -> np.ndarray:
    """Handedness of float3 tangents: ``primvars:tangentSigns``, else from
    ``primvars:bitangents`` and the normals, else +1."""
    pv = primvars.GetPrimvar("tangentSigns")
    if pv and pv.HasValue():
        w = face_varying(scene, pv, counts, indices, 1)
        if w is not None and np.isfinite(w).all():
            return w[:, 0]
    b_pv, n_pv = primvars.GetPrimvar("bitangents"), primvars.GetPrimvar("normals")
    if b_pv and b_pv.HasValue():
        b = face_varying(scene, b_pv, counts, indices, 3)
        n = None
        if n_pv and n_pv.HasValue():
            n = face_varying(scene, n_pv, counts, indices, 3)
        else:
            mesh = UsdGeom.Mesh(primvars.GetPrim())
            if mesh.GetNormalsAttr().HasValue():
                n = interpolate(np.asarray(mesh.GetNormalsAttr().Get(), np.float64),
                                str(mesh.GetNormalsInterpolation()), counts, indices, 3)
        if b is not None and n is not None:
            return np.einsum("ij,ij->i", np.cross(n, tangents[:, :3]), b)
    return np.ones(len(tangents))


def _ignored(scene: Scene, warn: bool, where: tuple[str, str], problem: str) -> None:
    if warn:
        scene.warn("CSM209", f"{where[1]} {problem}; ignored, new tangents are made", where[0])
    return None
