"""Finding a USD material's height texture through its shading connections.

A material's ``UsdPreviewSurface`` (through ``outputs:surface`` or ``outputs:displacement``)
whose ``inputs:displacement`` is connected, through any chain of NodeGraph/Material interface
inputs and outputs, to a ``UsdUVTexture``: its file, channel, scale/bias of that channel,
wrap modes, and the uv primvar read by the ``UsdPrimvarReader_float2`` feeding ``inputs:st``.
A cycle or a dangling connection is a warning naming the material, never a hang.

Depth: the channel's ``inputs:scale`` is the displacement factor (model units per unit of
texture value, ``inputs:bias`` the offset); where it is not authored the scene states no
factor, and the depth is the default texture-space depth (``DEFAULT_DEPTH``, 0.1), as for an
OBJ ``bump`` without ``-bm``: its fallback 1 would make a relief one model unit deep.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from pxr import Ar, Gf, Sdf, Usd, UsdShade

from ..errors import FormatError
from ..height_source import DEFAULT_DEPTH
from ..scene import HeightInput, Scene, Texture, UdimSet, safe_name
from ..udim import set_name as udim_name
from .usd_assets import anchored_path, asset_bytes, udim_tiles

CHANNELS = {"r": 0, "g": 1, "b": 2, "a": 3, "rgb": None}
MIMES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".exr": "image/x-exr"}


class Cycle(Exception):
    pass


class Dangling(Exception):
    """A connection to a prim or property that does not exist."""



def source_of(attr: Usd.Attribute):
    """Follow the connections of a shading attribute to the shader output that drives
    it: ``(UsdShade.Shader, output name)``, or ``(None, last attribute)`` where the chain
    ends in a value. Raises Cycle (naming the attribute) on a connection cycle."""
    seen = set()
    while True:
        if attr.GetPath() in seen:
            raise Cycle(str(attr.GetPath()))
        seen.add(attr.GetPath())
        if UsdShade.Input.IsInput(attr):
            sources, invalid = UsdShade.Input(attr).GetConnectedSources()
        else:
            sources, invalid = UsdShade.Output(attr).GetConnectedSources()
        if not sources and invalid:
            raise Dangling(f"{attr.GetPath()} is connected to {invalid[0]}, which does not exist")
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


def input_value(shader: UsdShade.Shader, name: str, default=None):
    """The value of a shader input, through interface connections."""
    inp = shader.GetInput(name)
    if not inp:
        return default
    src, attr = source_of(inp.GetAttr())
    if src is not None:
        return default
    value = attr.Get()
    return default if value is None else value


def shader_id(shader: UsdShade.Shader) -> str:
    return str(shader.GetShaderId() or "")


def preview_surface(material: UsdShade.Material) -> UsdShade.Shader | None:
    for terminal in ("surface", "displacement"):
        out = material.GetOutput(terminal)
        if out:
            shader, _ = source_of(out.GetAttr())
            if shader is not None and shader_id(shader) == "UsdPreviewSurface":
                return shader
    return None


def preview_st(prim) -> str | None:
    """The uv primvar a material's textures read (for command-line heights)."""
    try:
        ps = preview_surface(UsdShade.Material(prim))
        if ps is None:
            return None
        for inp in ps.GetInputs():
            shader, _ = source_of(inp.GetAttr())
            if shader is not None and shader_id(shader) == "UsdUVTexture":
                return st_primvar(shader)
    except (Cycle, Dangling):
        return None
    return None


def find_height(scene: Scene, material: UsdShade.Material, name: str):
    """``(HeightInput, uv primvar name)`` of a material, or None (with a warning where
    something was there but unusable)."""
    try:
        ps = preview_surface(material)
        if ps is None or not ps.GetInput("displacement"):
            return None
        tex, output = source_of(ps.GetInput("displacement").GetAttr())
        if tex is None:
            return None
        if shader_id(tex) != "UsdUVTexture":
            scene.warn("CSM103", f"displacement comes from {tex.GetPath()} ({shader_id(tex) or 'no id'}), not a "
                       "UsdUVTexture; left without CSM", f"material {name!r}")
            return None
        st = st_primvar(tex)
        asset = input_value(tex, "file")
        channel = CHANNELS.get(output, 0)
        k = channel if isinstance(channel, int) else 0
        factors = [_factor(scene, tex, key, default, k) for key, default in (("scale", 1.0), ("bias", 0.0))]
        wraps = tuple(str(input_value(tex, w, "useMetadata")) for w in ("wrapS", "wrapT"))
    except Cycle as c:
        scene.warn("CSM104", f"shader connections form a cycle at {c}; left without CSM", f"material {name!r}")
        return None
    except Dangling as d:
        scene.warn("CSM104", f"{d}; left without CSM", f"material {name!r}")
        return None
    if None in factors:
        return None
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        scene.warn("CSM103", f"the displacement UsdUVTexture {tex.GetPath()} names no file; left without CSM",
                   f"material {name!r}")
        return None
    udim, attr = None, source_of(tex.GetInput("file").GetAttr())[1]
    if "<UDIM>" in asset.path:
        udim = _udim_set(scene, attr, asset, name)
        texture = None if udim is None else udim.first()
    else:
        texture = _texture(scene, asset.path, asset.resolvedPath, name, attr)
    if texture is None:
        return None
    tile = None if "useMetadata" in wraps else (wraps[0] == "repeat", wraps[1] == "repeat")
    if udim is not None:  # tiles are separate uv squares: clamped at their borders (--tile says otherwise)
        tile = (False, False)
    # an unauthored inputs:scale states no factor (its fallback 1 would be a relief 1 model unit deep):
    # the default texture-space depth, as for an OBJ bump without -bm
    depth = None if input_value(tex, "scale", None) is not None else DEFAULT_DEPTH
    return HeightInput(texture, 0, channel, False, factors[0], factors[1],
                       "UsdPreviewSurface displacement", tile, depth, udim), st


def _factor(scene: Scene, tex: UsdShade.Shader, key: str, default: float, k: int) -> float | None:
    """Channel ``k`` of a UsdUVTexture's ``inputs:scale``/``inputs:bias`` (float4): None,
    with a warning, for another type; FormatError for NaN or infinite values."""
    value = input_value(tex, key, None)
    where = f"{tex.GetPath()}.inputs:{key}"
    if value is None:
        return default
    if not isinstance(value, (Gf.Vec4f, Gf.Vec4d, Gf.Vec4h)):
        type_name = tex.GetInput(key).GetTypeName()
        scene.warn("CSM103", f"{where} is a {type_name}, not the float4 UsdUVTexture declares; its material is "
                   "left without CSM")
        return None
    if not all(math.isfinite(v) for v in value):
        raise FormatError(scene.path, f"{where} holds NaN or infinite values")
    return float(value[k])


def st_primvar(tex: UsdShade.Shader) -> str:
    """The primvar a UsdUVTexture reads its uvs from (``st`` when nothing says)."""
    inp = tex.GetInput("st")
    if not inp:
        return "st"
    shader, _ = source_of(inp.GetAttr())
    if shader is not None and shader_id(shader) == "UsdTransform2d":
        shader = source_of(shader.GetInput("in").GetAttr())[0] if shader.GetInput("in") else None
    if shader is not None and shader_id(shader).startswith("UsdPrimvarReader"):
        return str(input_value(shader, "varname", "st") or "st")
    return "st"


def _udim_set(scene: Scene, attr, asset: Sdf.AssetPath, material: str) -> UdimSet | None:
    """The tiles of a UDIM height set the attribute ``attr`` holds (``asset``), or None with a warning
    when none resolves or one cannot be read."""
    files = udim_tiles(attr, asset.path)
    if not files:
        scene.warn("CSM101", f"height texture {asset.path} is a UDIM set with no tile (1001-1999) found; left "
                   "without CSM", f"material {material!r}")
        scene.said_missing.add(Path(anchored_path(attr, asset.path)))  # check_assets' CSM404 leaves it out
        return None
    tiles = {t: _texture(scene, asset.path.replace("<UDIM>", str(t)), f, material) for t, f in files.items()}
    if None in tiles.values():
        return None
    first = files[min(files)]
    pattern = None if Ar.IsPackageRelativePath(first) else Path(first).with_name(Path(asset.path).name)
    return UdimSet({t: dataclasses.replace(x, name=udim_name(asset.path)) for t, x in tiles.items()}, pattern)


def _texture(scene: Scene, authored: str, resolved: str, material: str, attr=None) -> Texture | None:
    """The height texture ``authored`` resolved as ``resolved``; None with a CSM101 when missing (named in
    ``scene.said_missing`` where the attribute ``attr`` holding it anchors it)."""
    name = safe_name(Path(authored).stem)
    if not resolved:
        scene.warn("CSM101", f"height texture {authored} is missing; left without CSM", f"material {material!r}")
        if attr is not None:
            scene.said_missing.add(Path(anchored_path(attr, authored)))  # check_assets' CSM404 leaves it out
        return None
    if Ar.IsPackageRelativePath(resolved):
        data = asset_bytes(resolved)
        if data is None:
            scene.warn("CSM102", f"height texture {authored} cannot be read from the package; left without CSM",
                       f"material {material!r}")
            return None
        return Texture(name, data=data, mime=MIMES.get(Path(authored).suffix.lower()))
    return Texture(name, path=Path(resolved))
