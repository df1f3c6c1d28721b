"""Read back the CSM material a converted scene carries, one function per format.

Each returns ``{material ref: StoredCsm}`` with the refs the scene readers give
materials (glTF: material index; OBJ: material name; USD: material prim path), so
:mod:`csm_assets.verify.scene` can pair them with the meshes the readers load.
The settings are the ones ``convert`` writes: the glTF extension
``EXT_materials_cone_step_mapping``, the MTL's ``csm_*`` statements, the USD
``CsmConeStepSurface`` shader's inputs. The step map's bits come from the image.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import FormatError, no_file
from ..scene import Texture, resolve_reference
from .csm_params import GLTF_EXTENSION, MTL_IMAGES, PARAMETERS, parse_text, read_values


@dataclass
class StoredCsm:
    """What a converted material says about its step map and how to draw it.

    The attributes of :data:`~csm_assets.formats.csm_params.PARAMETERS`, plus the texture and
    its uv set.

    Attributes:
        name (str): the material's name.
        step_map (Texture): the step map image.
        depth_scale (float): texture-space depth: uv units per unit of height.
        max_ratio (float): the cone ratio G = 1 stands for.
        tile (tuple): ``(tile_u, tile_v)``.
        variant (str): the shader variant.
        steps (int): its step count (0: none or the default).
        min_step (float): the minimum step in texels.
        tex_coord (int): glTF: the TEXCOORD set the step map uses.
        height_scale (float): ``raw = height_offset + height_scale * R``.
        height_offset (float): see ``height_scale``.
        self_shadow (bool): the material shades itself.
        light_size (float): the light's angular radius in radians (0: hard shadows).
        step_map2 (Texture | None): a quadrant map's second image (variant ``"quadrant"`` only).
        tiles (dict): a UDIM set (USD ``<UDIM>`` asset paths): tile -> (its image, its second image or
            None); ``step_map``/``step_map2`` are then the lowest tile's. Empty for one map.
        levels (tuple): the levels images (docs/reference/levels.md) of ``step_map`` and of
            ``step_map2``: ``()`` for a map without levels, ``(Texture,)`` or, for a quadrant map,
            ``(Texture, Texture)`` (glTF ``stepMapLevelsTexture``/``stepMap2LevelsTexture``, MTL
            ``csm_map_levels``/``csm_map2_levels``, USD ``stepMapLevels``/``stepMap2Levels``).
    """

    name: str                 # the material's name
    step_map: Texture
    depth_scale: float        # texture-space depth: uv units per unit of height
    max_ratio: float = 1.0
    tile: tuple = (True, True)
    variant: str = "exact"
    steps: int = 0
    min_step: float = 1.0
    tex_coord: int = 0        # glTF: the TEXCOORD set the step map uses
    height_scale: float = 1.0
    height_offset: float = 0.0
    self_shadow: bool = False
    light_size: float = 0.0   # the light's angular radius in radians (0: hard shadows)
    step_map2: Texture | None = None  # a quadrant map's second image (variant "quadrant" only)
    tiles: dict = field(default_factory=dict)  # a UDIM set (USD): tile -> (image, second image or None)
    levels: tuple = ()  # the levels images of step_map (and step_map2): () without levels


def check_second(stored: StoredCsm, path, where: str) -> StoredCsm:
    """``stored`` when its second image and its variant agree: the quadrant variant draws a
    quadrant map's two images and nothing else. FormatError naming ``path`` and ``where`` (the
    material) otherwise."""
    if stored.variant == "quadrant" and stored.step_map2 is None:
        raise FormatError(path, f"{where}: variant 'quadrant' needs the quadrant map's second image "
                                f"({SECOND_NAMES}), which it does not name")
    if stored.variant != "quadrant" and stored.step_map2 is not None:
        raise FormatError(path, f"{where}: a second step map image ({SECOND_NAMES}) is drawn only by variant "
                                f"'quadrant', not {stored.variant!r}")
    return stored


SECOND_NAMES = "glTF stepMap2Texture, MTL csm_map2, USD stepMap2"
LEVELS_NAMES = ("glTF stepMapLevelsTexture, MTL csm_map_levels, USD stepMapLevels",
                "glTF stepMap2LevelsTexture, MTL csm_map2_levels, USD stepMap2Levels")


def check_levels(stored: StoredCsm, levels: list, path, where: str) -> StoredCsm:
    """``stored`` with its levels images ``levels`` ``[first's or None, second's or None]``: none,
    or one for each image it has. FormatError naming ``path`` and ``where`` otherwise."""
    images = 1 if stored.step_map2 is None else 2
    named = [lv is not None for lv in levels]
    if any(named) and named != [True] * images + [False] * (2 - images):
        wanted = " and ".join(n.split(",")[0] for n in LEVELS_NAMES[:images])
        raise FormatError(path, f"{where}: a map with levels names one levels image for each of its {images} "
                                f"image(s) ({wanted}), got {', '.join(LEVELS_NAMES[i] for i in range(2) if named[i])}")
    stored.levels = tuple(lv for lv in levels if lv is not None)
    return stored


def gltf_materials(doc) -> dict[int, StoredCsm]:
    """The CSM materials of a loaded glTF document.

    Args:
        doc: from :func:`csm_assets.formats.gltf_container.load`.

    Returns:
        ``{material index: StoredCsm}`` of the materials with the extension.

    Raises:
        FormatError: an extension with a bad or missing value, or an image it cannot find.
    """
    out = {}
    for i, m in enumerate(doc.json.get("materials", [])):
        ext = m.get("extensions", {}).get(GLTF_EXTENSION) if isinstance(m, dict) else None
        if ext is None:
            continue
        name = m.get("name") or f"material{i}"
        where = f"material {name!r} {GLTF_EXTENSION}"
        if not isinstance(ext, dict) or not isinstance(ext.get("stepMapTexture"), dict):
            raise FormatError(doc.path, f"{where}: no stepMapTexture object")
        texture, tex_coord = gltf_texture(doc, ext, "stepMapTexture", f"material{i}_step_map", where)
        second = None
        if "stepMap2Texture" in ext:
            if not isinstance(ext["stepMap2Texture"], dict):
                raise FormatError(doc.path, f"{where}: stepMap2Texture is not a textureInfo object")
            second, uv2 = gltf_texture(doc, ext, "stepMap2Texture", f"material{i}_step_map2", where)
            if uv2 != tex_coord:
                raise FormatError(doc.path, f"{where}: stepMap2Texture.texCoord {uv2} is not stepMapTexture's "
                                            f"{tex_coord} (the two images of a quadrant map share one uv set)")
        values = read_values(lambda p: ext.get(p.name), doc.path, where)
        levels = [gltf_texture(doc, ext, key, f"material{i}_{key}", where)[0] if key in ext else None
                  for key in ("stepMapLevelsTexture", "stepMap2LevelsTexture")]
        out[i] = check_levels(check_second(StoredCsm(name, texture, tex_coord=tex_coord, step_map2=second, **values),
                                           doc.path, where), levels, doc.path, where)
    return out


def gltf_texture(doc, ext: dict, key: str, name: str, where: str) -> tuple[Texture, int]:
    """(the image, texCoord) of textureInfo ``ext[key]`` of a CSM extension."""
    from . import gltf_container as gc

    if not isinstance(ext[key], dict):
        raise FormatError(doc.path, f"{where}: {key} is not a textureInfo object")
    try:
        image = doc.json["images"][doc.json["textures"][ext[key]["index"]]["source"]]
    except (KeyError, IndexError, TypeError):
        raise FormatError(doc.path, f"{where}: {key} names no image") from None
    if isinstance(image.get("uri"), str):
        texture = Texture(name, path=resolve_reference(doc.path, Path(doc.path).parent, image["uri"]))
    elif isinstance(image.get("bufferView"), int):
        texture = Texture(name, data=gc.view_bytes(doc, image["bufferView"]), mime=image.get("mimeType"))
    else:
        raise FormatError(doc.path, f"{where}: the {key} image has neither uri nor bufferView")
    tex_coord = ext[key].get("texCoord", 0)
    if isinstance(tex_coord, bool) or not isinstance(tex_coord, int) or tex_coord < 0:
        raise FormatError(doc.path, f"{where}: {key}.texCoord must be an integer >= 0, got {tex_coord!r}")
    return texture, tex_coord


def obj_materials(scene_path, mtl_path, mtl: dict) -> dict[str, StoredCsm]:
    """The CSM materials of an MTL already parsed.

    Args:
        scene_path (str | os.PathLike): the OBJ (texture paths resolve against it).
        mtl_path (str | os.PathLike): the MTL, for messages and paths.
        mtl: ``{name: MtlMaterial}`` with their ``lines``.

    Returns:
        ``{name: StoredCsm}`` of the materials with a ``csm_map``.

    Raises:
        FormatError: a ``csm_*`` statement with a bad or missing value.
    """
    out = {}
    for name, m in mtl.items():
        values = {}
        for raw in m.lines:
            parts = raw.strip().split(None, 1)
            if parts and parts[0].lower().startswith("csm_"):
                values[parts[0].lower()] = parts[1].strip() if len(parts) > 1 else ""
        if "csm_map" not in values:
            continue
        where = f"material {name!r} csm_* statements"
        parsed, problems = {}, []
        for p in PARAMETERS:
            if p.mtl in values:
                try:
                    parsed[p.name] = parse_text(p, values[p.mtl])
                except ValueError as e:
                    problems.append(f"{p.mtl} {e}")
        if problems:
            raise FormatError(mtl_path, f"{where}: {'; '.join(problems)}")
        stored = read_values(lambda p: parsed.get(p.name), mtl_path, where)
        texture = Texture(f"{name}_step_map", path=resolve_reference(scene_path, Path(mtl_path).parent,
                                                                     values["csm_map"]))
        second, *levels = (None if key not in values else Texture(
            f"{name}_step_{key[4:]}", path=resolve_reference(scene_path, Path(mtl_path).parent, values[key]))
            for key in MTL_IMAGES[1:])
        out[name] = check_levels(check_second(StoredCsm(name, texture, step_map2=second, **stored), mtl_path, where),
                                 levels, mtl_path, where)
    return out


def usd_materials(stage, scene_path) -> dict[str, StoredCsm]:
    """The CSM materials of a USD stage: each material holding a ``CsmConeStepSurface`` shader.

    Args:
        stage: a ``Usd.Stage``, or the USD reader's ``Scene.source``, which holds one.
        scene_path (str | os.PathLike): the stage's file (asset paths resolve against it).

    Returns:
        ``{material path: StoredCsm}``.

    Raises:
        FormatError: a shader input with a bad or missing value.
    """
    from pxr import Usd, UsdShade

    from .usd_assets import udim_tiles
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
            sets = {}  # key -> {tile: image}; a plain map is tile 0
            for key in ("stepMap", "stepMap2", "stepMapLevels", "stepMap2Levels"):
                asset = inputs.get(key)
                if asset is None and key != "stepMap":
                    continue
                files = {0: asset.resolvedPath} if asset is not None and asset.resolvedPath else {}
                if asset is not None and "<UDIM>" in asset.path:
                    files = udim_tiles(shader.GetInput(key).GetAttr(), asset.path)
                if not files:
                    raise FormatError(scene_path, f"material {prim.GetPath()}: the CSM shader's {key} "
                                                  f"{getattr(asset, 'path', None)!r} does not resolve")
                sets[key] = {t: _usd_texture(f, asset.path, prim.GetName(), scene_path, key) for t, f in files.items()}
            firsts = {k: v[min(v)] for k, v in sets.items()}
            tiles = {} if 0 in sets["stepMap"] else \
                {t: (x, sets.get("stepMap2", {}).get(t)) for t, x in sets["stepMap"].items()}
            where = f"material {prim.GetPath()}"
            values = read_values(lambda p: _usd_value(inputs, p), scene_path, where, fallback=True)
            stored = check_second(StoredCsm(prim.GetName(), firsts["stepMap"], step_map2=firsts.get("stepMap2"),
                                            tiles=tiles, **values), scene_path, where)
            out[str(prim.GetPath())] = check_levels(stored, [firsts.get("stepMapLevels"), firsts.get("stepMap2Levels")],
                                                    scene_path, where)
            break
    return out


def _usd_value(inputs: dict, p):
    """The value of parameter ``p`` among a CSM shader's inputs (``tile`` from the ints
    ``tileU``/``tileV``); None when not authored."""
    if p.kind != "tile":
        return inputs.get(p.name)
    pair = [inputs.get("tileU"), inputs.get("tileV")]
    if pair == [None, None]:
        return None
    pair = [1 if t is None else t for t in pair]
    ints = all(isinstance(t, int) and not isinstance(t, bool) and t in (0, 1) for t in pair)
    return [bool(t) for t in pair] if ints else pair


def _usd_texture(resolved: str, authored: str, name: str, scene_path, key: str = "stepMap") -> Texture:
    """The step map image a USD asset (``authored``) resolves to (input ``key``): a file, or bytes
    inside a .usdz package."""
    from pxr import Ar

    label = f"{name}_" + {"stepMap": "step_map", "stepMap2": "step_map2"}.get(key, key)
    if Path(resolved).is_file():
        return Texture(label, path=Path(resolved))
    if not Ar.IsPackageRelativePath(resolved):  # a FIFO, a folder, a device: never opened (a FIFO blocks)
        raise FormatError(resolved, f"{no_file(resolved)} (the CSM shader's {key} {authored!r} of material "
                                    f"{name!r}: expected an image file)")
    found = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if found is None:
        raise FormatError(scene_path, f"cannot open the CSM shader's {key} {authored!r} of material {name!r}")
    return Texture(label, data=bytes(found.GetBuffer()),
                   mime="image/x-exr" if resolved.lower().rstrip("]").endswith(".exr") else "image/png")
