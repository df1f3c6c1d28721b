"""Writing converted USD stages: flattened, assets copied flat beside them (inside the
package for ``.usdz``), faceVarying tangents, and the glslfx CSM shader per material."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
from pxr import Ar, Sdf, Usd, UsdGeom, UsdShade, Vt

from .. import cstderr
from ..atomic import atomic_path
from ..errors import OutputError
from ..glsl import shader_path
from ..scene import Material, Mesh, Scene, safe_name
from .usd_assets import KeptArc, UsdSource, asset_bytes, asset_uses, is_plain, usd_diagnostics
from .usd_mesh import existing_tangents, interpolate
from .usd_mtlx import mtlx_copy
from .usd_shader import (
    GLSLFX,
    GLSLFX_PARAMETERS,
    RENDER_CONTEXT,
    SHADER_ID,
    register_shader_definitions,
)


def write(scene: Scene, out_dir) -> list[Path]:
    """Write the converted stage into ``out_dir``; the paths written (scene, copied files).

    Step map files must already be in ``out_dir`` (``material.csm.step_map``). A
    ``.usdz`` input gives a ``.usdz`` holding the layer and every asset.
    """
    messages: list[str] = []
    try:
        with usd_diagnostics(messages):
            return _write(scene, Path(out_dir))
    finally:
        for message in messages:  # e.g. metadata fields no plugin declares, which Flatten drops
            scene.warn(f"USD: {message}")


def _write(scene: Scene, out_dir: Path) -> list[Path]:
    register_shader_definitions()
    source: UsdSource = scene.source
    stage = source.stage
    if is_plain(stage) and not source.kept:  # a copy keeps what Flatten would drop
        ext = stage.GetRootLayer().GetFileFormat().primaryFileExtension
        flat = Sdf.Layer.CreateAnonymous(".usdc" if ext == "usdz" else f".{ext}")
        flat.TransferContent(stage.GetRootLayer())
    else:
        flat = stage.Flatten()
        flat.documentation = stage.GetRootLayer().documentation  # not Flatten's note naming the input
    out = Usd.Stage.Open(flat)
    specifiers = {spec.path: spec.specifier for spec in flat.rootPrims}  # Define makes ancestors def
    converted = [m for m in scene.materials if m.csm is not None]
    package = scene.path.suffix.lower() == ".usdz"
    files = _Files(out_dir, {GLSLFX, scene.path.name} | {m.csm.step_map.name for m in converted} | scene.reserved,
                   package)
    _relocate_assets(stage, out, files)
    by_prim: dict[Sdf.Path, list[Mesh]] = {}
    for mesh in scene.meshes:
        if mesh.corner_tangents is not None:
            by_prim.setdefault(mesh.ref.path, []).append(mesh)
    for path, meshes in by_prim.items():
        _write_tangents(scene, out, path, meshes)
    for mat in converted:
        _add_shader(out, mat, source_asset=not package)
    if converted and not package:  # usdz may not hold .glslfx files (UsdValidation refuses them)
        files.add_file(GLSLFX, shader_path(GLSLFX))
    for mat in converted:
        if package:
            files.add_file(mat.csm.step_map.name, mat.csm.step_map)
    for path, specifier in specifiers.items():  # an `over` prototype stays over (not rendered)
        flat.GetPrimAtPath(path).specifier = specifier
    del out  # recomposing it on the kept arcs would repeat what reading warned about
    for arc in source.kept:
        _keep_arc(scene, flat, arc, files)
    target = out_dir / scene.path.name
    if package:
        with tempfile.TemporaryDirectory() as tmp:
            layer_file = Path(tmp) / f"{scene.path.stem}.usdc"
            _usd_call(target, "export the converted layer", lambda: flat.Export(str(layer_file)))
            with atomic_path(target, check=lambda t: _usd_call(target, "read back the package", lambda: Usd.Stage.Open(str(t)))) as t:
                def pack():
                    zf = Sdf.ZipFileWriter.CreateNew(str(t))
                    zf.AddFile(str(layer_file), layer_file.name)
                    for name, src in files.packed.items():
                        zf.AddFile(str(src), name)
                    return zf.Save()
                _usd_call(target, "write the package", pack)
        return [target]
    with atomic_path(target, check=lambda t: _usd_call(target, "read back the written layer",
                                                        lambda: Sdf.Layer.OpenAsAnonymous(str(t)))) as t:
        _usd_call(target, "export the converted layer", lambda: flat.Export(str(t)))
    return [target, *files.written]


def _usd_call(target: Path, what: str, call):
    """Run a USD call that writes or reads ``target``'s files; a False/None result or a USD
    error (a full disk) is an OutputError naming ``target``, USD's own stderr lines kept out."""
    from pxr import Tf

    with cstderr.captured() as said:
        try:
            result = call()
        except Tf.ErrorException as e:
            result, error = None, str(e)
        else:
            error = ""
    if not result:
        lines = [" ".join(t.split()) for t in (error or "".join(said)).splitlines() if t.strip()]
        reason = next((t.split(": ", 1)[-1].strip("' ") for t in lines if "No space" in t or "rror" in t), "")
        raise OutputError(target, f"USD could not {what}" + (f" ({reason[:200]})" if reason else ""))
    return result


class _Files:
    """Assets the output names: copied flat into out_dir (or gathered for a package)
    under safe, unique names."""

    def __init__(self, out_dir: Path, reserved: set[str], package: bool):
        self.out_dir, self.taken, self.package = out_dir, set(reserved), package
        self.by_source: dict[str, str] = {}
        self.written: list[Path] = []
        self.packed: dict[str, Path] = {}
        self._tmp = tempfile.TemporaryDirectory() if package else None

    def name_for(self, resolved: str, authored: str, data: bytes | None = None,
                 name: str | None = None) -> str | None:
        """The flat name of the copy of ``resolved`` (copied on first use, under ``name``
        if given; ``data``: bytes to write instead of the file's own); None when it cannot
        be read."""
        if resolved in self.by_source:
            return self.by_source[resolved]
        name = name or self.free_name(authored)
        if data is None and Ar.IsPackageRelativePath(resolved):
            data = asset_bytes(resolved)
            if data is None:
                return None
        if data is not None:
            self.add_bytes(name, data)
        else:
            self.add_file(name, Path(resolved))
        self.taken.add(name)
        self.by_source[resolved] = name
        return name

    def udim_pattern(self, authored: str, tiles: dict[int, str]) -> str:
        """A free ``base.<UDIM>.ext`` pattern with every tile of ``tiles`` copied under it."""
        key = "udim:" + "|".join(tiles.values())
        if key in self.by_source:
            return self.by_source[key]
        head, tail = Path(authored).name.split("<UDIM>", 1)
        ext = "." + safe_name(tail.rsplit(".", 1)[1]).lower() if "." in tail else ""
        base, n = safe_name(head) if head.strip("._") else "udim", 0
        while True:
            stem = f"{base}_{n}" if n else base
            names = {tile: f"{stem}.{tile}{ext}" for tile in tiles}
            if not self.taken.intersection(names.values()):
                break
            n += 1
        for tile, resolved in tiles.items():
            self.name_for(resolved, names[tile], name=names[tile])
        self.by_source[key] = f"{stem}.<UDIM>{ext}"
        return self.by_source[key]

    def free_name(self, authored: str) -> str:
        suffix = Path(authored).suffix.lower()
        stem = safe_name(Path(authored).stem)
        name, n = f"{stem}{suffix}", 1
        while name in self.taken:
            name, n = f"{stem}_{n}{suffix}", n + 1
        return name

    def add_file(self, name: str, src: Path) -> None:
        if self.package:
            self.packed[name] = Path(src)
            return
        with atomic_path(self.out_dir / name) as tmp:
            shutil.copyfile(src, tmp)
        self.written.append(self.out_dir / name)

    def add_bytes(self, name: str, data: bytes) -> None:
        if self.package:
            file = Path(self._tmp.name) / name
            file.write_bytes(data)
            self.packed[name] = file
            return
        with atomic_path(self.out_dir / name) as tmp:
            tmp.write_bytes(data)
        self.written.append(self.out_dir / name)


def editable_path(out: Usd.Stage, path: Sdf.Path) -> Sdf.Path:
    """Where to author an opinion for the prim at ``path`` of a flattened stage: the path
    itself, or for an instance proxy the same prim under the ``Flattened_Prototype`` that
    its instance references (nested instances followed)."""
    prim = out.GetPrimAtPath(path)
    while prim and prim.IsInstanceProxy():
        instance = prim.GetParent()
        while not instance.IsInstance():
            instance = instance.GetParent()
        spec = out.GetRootLayer().GetPrimAtPath(instance.GetPath())
        protos = [r.primPath for r in spec.referenceList.GetAddedOrExplicitItems() if not r.assetPath]
        if len(protos) != 1:
            raise FormatError(out.GetRootLayer().identifier, f"cannot find the prototype of instance {instance.GetPath()} "
                                                            f"in the flattened stage")
        path = path.ReplacePrefix(instance.GetPath(), protos[0])
        prim = out.GetPrimAtPath(path)
    return path


def _relocate_assets(stage: Usd.Stage, out: Usd.Stage, files: _Files) -> None:
    """Point every resolvable asset-valued attribute at its flat copy (``./name``; UDIM
    tiles copied under one new ``name.<UDIM>.ext`` pattern)."""
    for use in asset_uses(stage):
        if use.tiles:
            name = files.udim_pattern(use.authored, use.tiles)
        elif use.resolved:
            name = files.name_for(use.resolved, use.authored)
        else:
            continue
        if name is not None:
            prim = out.GetPrimAtPath(editable_path(out, use.prim.GetPath()))
            prim.GetAttribute(use.attr.GetName()).Set(Sdf.AssetPath(f"./{name}"))


def _keep_arc(scene: Scene, flat: Sdf.Layer, arc: KeptArc, files: _Files) -> None:
    """Copy the file of an arc usd-core could not compose and author the arc again on the
    flattened layer, pointing at the copy (MaterialX documents: see :mod:`.usd_mtlx`)."""
    mtlx = arc.resolved.lower().endswith(".mtlx")
    data = mtlx_copy(scene, arc.resolved, arc.files, files.name_for) if mtlx else None
    name = files.name_for(arc.resolved, arc.authored, data)
    if name is None:
        raise FormatError(scene.path, f"{arc.kind} {arc.authored!r} cannot be read to be copied")
    asset = f"./{name}"
    if arc.kind == "subLayer":
        flat.subLayerPaths.append(asset)
        flat.subLayerOffsets[len(flat.subLayerPaths) - 1] = arc.offset
        return
    spec = flat.GetPrimAtPath(arc.site) or Sdf.CreatePrimInLayer(flat, arc.site)
    if arc.kind == "reference":
        spec.referenceList.Prepend(Sdf.Reference(asset, arc.prim_path, arc.offset))
    else:
        spec.payloadList.Prepend(Sdf.Payload(asset, arc.prim_path, arc.offset))


def _write_tangents(scene: Scene, out: Usd.Stage, path: Sdf.Path, meshes: list[Mesh]) -> None:
    """faceVarying tangents of one prim from its converted meshes (one per bound
    material), in the form the prim had: ``primvars:tangents`` float4[] (w = sign) when it
    had float4 tangents, else float3[] plus ``primvars:tangentSigns`` float[]; existing
    ``primvars:bitangents`` are rewritten to match. A face-vertex that several fan
    triangles share takes the first triangle's tangent; face-vertices of other
    materials keep the tangents the prim had, else get (1, 0, 0) and +1."""
    prim = out.GetPrimAtPath(editable_path(out, path))
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


def _add_shader(out: Usd.Stage, mat: Material, source_asset: bool) -> None:
    """The glslfx-context shader: identified by SHADER_ID (its Sdr definition names
    csm.glslfx); ``source_asset`` also points ``info:glslfx:sourceAsset`` at the copy."""
    csm = mat.csm
    material = UsdShade.Material(out.GetPrimAtPath(editable_path(out, Sdf.Path(mat.ref))))
    name, n = "CsmSurface", 1
    while material.GetPrim().GetChild(name):
        name, n = f"CsmSurface_{n}", n + 1
    shader = UsdShade.Shader.Define(out, material.GetPath().AppendChild(name))
    shader.SetShaderId(SHADER_ID)
    if source_asset:
        shader.GetPrim().CreateAttribute(f"info:{RENDER_CONTEXT}:sourceAsset", Sdf.ValueTypeNames.Asset,
                                         False, Sdf.VariabilityUniform).Set(Sdf.AssetPath(f"./{GLSLFX}"))
    shader.CreateInput("stepMap", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{csm.step_map.name}"))
    values = {"depthScale": csm.depth_scale, "maxRatio": csm.max_ratio, "heightScale": csm.height_scale,
              "heightOffset": csm.height_offset, "steps": csm.steps, "minStep": csm.min_step,
              "tileU": int(csm.tile[0]),
              "tileV": int(csm.tile[1])}
    for key, (kind, _, _) in GLSLFX_PARAMETERS.items():
        typ = Sdf.ValueTypeNames.Float if kind == "float" else Sdf.ValueTypeNames.Int
        shader.CreateInput(key, typ).Set(values[key])
    shader.CreateInput("variant", Sdf.ValueTypeNames.Token).Set(csm.variant)
    surface = shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput(RENDER_CONTEXT).ConnectToSource(surface)
