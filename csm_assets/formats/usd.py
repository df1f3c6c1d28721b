"""USD scenes (``.usda``, ``.usdc``, ``.usdz``; usd-core): height textures in, tangents
and a glslfx CSM shader out.

Heights (found by :mod:`.usd_height`): a material's ``UsdPreviewSurface`` (found through ``outputs:surface`` or
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

from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from .. import height_source
from ..errors import FormatError
from ..references import reach
from ..scene import Material, Scene
from .registry import module_bits, module_stores_tangents
from .usd_assets import UsdSource, check_assets, open_stage, warn_unresolved_assets
from .usd_messages import usd_diagnostics
from .usd_height import CHANNELS, MIMES, find_height, preview_st  # noqa: F401 (public names)
from .usd_mesh import MeshRef, read_mesh
from .usd_mtlx import mtlx_files
from .usd_shader import GLSLFX_PARAMETERS, SHADER_ID, build_glslfx, register_shader_definitions
from .usd_write import write

__all__ = ["GLSLFX_PARAMETERS", "SHADER_ID", "MeshRef", "UsdSource", "build_glslfx", "read",
           "register_shader_definitions", "write"]

STORES_TANGENTS = module_stores_tangents("usd")
STEP_MAP_BITS = module_bits("usd")
UDIM_SETS = True  # a material may name a UDIM set (csm_assets.convert.udim); glTF and MTL cannot


def read(path, heights: dict | None = None, *, allow_outside: bool = False, root=None) -> Scene:
    """The scene of a USD file. ``heights`` maps material names (prim name or path) to
    height texture files (or :class:`HeightInput`) that override what the file says.
    Assets authored as absolute paths, or resolving outside the project root ``root``
    (default: the scene's folder; anywhere with ``allow_outside``), raise FormatError."""
    path = Path(path)
    if not path.is_file():
        raise FormatError(path, "no such file")
    messages: list[str] = []
    within = reach(path, allow_outside=allow_outside, root=root)
    source = open_stage(path, within, messages)
    scene = Scene(path, path.suffix[1:].lower(), source=source, inputs=[path])
    scene.absent += [Path(a) for a in source.missing if Path(a).is_absolute()]  # a layer an unselected variant names
    try:
        with usd_diagnostics(messages):  # USD warns lazily too (relationship targets, ...)
            _read(scene, source, heights or {}, within)
    finally:
        for message in messages:
            scene.warn("CSM401", f"USD: {message}")
    return scene


def _read(scene: Scene, source: UsdSource, heights: dict, within) -> None:
    stage = source.stage
    for arc in source.kept:
        if arc.resolved.lower().endswith(".mtlx"):
            arc.files = mtlx_files(scene, arc.resolved, within)
    missing = check_assets(scene, stage, within)
    _warn_unresolved(scene, source)
    _warn_variants(scene, stage)
    by_path = {}
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        key = _canonical(prim)
        if not prim.IsA(UsdShade.Material) or key in by_path:
            continue
        mat = Material(prim.GetName(), ref=str(prim.GetPath()))
        found = {}

        def find(prim=prim, where=mat.ref, found=found):
            found["r"] = find_height(scene, UsdShade.Material(prim), where)
            return found["r"][0] if found["r"] else None

        mat.height, given = height_source.material_height(heights, [mat.ref, key, prim.GetName()], scene, find)
        st = found["r"][1] if found.get("r") else (preview_st(prim) if given else None) or "st"
        scene.materials.append(mat)
        by_path[key] = (mat, st)
    if any(mat.height is not None for mat, _ in by_path.values()):
        done, undrawn = set(), []
        for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
            if not prim.IsA(UsdGeom.Mesh):
                continue
            for bound, subset in _bindings(prim):
                mat, st = by_path.get(_canonical(bound.GetPrim()) if bound else None, (None, None))
                once = (_canonical(prim), subset[0] if subset else None)  # instances share their prototype
                if mat is None or mat.height is None or once in done:
                    continue
                done.add(once)
                mesh = read_mesh(scene, prim, mat, st, subset)
                if mesh is not None:
                    scene.meshes.append(mesh)
                else:
                    undrawn.append((mat, f"primvars:{st}"))
        scene.drop_undrawn(undrawn)
    warn_unresolved_assets(scene, missing)


def _canonical(prim) -> str:
    """A prim's path, or for an instance proxy its prototype's (shared by every instance)."""
    return str(prim.GetPrimInPrototype().GetPath() if prim.IsInstanceProxy() else prim.GetPath())


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


def _warn_unresolved(scene: Scene, source: UsdSource) -> None:
    """One warning per kept arc, naming the materials bound through it (unresolved: they
    get no CSM, and usd-core cannot tell what they hold)."""
    if not source.kept:
        return
    stage = source.stage
    targets = set()
    for prim in stage.Traverse():
        if prim.IsA(UsdShade.Material):
            targets.add(prim.GetPath())
        for rel in prim.GetRelationships():
            if rel.GetName().startswith("material:binding"):
                targets.update(t for t in rel.GetTargets() if t.IsPrimPath())
    groups: dict[tuple, list] = {}
    for arc in source.kept:  # one warning per file, however many prims reference it
        groups.setdefault((arc.kind, arc.authored, arc.resolved), []).append(arc)
    for arcs in groups.values():
        arcs.sort(key=lambda a: str(a.site))
    for (kind, authored, resolved), arcs in groups.items():
        bound = set()
        for arc in arcs:
            if kind == "subLayer":
                arc.bound = sorted(t for t in targets if not stage.GetPrimAtPath(t))
            else:
                arc.bound = sorted(t for t in targets if t.HasPrefix(arc.site))
            bound.update(arc.bound)
        names = ", ".join(map(str, sorted(bound)[:3])) + (", ..." if len(bound) > 3 else "")
        sites = ", ".join(f"<{a.site}>" for a in arcs[:2]) + (f" and {len(arcs) - 2} more" if len(arcs) > 2 else "")
        scene.warn("CSM402", f"{kind} {authored!r} at {sites} is kept as authored and copied, but usd-core cannot read "
                   f"it (no plugin for .{Path(resolved).suffix[1:]}): {len(bound)} material(s) through it "
                   f"unresolved, left without CSM" + (f" ({names})" if bound else ""))


def _warn_variants(scene: Scene, stage) -> None:
    """One warning when the output (flattened) keeps only the selected variants."""
    sets = []
    for prim in stage.Traverse():
        vsets = prim.GetVariantSets()
        sets += [(prim.GetPath(), n) for n in vsets.GetNames() if len(vsets.GetVariantSet(n).GetVariantNames()) > 1]
    if sets:
        names = ", ".join(f"<{p}> {n}" for p, n in sets[:3]) + (", ..." if len(sets) > 3 else "")
        scene.warn("CSM403", f"{len(sets)} variant set(s) ({names}) are flattened to their current selections; "
                   f"the other variants are not in the output")
