"""Read back the CSM material a converted scene carries, one function per format.

Each returns ``{material ref: StoredCsm}`` with the refs the scene readers give
materials (glTF: material index; OBJ: material name; USD: material prim path), so
:mod:`csm_assets.verify_scene` can pair them with the meshes the readers load.
The settings are the ones ``convert`` writes: the glTF extension
``EXT_materials_cone_step_mapping``, the MTL's ``csm_*`` statements, the USD
``CsmConeStepSurface`` shader's inputs. The step map's bits come from the image.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import FormatError
from ..scene import Texture, resolve_reference

GLTF_EXTENSION = "EXT_materials_cone_step_mapping"


@dataclass
class StoredCsm:
    """What a converted material says about its step map and how to draw it."""

    name: str                 # the material's name
    step_map: Texture
    depth_scale: float        # texture-space depth: uv units per unit of height
    max_ratio: float = 1.0
    tile: tuple = (True, True)
    variant: str = "exact"
    steps: int = 0
    min_step: float = 1.0
    tex_coord: int = 0        # glTF: the TEXCOORD set the step map uses


def checked(stored: StoredCsm, path, where: str) -> StoredCsm:
    """``stored``, or FormatError naming ``path`` and ``where`` for settings no shader can draw."""
    from ..render import VARIANTS

    problems = []
    if stored.variant not in VARIANTS:
        problems.append(f"variant {stored.variant!r} is none of {', '.join(VARIANTS)}")
    if not 0 <= stored.steps <= 127:
        problems.append(f"steps {stored.steps} is outside 0..127")
    if not (stored.depth_scale >= 0 and stored.depth_scale < float("inf")):
        problems.append(f"depth {stored.depth_scale!r} is not a finite number >= 0")
    if not (stored.max_ratio > 0 and stored.max_ratio < float("inf")):
        problems.append(f"max ratio {stored.max_ratio!r} is not a finite number > 0")
    if not 0 < stored.min_step <= 1:
        problems.append(f"min step {stored.min_step!r} is outside (0, 1] texels")
    if problems:
        raise FormatError(path, f"{where}: {'; '.join(problems)}")
    return stored


def _number(scene_path, where: str, value, default, kind=float):
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FormatError(scene_path, f"{where}: expected a number, got {value!r}")
    v = kind(value)
    if v != v or v in (float("inf"), float("-inf")):
        raise FormatError(scene_path, f"{where}: not a finite number ({value!r})")
    return v


def gltf_materials(doc) -> dict[int, StoredCsm]:
    """The CSM materials of a loaded glTF document (:func:`gltf_container.load`)."""
    from . import gltf_container as gc

    out = {}
    for i, m in enumerate(doc.json.get("materials", [])):
        ext = m.get("extensions", {}).get(GLTF_EXTENSION) if isinstance(m, dict) else None
        if ext is None:
            continue
        name = m.get("name") or f"material{i}"
        where = f"material {name!r} {GLTF_EXTENSION}"
        if not isinstance(ext, dict) or not isinstance(ext.get("stepMapTexture"), dict):
            raise FormatError(doc.path, f"{where}: no stepMapTexture object")
        try:
            image_index = doc.json["textures"][ext["stepMapTexture"]["index"]]["source"]
            image = doc.json["images"][image_index]
        except (KeyError, IndexError, TypeError):
            raise FormatError(doc.path, f"{where}: stepMapTexture names no image") from None
        if isinstance(image.get("uri"), str):
            texture = Texture(f"material{i}_step_map", path=resolve_reference(doc.path, Path(doc.path).parent,
                                                                             image["uri"]))
        elif isinstance(image.get("bufferView"), int):
            texture = Texture(f"material{i}_step_map", data=gc.view_bytes(doc, image["bufferView"]),
                              mime=image.get("mimeType"))
        else:
            raise FormatError(doc.path, f"{where}: the step map image has neither uri nor bufferView")
        tile = ext.get("tile", [True, True])
        if not (isinstance(tile, list) and len(tile) == 2 and all(isinstance(t, bool) for t in tile)):
            raise FormatError(doc.path, f"{where}: tile must be two booleans, got {tile!r}")
        out[i] = StoredCsm(
            name, texture, _number(doc.path, f"{where} depthScale", ext.get("depthScale"), None),
            _number(doc.path, f"{where} maxRatio", ext.get("maxRatio"), 1.0),
            (tile[0], tile[1]),
            str(ext.get("variant", "exact")), _number(doc.path, f"{where} steps", ext.get("steps"), 0, int),
            _number(doc.path, f"{where} minStep", ext.get("minStep"), 1.0),
            _number(doc.path, f"{where} texCoord", ext["stepMapTexture"].get("texCoord"), 0, int))
        if out[i].depth_scale is None:
            raise FormatError(doc.path, f"{where}: no depthScale")
        checked(out[i], doc.path, where)
    return out


def obj_materials(scene_path, mtl_path, mtl: dict) -> dict[str, StoredCsm]:
    """The CSM materials of an MTL already parsed (``{name: MtlMaterial}`` with ``lines``)."""
    out = {}
    for name, m in mtl.items():
        values = {}
        for raw in m.lines:
            parts = raw.strip().split(None, 1)
            if parts and parts[0].lower().startswith("csm_"):
                values[parts[0].lower()] = parts[1].strip() if len(parts) > 1 else ""
        if "csm_map" not in values:
            continue
        try:
            tile = [bool(int(t)) for t in values.get("csm_tile", "1 1").split()]
            stored = StoredCsm(
                name, Texture(f"{name}_step_map", path=resolve_reference(scene_path, Path(mtl_path).parent,
                                                                          values["csm_map"])),
                float(values["csm_depth"]), float(values.get("csm_max_ratio", 1.0)),
                (tile[0], tile[1]), values.get("csm_variant", "exact"), int(values.get("csm_steps", 0)),
                float(values.get("csm_min_step", 1.0)))
        except (KeyError, ValueError, IndexError) as e:
            raise FormatError(mtl_path, f"material {name!r}: malformed csm_* statements ({e})") from None
        out[name] = checked(stored, mtl_path, f"material {name!r} csm_* statements")
    return out


def usd_materials(stage, scene_path) -> dict[str, StoredCsm]:
    """The CSM materials of a USD stage (or the USD reader's ``Scene.source``, which holds one):
    each material holding a ``CsmConeStepSurface`` shader."""
    from pxr import Usd, UsdShade

    from .usd_shader import SHADER_ID

    stage = getattr(stage, "stage", stage)
    out = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdShade.Material):
            continue
        for child in Usd.PrimRange(prim):
            shader = UsdShade.Shader(child)
            if not (child.IsA(UsdShade.Shader) and shader.GetShaderId() == SHADER_ID):
                continue
            inputs = {i.GetBaseName(): i.Get() for i in shader.GetInputs()}
            asset = inputs.get("stepMap")
            if asset is None or not asset.resolvedPath:
                raise FormatError(scene_path, f"material {prim.GetPath()}: the CSM shader's stepMap "
                                              f"{getattr(asset, 'path', None)!r} does not resolve")
            where = f"material {prim.GetPath()}"
            out[str(prim.GetPath())] = checked(StoredCsm(
                prim.GetName(), _usd_texture(asset, prim.GetName(), scene_path),
                _number(scene_path, f"{where} depthScale", inputs.get("depthScale"), 0.1),
                _number(scene_path, f"{where} maxRatio", inputs.get("maxRatio"), 1.0),
                (bool(inputs.get("tileU", 1)), bool(inputs.get("tileV", 1))),
                str(inputs.get("variant", "exact")), _number(scene_path, f"{where} steps", inputs.get("steps"), 0,
                                                             int),
                _number(scene_path, f"{where} minStep", inputs.get("minStep"), 1.0)), scene_path, where)
            break
    return out


def _usd_texture(asset, name: str, scene_path) -> Texture:
    """The step map a resolved USD asset names: a file, or bytes inside a .usdz package."""
    from pxr import Ar

    resolved = asset.resolvedPath
    if Path(resolved).is_file():
        return Texture(f"{name}_step_map", path=Path(resolved))
    found = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if found is None:
        raise FormatError(scene_path, f"cannot open the step map {asset.path!r}")
    return Texture(f"{name}_step_map", data=bytes(found.GetBuffer()),
                   mime="image/x-exr" if resolved.lower().rstrip("]").endswith(".exr") else "image/png")
