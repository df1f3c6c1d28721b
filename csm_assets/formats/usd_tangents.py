"""Tangents of a converted USD mesh, written as faceVarying primvars in the form the
prim had (float3 + ``tangentSigns``, or float4), existing bitangents rewritten to match."""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from ..scene import Mesh, Scene
from .usd_mesh import existing_tangents, interpolate


def write_tangents(scene: Scene, prim: Usd.Prim, meshes: list[Mesh]) -> None:
    """faceVarying tangents of one prim (where to author them on the output stage) from its converted meshes (one per bound
    material), in the form the prim had: ``primvars:tangents`` float4[] (w = sign) when it
    had float4 tangents, else float3[] plus ``primvars:tangentSigns`` float[]; existing
    ``primvars:bitangents`` are rewritten to match. A face-vertex that several fan
    triangles share takes the first triangle's tangent; face-vertices of other
    materials keep the tangents the prim had, else get (1, 0, 0) and +1."""
    api = UsdGeom.PrimvarsAPI(prim)
    n = meshes[0].ref.face_vertices
    tangents = np.tile(np.array([1, 0, 0, 1], np.float64), (n, 1))
    mesh = UsdGeom.Mesh(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), np.int64)
    old = existing_tangents(scene, prim, counts, indices, warn=False)
    if old is not None:
        tangents[:] = old
    pv = api.GetPrimvar("tangents")
    four = bool(pv) and "Vec4" in pv.GetTypeName().scalarType.type.typeName
    bitangents = _old_bitangents(scene, api, counts, indices)
    for m in meshes:
        fv, first = np.unique(m.ref.corners.reshape(-1), return_index=True)
        t = m.corner_tangents.reshape(-1, 4)[first]
        tangents[fv] = t
        if bitangents is not None:
            normals = m.normals[m.faces].reshape(-1, 3)[first]
            bitangents[fv] = np.cross(normals, t[:, :3]) * t[:, 3:]
    _replace(api, "tangents", Sdf.ValueTypeNames.Float4Array if four else Sdf.ValueTypeNames.Float3Array,
             (Vt.Vec4fArray if four else Vt.Vec3fArray).FromNumpy(
                 np.ascontiguousarray(tangents if four else tangents[:, :3], np.float32)))
    if not four or api.GetPrimvar("tangentSigns"):
        _replace(api, "tangentSigns", Sdf.ValueTypeNames.FloatArray,
                 Vt.FloatArray.FromNumpy(np.ascontiguousarray(tangents[:, 3], np.float32)))
    if bitangents is not None:
        _replace(api, "bitangents", Sdf.ValueTypeNames.Float3Array,
                 Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(bitangents, np.float32)))


def _old_bitangents(scene: Scene, api: UsdGeom.PrimvarsAPI, counts, indices) -> np.ndarray | None:
    """The prim's ``primvars:bitangents`` per face-vertex (zeros where unreadable), or None."""
    pv = api.GetPrimvar("bitangents")
    if not (pv and pv.HasValue()):
        return None
    values = pv.ComputeFlattened()
    old = None if values is None else interpolate(np.asarray(values, np.float64), str(pv.GetInterpolation()),
                                                  counts, indices, 3)
    return np.zeros((len(indices), 3)) if old is None or not np.isfinite(old).all() else old


def _replace(api: UsdGeom.PrimvarsAPI, name: str, type_name, value) -> None:
    """A faceVarying primvar ``name`` of ``type_name`` holding ``value``, whatever type,
    interpolation, indices or element size the prim had under that name."""
    prim = api.GetPrim()
    for prop in (f"primvars:{name}", f"primvars:{name}:indices"):
        if prim.HasProperty(prop):
            prim.RemoveProperty(prop)
    api.CreatePrimvar(name, type_name, UsdGeom.Tokens.faceVarying).Set(value)
