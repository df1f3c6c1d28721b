"""glTF 2.0 / GLB scenes: height textures in, tangents and the CSM material out.

Heights are found, in this order, in a material's ``KHR_materials_displacement``
(``displacementGeometryTexture``, factor, offset), ``KHR_materials_parallax_mapping``
(``heightTexture``, ``heightFactor``) or ``extras.csm_height`` (``{"index", "texCoord",
"channel", "invert", "scale"}``); all read the red channel unless told otherwise.
The document's JSON is checked (:mod:`.gltf_schema`) before anything is read; Draco and
meshopt geometry is decoded (:mod:`.gltf_decode`) only where a step map goes; uvs are
read through the height texture's ``KHR_texture_transform``. Writing is
:mod:`.gltf_write`; everything else in the document is written back as it was read.
"""

from __future__ import annotations

import math
import urllib.parse
from pathlib import Path

import numpy as np

from ..errors import FormatError, case_hint
from ..height_source import material_height
from ..references import is_data_uri
from ..scene import HeightInput, Material, Mesh, Scene, Texture, resolve_reference, safe_name
from . import gltf_container as gc
from . import gltf_decode
from .gltf_write import CLAMP, EXTENSION, LINEAR, REPEAT, TRANSFORM, embeds_step_maps, output_path, write
from .registry import module_bits, module_stores_tangents

__all__ = ["read", "write", "output_path", "embeds_step_maps", "EXTENSION", "LINEAR", "REPEAT", "CLAMP"]

STORES_TANGENTS = module_stores_tangents("gltf")
STEP_MAP_BITS = module_bits("gltf")  # glTF images are PNG (or JPEG): no float step maps
# where a material's own textures are, for the uv set and transform of a command-line height
OTHER_TEXTURES = [("pbrMetallicRoughness", "baseColorTexture"), (None, "normalTexture"),
                  ("pbrMetallicRoughness", "metallicRoughnessTexture"), (None, "occlusionTexture"),
                  (None, "emissiveTexture")]


def read(path, heights: dict | None = None, *, allow_outside: bool = False, root=None) -> Scene:
    """The scene of a .gltf/.glb file. ``heights`` maps material names to height
    texture files (or :class:`HeightInput`) that override what the file says.
    Files the document names outside the project root ``root`` (default: its folder) are
    refused unless ``allow_outside``."""
    path = Path(path)

    def resolve(uri: str) -> Path:
        return resolve_reference(path, path.parent, urllib.parse.unquote(uri), allow_outside=allow_outside,
                                 root=root)

    doc = gc.load(path, resolve)
    scene = Scene(path, "glb" if doc.binary else "gltf", source=doc, inputs=[path, *doc.files])
    doc.image_files = {i: resolve(im["uri"]) for i, im in enumerate(doc.json.get("images", []))
                       if isinstance(im.get("uri"), str) and not is_data_uri(im["uri"])}
    scene.inputs += [f for f in doc.image_files.values() if f.is_file()]
    scene.absent += [f for f in doc.image_files.values() if not f.is_file()]
    heights = heights or {}
    textures: dict[int, Texture | None] = {}
    for i, m in enumerate(doc.json.get("materials", [])):
        name = m.get("name") or f"material{i}"
        mat = Material(name, ref=i)
        mat.height, given = material_height(heights, [name], scene,
                                            lambda m=m, name=name, i=i: _find_height(doc, scene, m, name, textures, i))
        info = _other_texture_info(m)
        if given and i not in doc.placements and info is not None:  # the scene places no height texture
            doc.placements[i] = dict(_placement(info), wraps=_wrap_modes(doc, info["index"]))
            mat.height.tex_coord = _uv_set(info)
            mat.height.tile = tuple(w == REPEAT for w in doc.placements[i]["wraps"])
        scene.materials.append(mat)
    if any(m.height is not None for m in scene.materials):
        gltf_decode.decode_meshopt(doc)
    undrawn: list = []  # (material, uvs) of primitives that cannot carry the relief
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            m = prim.get("material")
            mat = scene.materials[m] if m is not None else None
            if mat is None or mat.height is None:
                continue  # costs nothing: geometry is read only where a step map goes
            name = f"{mesh.get('name') or f'mesh{mi}'}[{pi}]"
            loaded = _primitive(doc, scene, prim, name, mat, f"/meshes/{mi}/primitives/{pi}")
            if loaded is not None:
                loaded.ref = (mi, pi)
                scene.meshes.append(loaded)
            else:
                undrawn.append((mat, f"TEXCOORD_{mat.height.tex_coord}"))
    scene.drop_undrawn(undrawn)
    return scene


def _other_texture_info(m: dict) -> dict | None:
    """Where a height named on the command line (or a converted scene's step map, as
    verify reads it) is placed, as nothing else says: the material's CSM step map if it
    has one, else the first of its own textures (base colour first)."""
    csm = m.get("extensions", {}).get(EXTENSION)
    if isinstance(csm, dict) and isinstance(csm.get("stepMapTexture"), dict):
        return csm["stepMapTexture"]
    for parent, key in OTHER_TEXTURES:
        holder = m.get(parent, {}) if parent else m
        if key in holder:
            return holder[key]
    return None


def _placement(info: dict) -> dict:
    """How a texture is placed on the surface: its uv set and KHR_texture_transform."""
    return {"texCoord": info.get("texCoord", 0), "transform": info.get("extensions", {}).get(TRANSFORM)}


def _uv_set(info: dict) -> int:
    """The uv set a textureInfo samples (KHR_texture_transform's texCoord overrides)."""
    return int(info.get("extensions", {}).get(TRANSFORM, {}).get("texCoord", info.get("texCoord", 0)))


def _find_height(doc, scene, m: dict, name: str, textures: dict, index: int) -> HeightInput | None:
    ext = m.get("extensions", {})
    found = None
    if "KHR_materials_displacement" in ext:
        d = ext["KHR_materials_displacement"]
        info = d.get("displacementGeometryTexture")
        found = (info, float(d.get("displacementGeometryFactor", 1.0)),
                 float(d.get("displacementGeometryOffset", 0.0)), "KHR_materials_displacement")
    elif "KHR_materials_parallax_mapping" in ext:
        d = ext["KHR_materials_parallax_mapping"]
        info = d.get("heightTexture")
        found = ({"index": info} if isinstance(info, int) else info,
                 float(d.get("heightFactor", 1.0)), 0.0, "KHR_materials_parallax_mapping")
    elif isinstance(m.get("extras"), dict) and "csm_height" in m["extras"]:
        d = m["extras"]["csm_height"]
        found = (d, float(d.get("scale", 1.0)), 0.0, "extras.csm_height")
    if found is None:
        return None
    info, scale, offset, origin = found
    if not isinstance(info, dict) or not isinstance(info.get("index"), int):
        scene.warn("CSM103", f"{origin} names no texture index; left without CSM", f"material {name!r}")
        return None
    if not (math.isfinite(scale) and math.isfinite(offset)):
        raise doc.fail(f"material {name!r}: {origin} has a non-finite factor or offset")
    if info["index"] not in textures:
        textures[info["index"]] = _texture(doc, scene, info["index"], name)
    tex = textures[info["index"]]
    if tex is None:
        return None
    extra = info if origin == "extras.csm_height" else {}
    place = _placement(info)
    place["wraps"] = _wrap_modes(doc, info["index"])
    doc.placements[index] = place
    return HeightInput(tex, _uv_set(info), extra.get("channel", 0), bool(extra.get("invert", False)),
                       scale, offset, origin, tuple(w == REPEAT for w in place["wraps"]))


def _wrap_modes(doc, texture_index: int) -> list[int]:
    """The texture's (wrapS, wrapT) sampler modes, REPEAT when unsaid. Clamped and
    mirrored axes do not tile: mirrored copies are never nearer than the texels they mirror."""
    sampler = doc.json["textures"][texture_index].get("sampler")
    s = doc.json["samplers"][sampler] if sampler is not None else {}
    return [s.get("wrapS", REPEAT), s.get("wrapT", REPEAT)]


def _texture(doc, scene, index: int, material: str) -> Texture | None:
    image_index = doc.json["textures"][index].get("source")
    if image_index is None:
        scene.warn("CSM103", f"texture {index} has no image; left without CSM", f"material {material!r}")
        return None
    image = doc.json["images"][image_index]
    uri, mime = image.get("uri"), image.get("mimeType")
    name = safe_name(image.get("name") or (Path(uri).stem if uri and not is_data_uri(uri) else "")
                     or f"image{image_index}")
    if uri is None:
        if image.get("bufferView") is None:
            scene.warn("CSM103", f"image {image_index} has neither uri nor buffer view; left without CSM",
                       f"material {material!r}")
            return None
        return Texture(name, data=gc.view_bytes(doc, image["bufferView"]), mime=mime)
    if is_data_uri(uri):
        try:
            return Texture(name, data=gc.data_uri_bytes(doc.path, uri), mime=uri[5:].split(";")[0] or mime)
        except FormatError as e:
            scene.warn("CSM102", f"{e}; left without CSM", f"material {material!r}")
            return None
    file = doc.image_files[image_index]
    if not file.is_file():
        scene.warn("CSM101", f"height texture {uri} is missing{case_hint(file)}; left without CSM", f"material {material!r}")
        scene.said_missing.add(file)
        return None
    return Texture(name, path=file, mime=mime)


def apply_transform(uvs: np.ndarray, transform: dict | None) -> np.ndarray:
    """Texture coordinates as KHR_texture_transform maps them: scale, then rotation, then offset.

    Args:
        uvs: ``(V, 2)`` float.
        transform: the extension's object (``scale``, ``rotation`` in radians, ``offset``);
            None or empty: unchanged.

    Returns:
        ``(V, 2)``: the transformed uvs (``uvs`` itself when there is no transform).
    """
    if not transform:
        return uvs
    sx, sy = transform.get("scale", [1.0, 1.0])
    ox, oy = transform.get("offset", [0.0, 0.0])
    r = float(transform.get("rotation", 0.0))
    u, v = uvs[:, 0] * sx, uvs[:, 1] * sy
    c, s = math.cos(r), math.sin(r)
    return np.column_stack([c * u + s * v + ox, -s * u + c * v + oy])


def _primitive(doc, scene, prim: dict, name: str, mat: Material, pointer: str) -> Mesh | None:
    """The mesh of a primitive that can carry the relief (Draco decoded only then), else None."""
    attrs = prim.get("attributes", {})
    if prim.get("mode", 4) != 4:
        scene.warn("CSM204", f"primitive mode {prim.get('mode')} is not triangles; no tangents", f"mesh {name}")
        return None
    uv_key = f"TEXCOORD_{mat.height.tex_coord}"
    draco = prim.get("extensions", {}).get(gltf_decode.DRACO)
    named = {**attrs, **(draco.get("attributes") if isinstance(draco, dict) and
                         isinstance(draco.get("attributes"), dict) else {})}
    if "POSITION" not in named or uv_key not in named:
        scene.warn("CSM202", f"no POSITION or {uv_key}; no tangents", f"mesh {name} (material {mat.name!r})")
        return None
    gltf_decode.decode_draco(doc, prim, pointer)
    attrs = prim.get("attributes", {})

    def attribute(key):
        if key not in attrs:
            return None
        values = gc.read_accessor(doc, attrs[key]).astype(np.float64)
        if not np.isfinite(values).all():
            raise doc.fail(f"mesh {name}: {key} (accessor {attrs[key]}) holds NaN or infinite values")
        return values

    pos, normals, tangents = attribute("POSITION"), attribute("NORMAL"), attribute("TANGENT")
    uvs = apply_transform(attribute(uv_key), doc.placements.get(mat.ref, {}).get("transform"))
    if not np.isfinite(uvs).all():
        raise doc.fail(f"mesh {name}: KHR_texture_transform of material {mat.name!r} makes uvs infinite")
    if "indices" in prim:
        faces = gc.read_accessor(doc, prim["indices"])[:, 0].astype(np.int64)
    else:
        faces = np.arange(len(pos), dtype=np.int64)
    if len(faces) % 3 or (len(faces) and faces.max() >= len(pos)):
        raise doc.fail(f"mesh {name}: indices out of range or not a multiple of 3")
    return Mesh(name, pos, faces.reshape(-1, 3), normals, uvs, tangents, mat, uv_origin="top-left")
