"""USD scenes (``.usda``, ``.usdc``, ``.usdz``; usd-core): height textures in, tangents
and a glslfx CSM shader out.

Heights: a material's ``UsdPreviewSurface`` (found through ``outputs:surface`` or
``outputs:displacement``, universal render context) whose ``inputs:displacement`` is
connected, through any chain of NodeGraph/Material interface inputs and outputs, to a
``UsdUVTexture``: its ``inputs:file``, the output's channel (``outputs:r`` .. ``a``),
``inputs:scale``/``inputs:bias`` of that channel, ``wrapS``/``wrapT``, and the uv primvar
named by the ``UsdPrimvarReader_float2`` feeding ``inputs:st`` (a ``UsdTransform2d`` in
between is followed; its transform is not applied) or ``st``. A connection cycle, a
missing texture or a mesh without that primvar is a warning naming the material.

Geometry is read only for meshes bound (``ComputeBoundMaterial``) to such a material:
points, normals and the uv primvar in any interpolation, polygons fan-triangulated,
``leftHanded`` faces reversed; uvs have USD's origin (bottom-left).

Writing flattens the stage into ``out_dir`` (same file name), copies every asset it
names flat beside it (inside the package for ``.usdz``), adds ``primvars:tangents``
(float3[], faceVarying) and ``primvars:tangentSigns`` (float[], faceVarying, the
handedness) to converted meshes, and to each converted material a shader for the
``glslfx`` render context (:data:`SHADER_ID`, see :func:`register_shader_definitions`)
next to its UsdPreviewSurface, which stays the universal fallback.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Ar, Sdf, Usd, UsdGeom, UsdShade

from .. import height_source
from ..errors import FormatError
from ..scene import HeightInput, Material, Mesh, Scene, Texture, safe_name
from .usd_shader import (
    GLSLFX_PARAMETERS,
    SHADER_ID,
    build_glslfx,
    register_shader_definitions,
)

__all__ = ["GLSLFX_PARAMETERS", "SHADER_ID", "build_glslfx", "read", "register_shader_definitions", "write"]

STORES_TANGENTS = True
STEP_MAP_BITS = (8, 16, 32)
CHANNELS = {"r": 0, "g": 1, "b": 2, "a": 3, "rgb": None}
MIMES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".exr": "image/x-exr"}


class _Cycle(Exception):
    pass


@dataclass
class MeshRef:
    """Where a Mesh came from: the prim, and for each triangle corner the face-vertex
    (index into ``faceVertexIndices``) it stands for, ``(F, 3)``; ``face_vertices``: N."""

    path: Sdf.Path
    corners: np.ndarray
    face_vertices: int


def read(path, heights: dict | None = None, *, allow_outside: bool = False) -> Scene:
    """The scene of a USD file. ``heights`` maps material names (prim name or path) to
    height texture files (or :class:`HeightInput`) that override what the file says.
    Assets authored as absolute paths, or resolving outside the scene's folder (unless
    ``allow_outside``), raise FormatError."""
    path = Path(path)
    if not path.is_file():
        raise FormatError(path, "no such file")
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as e:  # pxr raises Tf.ErrorException, a plain Exception subclass
        raise FormatError(path, f"not a readable USD stage: {str(e).strip().splitlines()[-1]}") from None
    if stage is None:
        raise FormatError(path, "not a readable USD stage")
    scene = Scene(path, path.suffix[1:].lower(), source=stage, inputs=[path])
    _check_assets(scene, stage, allow_outside)
    heights = heights or {}
    by_path = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdShade.Material):
            continue
        key = str(prim.GetPath())
        mat = Material(prim.GetName(), ref=key)
        st = "st"
        override = heights.get(key, heights.get(prim.GetName()))
        if override is not None:
            found = {}

            def find(prim=prim, key=key):
                found["r"] = _find_height(scene, UsdShade.Material(prim), key)
                return found["r"][0] if found["r"] else None

            mat.height = height_source.override(override, scene, find)
            st = found["r"][1] if found.get("r") else _preview_st(prim) or st
        else:
            found = _find_height(scene, UsdShade.Material(prim), key)
            if found is not None:
                mat.height, st = found
        scene.materials.append(mat)
        if mat.height is not None:
            by_path[key] = (mat, st)
    if by_path:
        for prim in stage.Traverse():
            if not prim.IsA(UsdGeom.Mesh):
                continue
            for bound, subset in _bindings(prim):
                if bound and str(bound.GetPath()) in by_path:
                    mat, st = by_path[str(bound.GetPath())]
                    mesh = _mesh(scene, prim, mat, st, subset)
                    if mesh is not None:
                        scene.meshes.append(mesh)
    return scene


def _bindings(prim):
    """``(material, subset)`` pairs of a mesh: each ``materialBind`` GeomSubset with
    its bound material and face indices, then the mesh's own material for the faces no
    subset takes (subset None: all faces, when there are no subsets)."""
    api = UsdShade.MaterialBindingAPI(prim)
    pairs, taken = [], []
    for subset in api.GetMaterialBindSubsets():
        faces = np.asarray(subset.GetIndicesAttr().Get() or [], np.int64)
        pairs.append((UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0],
                      (subset.GetPrim().GetName(), faces)))
        taken.append(faces)
    rest = None if not taken else ("", np.concatenate(taken))  # "" : every face but these
    return [(api.ComputeBoundMaterial()[0], rest), *pairs]


# --- following connections -------------------------------------------------------------

def _source(attr: Usd.Attribute):
    """Follow the connections of a shading attribute to the shader output that drives
    it: ``(UsdShade.Shader, output name)``, or ``(None, last attribute)`` where the chain
    ends in a value. Raises _Cycle (naming the attribute) on a connection cycle."""
    seen = set()
    while True:
        if attr.GetPath() in seen:
            raise _Cycle(str(attr.GetPath()))
        seen.add(attr.GetPath())
        if UsdShade.Input.IsInput(attr):
            sources = UsdShade.Input(attr).GetConnectedSources()[0]
        else:
            sources = UsdShade.Output(attr).GetConnectedSources()[0]
        if not sources:
            return None, attr
        info = sources[0]
        prim = info.source.GetPrim()
        if info.sourceType == UsdShade.AttributeType.Output:
            if prim.IsA(UsdShade.Shader):
                return UsdShade.Shader(prim), info.sourceName
            nxt = info.source.GetOutput(info.sourceName)
        else:
            nxt = info.source.GetInput(info.sourceName)
        if not nxt:
            return None, attr
        attr = nxt.GetAttr()


def _value(shader: UsdShade.Shader, name: str, default=None):
    """The value of a shader input, through interface connections."""
    inp = shader.GetInput(name)
    if not inp:
        return default
    src, attr = _source(inp.GetAttr())
    if src is not None:
        return default
    value = attr.Get()
    return default if value is None else value


def _shader_id(shader: UsdShade.Shader) -> str:
    return str(shader.GetShaderId() or "")


def _preview_surface(material: UsdShade.Material) -> UsdShade.Shader | None:
    for terminal in ("surface", "displacement"):
        out = material.GetOutput(terminal)
        if out:
            shader, _ = _source(out.GetAttr())
            if shader is not None and _shader_id(shader) == "UsdPreviewSurface":
                return shader
    return None


def _preview_st(prim) -> str | None:
    """The uv primvar a material's textures read (for command-line heights)."""
    try:
        ps = _preview_surface(UsdShade.Material(prim))
        if ps is None:
            return None
        for inp in ps.GetInputs():
            shader, _ = _source(inp.GetAttr())
            if shader is not None and _shader_id(shader) == "UsdUVTexture":
                return _st_primvar(shader)
    except _Cycle:
        return None
    return None


def _find_height(scene: Scene, material: UsdShade.Material, name: str):
    """``(HeightInput, uv primvar name)`` of a material, or None (with a warning where
    something was there but unusable)."""
    try:
        ps = _preview_surface(material)
        if ps is None or not ps.GetInput("displacement"):
            return None
        tex, output = _source(ps.GetInput("displacement").GetAttr())
        if tex is None:
            return None
        if _shader_id(tex) != "UsdUVTexture":
            scene.warn(f"material {name!r}: displacement comes from {tex.GetPath()} "
                       f"({_shader_id(tex) or 'no id'}), not a UsdUVTexture; left without CSM")
            return None
        st = _st_primvar(tex)
        asset = _value(tex, "file")
    except _Cycle as c:
        scene.warn(f"material {name!r}: shader connections form a cycle at {c}; left without CSM")
        return None
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        scene.warn(f"material {name!r}: the displacement UsdUVTexture {tex.GetPath()} names no file; "
                   f"left without CSM")
        return None
    texture = _texture(scene, asset, name)
    if texture is None:
        return None
    channel = CHANNELS.get(output, 0)
    k = channel if isinstance(channel, int) else 0
    scale = _value(tex, "scale", (1.0, 1.0, 1.0, 1.0))
    bias = _value(tex, "bias", (0.0, 0.0, 0.0, 0.0))
    wraps = tuple(str(_value(tex, w, "useMetadata")) for w in ("wrapS", "wrapT"))
    tile = None if "useMetadata" in wraps else (wraps[0] == "repeat", wraps[1] == "repeat")
    return HeightInput(texture, 0, channel, False, float(scale[k]), float(bias[k]),
                       "UsdPreviewSurface displacement", tile), st


def _st_primvar(tex: UsdShade.Shader) -> str:
    """The primvar a UsdUVTexture reads its uvs from (``st`` when nothing says)."""
    inp = tex.GetInput("st")
    if not inp:
        return "st"
    shader, _ = _source(inp.GetAttr())
    if shader is not None and _shader_id(shader) == "UsdTransform2d":
        shader = _source(shader.GetInput("in").GetAttr())[0] if shader.GetInput("in") else None
    if shader is not None and _shader_id(shader).startswith("UsdPrimvarReader"):
        return str(_value(shader, "varname", "st") or "st")
    return "st"


def _texture(scene: Scene, asset: Sdf.AssetPath, material: str) -> Texture | None:
    resolved = asset.resolvedPath
    name = safe_name(Path(asset.path).stem)
    if not resolved:
        scene.warn(f"material {material!r}: height texture {asset.path} is missing; left without CSM")
        return None
    if Ar.IsPackageRelativePath(resolved):
        data = _asset_bytes(resolved)
        if data is None:
            scene.warn(f"material {material!r}: height texture {asset.path} cannot be read from "
                       f"the package; left without CSM")
            return None
        return Texture(name, data=data, mime=MIMES.get(Path(asset.path).suffix.lower()))
    return Texture(name, path=Path(resolved))


def _asset_bytes(resolved: str) -> bytes | None:
    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    return None if asset is None else bytes(asset.GetBuffer())



# --- geometry ---------------------------------------------------------------------------

def _mesh(scene: Scene, prim, mat: Material, st: str, subset=None) -> Mesh | None:
    """The triangles of ``prim`` bound to ``mat``: all of them, the faces of a GeomSubset
    ``(name, face indices)``, or every face but those (name "")."""
    mesh = UsdGeom.Mesh(prim)
    name = str(prim.GetPath()) + (f"/{subset[0]}" if subset and subset[0] else "")
    t = Usd.TimeCode.EarliestTime()
    points = np.asarray(mesh.GetPointsAttr().Get(t) or [], np.float64).reshape(-1, 3)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(t) or [], np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(t) or [], np.int64)
    if counts.sum() != len(indices) or (len(indices) and (indices.min() < 0 or indices.max() >= len(points))):
        scene.warn(f"mesh {name} (material {mat.ref!r}): faceVertexCounts/Indices do not match its "
                   f"{len(points)} points; no tangents")
        return None
    if (counts < 3).any():
        scene.warn(f"mesh {name}: {(counts < 3).sum()} face(s) with fewer than 3 vertices skipped")
    primvars = UsdGeom.PrimvarsAPI(prim)
    uv_pv = primvars.GetPrimvar(st)
    uvs = _face_varying(uv_pv, counts, indices, 2) if uv_pv and uv_pv.HasValue() else None
    if uvs is None:
        scene.warn(f"mesh {name} (material {mat.ref!r}): no usable primvars:{st}; no tangents")
        return None
    normals = None
    n_pv = primvars.GetPrimvar("normals")
    if n_pv and n_pv.HasValue():
        normals = _face_varying(n_pv, counts, indices, 3)
    elif mesh.GetNormalsAttr().HasValue():
        normals = _interpolate(np.asarray(mesh.GetNormalsAttr().Get(t), np.float64), str(
            mesh.GetNormalsInterpolation()), counts, indices, 3)
    corners, poly = _fan(counts)
    if subset is not None:
        chosen = np.isin(poly, subset[1])
        corners = corners[chosen if subset[0] else ~chosen]
        if len(corners) == 0:
            return None
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        corners = corners[:, [0, 2, 1]]
    tangents = _existing_tangents(primvars, counts, indices)
    used = np.unique(corners)
    key = np.column_stack([indices[used], uvs[used]] + ([normals[used]] if normals is not None else []))
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    rep = used[first]  # one face-vertex per welded vertex
    lookup = np.empty(len(indices), np.int64)
    lookup[used] = inverse.reshape(-1)
    return Mesh(name, points[indices[rep]], lookup[corners], None if normals is None else normals[rep],
                uvs[rep], None if tangents is None else tangents[rep], mat, uv_origin="bottom-left",
                ref=MeshRef(prim.GetPath(), corners, len(indices)))


def _fan(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face-vertex indices ``(F, 3)`` of the fan triangulation of polygons of ``counts``,
    and the polygon of each triangle ``(F,)``."""
    starts = np.cumsum(counts) - counts
    ntri = np.maximum(counts - 2, 0)
    poly = np.repeat(np.arange(len(counts)), ntri)
    k = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = starts[poly]
    return np.stack([s, s + k, s + k + 1], 1).astype(np.int64), poly


def _face_varying(primvar: UsdGeom.Primvar, counts, indices, k: int) -> np.ndarray | None:
    values = primvar.ComputeFlattened(Usd.TimeCode.EarliestTime())
    if values is None:
        return None
    return _interpolate(np.asarray(values, np.float64), str(primvar.GetInterpolation()), counts, indices, k)


def _interpolate(values: np.ndarray, interpolation: str, counts, indices, k: int) -> np.ndarray | None:
    """Per face-vertex values ``(N, k)`` of a primvar of any interpolation (None when
    its length does not fit)."""
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


def _existing_tangents(primvars, counts, indices) -> np.ndarray | None:
    pv = primvars.GetPrimvar("tangents")
    if not (pv and pv.HasValue()):
        return None
    xyz = _face_varying(pv, counts, indices, 3)
    if xyz is None:
        return None
    signs_pv = primvars.GetPrimvar("tangentSigns")
    w = _face_varying(signs_pv, counts, indices, 1) if signs_pv and signs_pv.HasValue() else None
    return np.column_stack([xyz, np.ones(len(xyz)) if w is None else w[:, 0]])


# --- assets ------------------------------------------------------------------------------

def _asset_values(stage: Usd.Stage):
    """``(prim, attribute, Sdf.AssetPath)`` of every authored asset value that resolves."""
    for prim in stage.Traverse():
        for attr in prim.GetAttributes():
            if attr.GetTypeName() != Sdf.ValueTypeNames.Asset or not attr.HasAuthoredValue():
                continue
            value = attr.Get()
            if isinstance(value, Sdf.AssetPath) and value.resolvedPath:
                yield prim, attr, value


def _check_assets(scene: Scene, stage: Usd.Stage, allow_outside: bool) -> None:
    """Refuse assets that leave the scene's folder; record the layers and files read."""
    root = scene.path.resolve().parent
    layers = [Path(layer.realPath) for layer in stage.GetUsedLayers() if layer.realPath]
    for file in layers:
        if not Ar.IsPackageRelativePath(str(file)) and file.is_file() and file not in scene.inputs:
            scene.inputs.append(file)
    for _, _, value in _asset_values(stage):
        if Ar.IsPackageRelativePath(value.resolvedPath):
            continue  # inside a .usdz
        if Path(value.path).is_absolute() or re.match(r"^[A-Za-z]:|^[a-z][a-z0-9+.-]*://", value.path):
            raise FormatError(scene.path, f"refers to {value.path!r}: absolute paths and URLs are refused")
        file = Path(value.resolvedPath)
        if not allow_outside and not file.resolve().is_relative_to(root):
            raise FormatError(scene.path, f"refers to {value.path!r}, outside the scene's folder; refused "
                                          f"(allow it with --allow-outside-paths)")
        if file.is_file() and file not in scene.inputs:
            scene.inputs.append(file)


# --- writing ----------------------------------------------------------------------------

def write(scene: Scene, out_dir) -> list[Path]:
    """Write the converted stage into ``out_dir``; the paths written (see :mod:`.usd_write`)."""
    from .usd_write import write as write_stage

    return write_stage(scene, out_dir)
