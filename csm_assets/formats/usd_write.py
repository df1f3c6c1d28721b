"""Writing converted USD stages: flattened, assets copied flat beside them (inside the
package for ``.usdz``; :mod:`.usd_copies`), faceVarying tangents (:mod:`.usd_tangents`),
and the glslfx CSM shader per material."""

from __future__ import annotations

import tempfile
from pathlib import Path

from pxr import Ar, Sdf, Usd, UsdShade

from .. import cstderr
from ..atomic import atomic_path
from ..convert.links import missing
from ..convert.output_folder import free_name
from ..errors import FormatError, OutputError
from ..render.glsl import shader_path
from ..scene import Material, Mesh, Scene
from .csm_params import written
from .usd_assets import UsdSource, asset_uses
from .usd_messages import usd_diagnostics
from .usd_copies import AssetFiles, keep_arc
from .usd_shader import GLSLFX, RENDER_CONTEXT, SHADER_ID, register_shader_definitions
from .usd_tangents import write_tangents


def is_plain(stage: Usd.Stage) -> bool:
    """True when the stage is its root layer alone: no sublayers, no session opinions, and
    no references, payloads, inherits, specializes, variants or clips on any prim. Such a
    layer can be copied instead of flattened, keeping what Flatten cannot carry (metadata
    fields no plugin declares, as Omniverse writes them)."""
    layer = stage.GetRootLayer()
    if layer.subLayerPaths or not stage.GetSessionLayer().empty:
        return False
    composed = []

    def visit(path):
        if composed or not path.IsPrimPath():
            composed.extend([path] if path.IsPrimVariantSelectionPath() else [])
            return
        spec = layer.GetPrimAtPath(path)
        if spec is not None and (spec.hasReferences or spec.hasPayloads or spec.hasInheritPaths or
                                 spec.hasSpecializes or spec.hasClipSets or len(spec.variantSets)):
            composed.append(path)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return not composed


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
            scene.warn("CSM401", f"USD: {message}")


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
    files = AssetFiles(out_dir, {GLSLFX, scene.path.name} | {p.name for m in converted for p in m.csm.step_maps()}
                       | scene.reserved,
                       package, scene.others, scene.links)
    _relocate_assets(stage, out, files, scene.published or out_dir)
    by_prim: dict[Sdf.Path, list[Mesh]] = {}
    for mesh in scene.meshes:
        if mesh.corner_tangents is not None:
            by_prim.setdefault(mesh.ref.path, []).append(mesh)
    for path, meshes in by_prim.items():
        write_tangents(scene, out.GetPrimAtPath(editable_path(out, path)), meshes)
    for mat in converted:
        _add_shader(out, mat, source_asset=not package)
    if converted and not package:  # usdz may not hold .glslfx files (UsdValidation refuses them)
        files.add_file(GLSLFX, shader_path(GLSLFX))
    for mat in converted:
        if package:
            for path in mat.csm.step_maps():  # a quadrant map's second image too
                files.add_file(path.name, path)
    for path, specifier in specifiers.items():  # an `over` prototype stays over (not rendered)
        flat.GetPrimAtPath(path).specifier = specifier
    del out  # recomposing it on the kept arcs would repeat what reading warned about
    for arc in source.kept:
        keep_arc(scene, flat, arc, files)
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


def _relocate_assets(stage: Usd.Stage, out: Usd.Stage, files: AssetFiles, published: Path) -> None:
    """Point every resolvable asset-valued attribute at the file where it is, when ``files``
    may name it there (lean outputs), else at its flat copy (``./name``; UDIM tiles copied
    under one new ``name.<UDIM>.ext`` pattern): :meth:`~.usd_copies.AssetFiles.asset_path`;
    one that resolves to nothing where the scene names it, from ``published`` (:func:`_missing`)."""
    for use in asset_uses(stage):
        if use.tiles:
            asset = files.udim_asset_path(use.authored, use.tiles)
        elif use.resolved:
            asset = files.asset_path(use.resolved, use.authored)
        else:
            asset = None if files.package else _missing(use, published)
        if asset is not None:
            prim = out.GetPrimAtPath(editable_path(out, use.prim.GetPath()))
            prim.GetAttribute(use.attr.GetName()).Set(Sdf.AssetPath(asset))


def _missing(use, published: Path) -> str | None:
    """The asset path, from the output folder ``published``, of a value that resolves to nothing:
    its authored path anchored at the layer that authors it (not the absolute path a flattened
    stage holds, nor a path right only beside the scene), so it resolves once the file is there.
    None (kept as it is) where the layer is no file on disk or the path stays unanchored."""
    specs = use.attr.GetPropertyStack()
    layer = specs[0].layer if specs else None
    if layer is None or layer.anonymous or not layer.realPath or Ar.IsPackageRelativePath(layer.realPath):
        return None
    anchored = Sdf.ComputeAssetPathRelativeToLayer(layer, use.authored)
    where = missing(published, anchored) if Path(anchored).is_absolute() else None
    return None if where is None else where if where.startswith("../") else f"./{where}"


def _add_shader(out: Usd.Stage, mat: Material, source_asset: bool) -> None:
    """The glslfx-context shader: identified by SHADER_ID (its Sdr definition names
    csm.glslfx); ``source_asset`` also points ``info:glslfx:sourceAsset`` at the copy."""
    csm = mat.csm
    material = UsdShade.Material(out.GetPrimAtPath(editable_path(out, Sdf.Path(mat.ref))))
    name = free_name("CsmSurface", "", lambda n: bool(material.GetPrim().GetChild(n)))
    shader = UsdShade.Shader.Define(out, material.GetPath().AppendChild(name))
    shader.SetShaderId(SHADER_ID)
    if source_asset:
        shader.GetPrim().CreateAttribute(f"info:{RENDER_CONTEXT}:sourceAsset", Sdf.ValueTypeNames.Asset,
                                         False, Sdf.VariabilityUniform).Set(Sdf.AssetPath(f"./{GLSLFX}"))
    shader.CreateInput("stepMap", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{csm.step_map.name}"))
    if csm.step_map2 is not None:  # a quadrant map's second image
        shader.CreateInput("stepMap2", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{csm.step_map2.name}"))
    for key, path in zip(("stepMapLevels", "stepMap2Levels"), csm.levels_images):  # docs/reference/levels.md
        shader.CreateInput(key, Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{path.name}"))
    types = {"number": Sdf.ValueTypeNames.Float, "integer": Sdf.ValueTypeNames.Int,
             "boolean": Sdf.ValueTypeNames.Bool, "string": Sdf.ValueTypeNames.Token}
    for p, value in written(csm):  # the one parameter list, in the schema's order
        if p.kind == "tile":
            shader.CreateInput("tileU", Sdf.ValueTypeNames.Int).Set(int(value[0]))
            shader.CreateInput("tileV", Sdf.ValueTypeNames.Int).Set(int(value[1]))
        else:
            shader.CreateInput(p.name, types[p.kind]).Set(value)
    surface = shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput(RENDER_CONTEXT).ConnectToSource(surface)
