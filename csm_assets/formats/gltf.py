"""glTF 2.0 / GLB scenes: height textures in, tangents and the CSM material out.

Heights are found, in this order, in a material's ``KHR_materials_displacement``
(``displacementGeometryTexture``, factor, offset), ``KHR_materials_parallax_mapping``
(``heightTexture``, ``heightFactor``) or ``extras.csm_height`` (``{"index", "texCoord",
"channel", "invert", "scale"}``); all read the red channel unless told otherwise.
Everything else in the document is written back as it was read.
"""

from __future__ import annotations

import shutil
import urllib.parse
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import FormatError
from ..height_source import override
from ..scene import (
    HeightInput,
    Material,
    Mesh,
    Scene,
    Texture,
    resolve_reference,
    safe_name,
)
from . import gltf_container as gc

STORES_TANGENTS = True
STEP_MAP_BITS = (8, 16)  # glTF images are PNG (or JPEG): no float step maps
EXTENSION = "EXT_materials_cone_step_mapping"
LINEAR, REPEAT, CLAMP = 9729, 10497, 33071


def read(path, heights: dict | None = None, *, allow_outside: bool = False) -> Scene:
    """The scene of a .gltf/.glb file. ``heights`` maps material names to height
    texture files (or :class:`HeightInput`) that override what the file says.
    Files the document names outside its folder are refused unless ``allow_outside``."""
    path = Path(path)

    def resolve(uri: str) -> Path:
        return resolve_reference(path, path.parent, urllib.parse.unquote(uri), allow_outside=allow_outside)

    doc = gc.load(path, resolve)
    scene = Scene(path, "glb" if doc.binary else "gltf", source=doc, inputs=[path, *doc.files])
    doc.image_files = {i: resolve(im["uri"]) for i, im in enumerate(doc.json.get("images", []))
                       if isinstance(im.get("uri"), str) and not im["uri"].startswith("data:")}
    scene.inputs += [f for f in doc.image_files.values() if f.is_file()]
    heights = heights or {}
    for i, m in enumerate(doc.json.get("materials", [])):
        name = m.get("name") or f"material{i}"
        mat = Material(name, ref=i)
        if name in heights:
            mat.height = override(heights[name], scene, lambda: _find_height(doc, scene, m, name))
        else:
            mat.height = _find_height(doc, scene, m, name)
        scene.materials.append(mat)
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            m = prim.get("material")
            mat = scene.materials[m] if isinstance(m, int) and 0 <= m < len(scene.materials) else None
            if mat is None or mat.height is None:
                continue  # costs nothing: geometry is read only where a step map goes
            name = f"{mesh.get('name') or f'mesh{mi}'}[{pi}]"
            loaded = _primitive(doc, scene, prim, name, mat)
            if loaded is not None:
                loaded.ref = (mi, pi)
                scene.meshes.append(loaded)
    return scene


def _find_height(doc, scene, m: dict, name: str) -> HeightInput | None:
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
        scene.warn(f"material {name!r}: {origin} names no texture index; left without CSM")
        return None
    tex = _texture(doc, scene, info["index"], name)
    if tex is None:
        return None
    extra = info if origin == "extras.csm_height" else {}
    return HeightInput(tex, int(info.get("texCoord", 0)), extra.get("channel", 0),
                       bool(extra.get("invert", False)), scale, offset, origin,
                       _wraps(doc, info["index"]))


def _wraps(doc, texture_index: int) -> tuple[bool, bool]:
    """Whether the texture repeats along u and v (REPEAT, the default). Clamped and
    mirrored axes do not: mirrored copies are never nearer than the texels they mirror."""
    sampler = doc.json["textures"][texture_index].get("sampler")
    samplers = doc.json.get("samplers", [])
    s = samplers[sampler] if isinstance(sampler, int) and 0 <= sampler < len(samplers) else {}
    return s.get("wrapS", REPEAT) == REPEAT, s.get("wrapT", REPEAT) == REPEAT


def _texture(doc, scene, index: int, material: str) -> Texture | None:
    try:
        image_index = doc.json["textures"][index]["source"]
        image = doc.json["images"][image_index]
    except (KeyError, IndexError, TypeError):
        scene.warn(f"material {material!r}: texture {index} has no image; left without CSM")
        return None
    uri, mime = image.get("uri"), image.get("mimeType")
    name = safe_name(image.get("name") or (Path(uri).stem if uri and not uri.startswith("data:") else "")
                      or f"image{image_index}")
    if uri is None:
        try:
            return Texture(name, data=gc.view_bytes(doc, image["bufferView"]), mime=mime)
        except (KeyError, IndexError, TypeError):
            scene.warn(f"material {material!r}: image {image_index} has neither uri nor buffer view")
            return None
    if uri.startswith("data:"):
        try:
            return Texture(name, data=gc.data_uri_bytes(doc.path, uri), mime=uri[5:].split(";")[0] or mime)
        except FormatError as e:
            scene.warn(f"material {material!r}: {e}")
            return None
    file = doc.image_files[image_index]
    if not file.is_file():
        scene.warn(f"material {material!r}: height texture {uri} is missing; left without CSM")
        return None
    return Texture(name, path=file, mime=mime)


def _primitive(doc, scene, prim: dict, name: str, mat: Material) -> Mesh | None:
    attrs = prim.get("attributes", {})
    if prim.get("mode", 4) != 4:
        scene.warn(f"mesh {name}: primitive mode {prim.get('mode')} is not triangles; no tangents")
        return None
    uv_key = f"TEXCOORD_{mat.height.tex_coord}"
    if "POSITION" not in attrs or uv_key not in attrs:
        scene.warn(f"mesh {name} (material {mat.name!r}): no POSITION or {uv_key}; no tangents")
        return None
    pos = gc.read_accessor(doc, attrs["POSITION"]).astype(np.float64)
    uvs = gc.read_accessor(doc, attrs[uv_key]).astype(np.float64)
    normals = gc.read_accessor(doc, attrs["NORMAL"]).astype(np.float64) if "NORMAL" in attrs else None
    tangents = gc.read_accessor(doc, attrs["TANGENT"]).astype(np.float64) if "TANGENT" in attrs else None
    if "indices" in prim:
        faces = gc.read_accessor(doc, prim["indices"])[:, 0].astype(np.int64)
    else:
        faces = np.arange(len(pos), dtype=np.int64)
    if len(faces) % 3 or (len(faces) and faces.max() >= len(pos)):
        raise doc.fail(f"mesh {name}: indices out of range or not a multiple of 3")
    return Mesh(name, pos, faces.reshape(-1, 3), normals, uvs, tangents, mat, uv_origin="top-left")



def output_path(scene: Scene, out_dir: Path) -> Path:
    return Path(out_dir) / scene.path.name


def write(scene: Scene, out_dir) -> list[Path]:
    """Write the converted scene into ``out_dir``; the paths written (scene, copied files).

    Step map files must already be in ``out_dir`` (``material.csm.step_map``). Meshes
    with ``corner_tangents`` get a TANGENT attribute, split where corners disagree.
    """
    doc: gc.Document = scene.source
    out_dir = Path(out_dir)
    for mesh in scene.meshes:
        if mesh.corner_tangents is not None:
            _write_tangents(doc, mesh)
    converted = [m for m in scene.materials if m.csm is not None]
    reserved = {m.csm.step_map.name for m in converted}
    written = [] if doc.binary else _relocate_external(doc, out_dir, reserved)
    for mat in converted:
        _add_material_extension(doc, mat)
    target = output_path(scene, out_dir)
    with atomic_path(target) as tmp:
        tmp.write_bytes(gc.glb_bytes(doc) if doc.binary else gc.gltf_bytes(doc))
    return [target, *written]


def _write_tangents(doc: gc.Document, mesh: Mesh) -> None:
    """TANGENT for one primitive; where corners of one vertex disagree (uv mirrors), the
    vertex is split and every attribute and morph target is gathered to the new vertices."""
    from ..tangents import weld_corners

    mi, pi = mesh.ref
    prim = doc.json["meshes"][mi]["primitives"][pi]
    welded = weld_corners({"source": mesh.faces, "tangent": mesh.corner_tangents.astype(np.float32)})
    source = welded.vertices["source"]
    tangents = welded.vertices["tangent"]
    if len(np.unique(source)) == len(source):  # one tangent per used vertex: no split
        per_vertex = np.tile(np.array([1, 0, 0, 1], np.float32), (len(mesh.positions), 1))
        per_vertex[source] = tangents
        prim["attributes"]["TANGENT"] = gc.add_accessor(doc, per_vertex)
        return
    for attrs in [prim["attributes"], *prim.get("targets", [])]:
        for name, acc in list(attrs.items()):
            if name == "TANGENT":
                continue
            old = doc.json["accessors"][acc]
            data = gc.read_accessor(doc, acc, raw=True)[source]
            attrs[name] = gc.add_accessor(doc, data, normalized=bool(old.get("normalized")),
                                          minmax=name == "POSITION" or "min" in old)
    prim["attributes"]["TANGENT"] = gc.add_accessor(doc, tangents)
    index_type = np.uint16 if len(source) < 65535 else np.uint32
    prim["indices"] = gc.add_accessor(doc, welded.faces.reshape(-1).astype(index_type),
                                      target=gc.ELEMENT_ARRAY_BUFFER)


def _add_material_extension(doc: gc.Document, mat: Material) -> None:
    csm = mat.csm
    if doc.binary:
        view = gc.add_view(doc, Path(csm.step_map).read_bytes())
        image = {"bufferView": view, "mimeType": "image/png", "name": csm.step_map.stem}
    else:
        image = {"uri": csm.step_map.name, "mimeType": "image/png", "name": csm.step_map.stem}
    doc.items("images").append(image)
    wrap = [REPEAT if t else CLAMP for t in csm.tile]
    doc.items("samplers").append({"magFilter": LINEAR, "minFilter": LINEAR,
                                  "wrapS": wrap[0], "wrapT": wrap[1]})
    doc.items("textures").append({"source": len(doc.json["images"]) - 1,
                                  "sampler": len(doc.json["samplers"]) - 1})
    material = doc.json["materials"][mat.ref]
    material.setdefault("extensions", {})[EXTENSION] = {
        "stepMapTexture": {"index": len(doc.json["textures"]) - 1, "texCoord": mat.height.tex_coord},
        "depthScale": csm.depth_scale, "maxRatio": csm.max_ratio, "tile": list(csm.tile),
        "heightScale": csm.height_scale, "heightOffset": csm.height_offset,
        "variant": csm.variant, "steps": csm.steps, "minStep": csm.min_step,
    }
    used = doc.items("extensionsUsed")
    if EXTENSION not in used:
        used.append(EXTENSION)


def _relocate_external(doc: gc.Document, out_dir: Path, reserved: set[str]) -> list[Path]:
    """Write buffers and copy images that live in files into ``out_dir`` (flat, safe
    names that avoid ``reserved``), pointing their uris there. Returns the paths written."""
    written, taken = [], set(reserved)

    def free_name(stem: str, suffix: str) -> str:
        name, n = f"{stem}{suffix}", 1
        while name in taken:
            name, n = f"{stem}_{n}{suffix}", n + 1
        taken.add(name)
        return name

    for i, buf in enumerate(doc.json.get("buffers", [])):
        uri = buf.get("uri")
        if uri is None or uri.startswith("data:"):
            continue
        name = free_name(safe_name(Path(uri).stem), ".bin")
        with atomic_path(out_dir / name) as tmp:
            tmp.write_bytes(bytes(doc.buffers[i][: buf["byteLength"]]))
        buf["uri"] = name
        written.append(out_dir / name)
    for i, image in enumerate(doc.json.get("images", [])):
        src = doc.image_files.get(i)
        if src is None:
            continue
        uri = image["uri"]
        name = free_name(safe_name(Path(uri).stem), Path(uri).suffix.lower())
        if src.is_file():
            with atomic_path(out_dir / name) as tmp:
                shutil.copyfile(src, tmp)
            written.append(out_dir / name)
        image["uri"] = name
    return written
