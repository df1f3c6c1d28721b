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
from .usd import _asset_bytes, _asset_values, _existing_tangents
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
    out_dir = Path(out_dir)
    register_shader_definitions()
    stage: Usd.Stage = scene.source
    flat = stage.Flatten()
    flat.documentation = stage.GetRootLayer().documentation  # not Flatten's note naming the input path
    out = Usd.Stage.Open(flat)
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
        _write_tangents(out, path, meshes)
    for mat in converted:
        _add_shader(out, mat, source_asset=not package)
    if converted and not package:  # usdz may not hold .glslfx files (UsdValidation refuses them)
        files.add_file(GLSLFX, shader_path(GLSLFX))
    for mat in converted:
        if package:
            files.add_file(mat.csm.step_map.name, mat.csm.step_map)
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

    def name_for(self, resolved: str, authored: str) -> str | None:
        if resolved in self.by_source:
            return self.by_source[resolved]
        suffix = Path(authored).suffix.lower()
        stem = safe_name(Path(authored).stem)
        name, n = f"{stem}{suffix}", 1
        while name in self.taken:
            name, n = f"{stem}_{n}{suffix}", n + 1
        if Ar.IsPackageRelativePath(resolved):
            data = _asset_bytes(resolved)
            if data is None:
                return None
            self.add_bytes(name, data)
        else:
            self.add_file(name, Path(resolved))
        self.taken.add(name)
        self.by_source[resolved] = name
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


def _relocate_assets(stage: Usd.Stage, out: Usd.Stage, files: _Files) -> None:
    """Point every resolvable asset-valued attribute at its flat copy (``./name``)."""
    for prim, attr, value in _asset_values(stage):
        name = files.name_for(value.resolvedPath, value.path)
        if name is not None:
            out.GetPrimAtPath(prim.GetPath()).GetAttribute(attr.GetName()).Set(Sdf.AssetPath(f"./{name}"))


def _write_tangents(out: Usd.Stage, path: Sdf.Path, meshes: list[Mesh]) -> None:
    """faceVarying ``primvars:tangents`` and ``primvars:tangentSigns`` of one prim from
    its converted meshes (one per bound material). A face-vertex that several fan
    triangles share takes the first triangle's tangent; face-vertices of other
    materials keep the tangents the prim had, else get (1, 0, 0) and +1."""
    prim = out.GetPrimAtPath(path)
    api = UsdGeom.PrimvarsAPI(prim)
    n = meshes[0].ref.face_vertices
    tangents = np.tile(np.array([1, 0, 0, 1], np.float32), (n, 1))
    mesh = UsdGeom.Mesh(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), np.int64)
    old = _existing_tangents(api, counts, indices)
    if old is not None:
        tangents[:] = old
    for m in meshes:
        fv, first = np.unique(m.ref.corners.reshape(-1), return_index=True)
        tangents[fv] = m.corner_tangents.reshape(-1, 4)[first]
    api.CreatePrimvar("tangents", Sdf.ValueTypeNames.Float3Array, UsdGeom.Tokens.faceVarying).Set(
        Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(tangents[:, :3])))
    api.CreatePrimvar("tangentSigns", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.faceVarying).Set(
        Vt.FloatArray.FromNumpy(np.ascontiguousarray(tangents[:, 3])))
    for name in ("tangents", "tangentSigns"):  # an indexed primvar's old indices would misread them
        if api.GetPrimvar(name).IsIndexed():
            api.GetPrimvar(name).BlockIndices()


def _add_shader(out: Usd.Stage, mat: Material, source_asset: bool) -> None:
    """The glslfx-context shader: identified by SHADER_ID (its Sdr definition names
    csm.glslfx); ``source_asset`` also points ``info:glslfx:sourceAsset`` at the copy."""
    csm = mat.csm
    material = UsdShade.Material(out.GetPrimAtPath(mat.ref))
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
