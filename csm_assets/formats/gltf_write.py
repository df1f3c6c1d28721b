"""Writing a converted glTF/GLB scene: TANGENT attributes, the CSM material extension,
the step map as an image (a file beside a .gltf, bytes inside a .glb), external files.

Everything the converter did not touch is written back as it was read.
"""

from __future__ import annotations

import copy
import shutil
import urllib.parse
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..convert.links import missing
from ..convert.output_folder import free_name
from ..references import is_data_uri
from ..scene import Material, Mesh, Scene, safe_name
from . import gltf_container as gc
from .csm_params import GLTF_EXTENSION, gltf_properties
from .gltf_compress import add_tangents, compress, warn_growth
from .gltf_prune import prune

EXTENSION = GLTF_EXTENSION
TRANSFORM = "KHR_texture_transform"
LINEAR, REPEAT, CLAMP, MIRRORED = 9729, 10497, 33071, 33648


def output_path(scene: Scene, out_dir: Path) -> Path:
    return Path(out_dir) / scene.path.name


def embeds_step_maps(scene: Scene) -> bool:
    """Whether the written scene holds its step maps itself (a GLB), so that no step
    map file belongs beside it."""
    return bool(scene.source.binary)


def write(scene: Scene, out_dir) -> list[Path]:
    """Write the converted scene into ``out_dir``; the paths written (scene, copied files).

    Step map files must already exist (``material.csm.step_map``); a GLB embeds them, a
    .gltf names them (they belong in ``out_dir``). Meshes with ``corner_tangents`` get a
    TANGENT attribute, split where corners disagree.
    """
    doc: gc.Document = scene.source
    out_dir = Path(out_dir)
    replaced: set[int] = set()
    for mesh in scene.meshes:
        if mesh.corner_tangents is not None:
            replaced |= _write_tangents(doc, mesh)
    prune(doc, replaced, doc.orphaned_views)  # old tangents, what a split primitive or Draco no longer reads
    plain = compress(doc)  # Draco and meshopt input written back compressed
    converted = [m for m in scene.materials if m.csm is not None]
    reserved = {p.name for m in converted for p in m.csm.step_maps()} | scene.reserved | {output_path(scene, out_dir).name}
    written = _relocate_external(doc, out_dir, reserved, scene.others, scene.links, scene.warn,
                                 scene.published or out_dir, scene.said_missing)
    images: dict[Path, int] = {}
    for mat in converted:
        _add_material_extension(doc, mat, images)
    target = output_path(scene, out_dir)
    data = gc.glb_bytes(doc) if doc.binary else gc.gltf_bytes(doc)
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    if plain:
        warn_growth(scene, plain, len(data))
    return [target, *written]


def _write_tangents(doc: gc.Document, mesh: Mesh) -> set[int]:
    """TANGENT for one primitive; where corners of one vertex disagree (uv mirrors), the
    vertex is split and every attribute and morph target is gathered to the new vertices.
    Returns the accessors it replaced (for :func:`~csm_assets.formats.gltf_prune.prune`)."""
    from ..tangents.frames import weld_corners

    mi, pi = mesh.ref
    prim = doc.json["meshes"][mi]["primitives"][pi]
    welded = weld_corners({"source": mesh.faces, "tangent": mesh.corner_tangents.astype(np.float32)})
    source = welded.vertices["source"]
    tangents = welded.vertices["tangent"]
    replaced = {prim["attributes"]["TANGENT"]} if "TANGENT" in prim["attributes"] else set()
    if len(np.unique(source)) == len(source):  # one tangent per used vertex: no split
        per_vertex = np.tile(np.array([1, 0, 0, 1], np.float32), (len(mesh.positions), 1))
        per_vertex[source] = tangents
        prim["attributes"]["TANGENT"] = add_tangents(doc, prim, per_vertex)
        return replaced
    replaced |= {prim["indices"]} if "indices" in prim else set()
    for attrs in [prim["attributes"], *prim.get("targets", [])]:
        for name, acc in list(attrs.items()):
            if name == "TANGENT":
                continue
            replaced.add(acc)
            old = doc.json["accessors"][acc]
            data = gc.read_accessor(doc, acc, raw=True)[source]
            attrs[name] = gc.add_accessor(doc, data, normalized=bool(old.get("normalized")),
                                          minmax=name == "POSITION" or "min" in old)
    prim["attributes"]["TANGENT"] = add_tangents(doc, prim, tangents)
    index_type = np.uint16 if len(source) < 65535 else np.uint32
    prim["indices"] = gc.add_accessor(doc, welded.faces.reshape(-1).astype(index_type),
                                      target=gc.ELEMENT_ARRAY_BUFFER)
    return replaced


def _add_material_extension(doc: gc.Document, mat: Material, images: dict[Path, int]) -> None:
    """The CSM extension on ``mat``: its step map texture samples the same uv set, with the
    same KHR_texture_transform and wrap modes, as the texture its heights came from; a quadrant
    map's second image (``stepMap2Texture``) and the levels images (``stepMapLevelsTexture``,
    ``stepMap2LevelsTexture``: docs/reference/levels.md) likewise."""
    csm = mat.csm
    placement = doc.placements.get(mat.ref, {})
    wraps = step_map_wraps(csm.tile, placement.get("wraps"))
    sampler = _index_of(doc.items("samplers"), {"magFilter": LINEAR, "minFilter": LINEAR,
                                                "wrapS": wraps[0], "wrapT": wraps[1]})
    infos = {}
    levels = dict(zip(("stepMapLevelsTexture", "stepMap2LevelsTexture"), csm.levels_images))
    for key, path in (("stepMapTexture", csm.step_map), ("stepMap2Texture", csm.step_map2), *levels.items()):
        if path is None:
            continue
        texture = _index_of(doc.items("textures"), {"source": _image(doc, Path(path), images), "sampler": sampler})
        info = {"index": texture, "texCoord": placement.get("texCoord", mat.height.tex_coord)}
        if placement.get("transform") is not None:
            info["extensions"] = {TRANSFORM: copy.deepcopy(placement["transform"])}
            _use(doc, TRANSFORM)
        infos[key] = info
    material = doc.json["materials"][mat.ref]
    material.setdefault("extensions", {})[EXTENSION] = {**infos, **gltf_properties(csm)}
    _use(doc, EXTENSION)


def _image(doc: gc.Document, path: Path, images: dict[Path, int]) -> int:
    """The index of the image of step map file ``path`` (added once: a file beside a .gltf,
    bytes in a bufferView of a .glb)."""
    if path not in images:
        if doc.binary:
            view = gc.add_view(doc, path.read_bytes())
            image = {"bufferView": view, "mimeType": "image/png", "name": path.stem}
        else:
            image = {"uri": path.name, "mimeType": "image/png", "name": path.stem}
        doc.items("images").append(image)
        images[path] = len(doc.json["images"]) - 1
    return images[path]


def _index_of(items: list, wanted: dict) -> int:
    """The index of an entry equal to ``wanted`` in ``items`` (a sampler, a texture), appended
    when there is none: two step maps sampled alike share one."""
    for i, item in enumerate(items):
        if item == wanted:
            return i
    items.append(wanted)
    return len(items) - 1


def step_map_wraps(tile, height_wraps=None) -> list[int]:
    """The step map sampler's (wrapS, wrapT): REPEAT on a tiled axis (its cones wrap), else
    the height texture's clamped or mirrored mode (cones that do not wrap are safe under
    both), CLAMP_TO_EDGE where the height repeats but ``--no-tile`` said the axis does not."""
    height_wraps = height_wraps or [REPEAT, REPEAT]
    return [REPEAT if t else (w if w in (CLAMP, MIRRORED) else CLAMP) for t, w in zip(tile, height_wraps)]


def _use(doc: gc.Document, extension: str) -> None:
    used = doc.items("extensionsUsed")
    if extension not in used:
        used.append(extension)


def _relocate_external(doc: gc.Document, out_dir: Path, reserved: set[str], others: dict, links=None,
                       warn=None, published=None, said=frozenset()) -> list[Path]:
    """Write buffers and copy images that live in files into ``out_dir`` (flat, safe
    names that avoid ``reserved`` and other scenes' files, :func:`~csm_assets.convert.output_folder.free_name`),
    pointing their uris there; an image ``links`` can name where it is (:class:`~csm_assets.convert.links.Links`)
    is not copied, its uri the escaped relative path. A GLB's BIN chunk and data URIs stay
    inside. A missing image is named where the scene names it, relative to ``published`` (the output
    folder, else ``out_dir``), with a CSM404 through ``warn``.
    Returns the paths written."""
    written, taken = [], set(reserved)
    for i, buf in enumerate(doc.json.get("buffers", [])):
        uri = buf.get("uri")
        if uri is None or is_data_uri(uri):
            continue
        data = bytes(doc.buffers[i][: buf["byteLength"]])
        name = free_name(safe_name(Path(uri).stem), ".bin", taken, others, content=data)
        taken.add(name)
        with atomic_path(out_dir / name) as tmp:
            tmp.write_bytes(data)
        buf["uri"] = name
        written.append(out_dir / name)
    for i, image in enumerate(doc.json.get("images", [])):
        src = doc.image_files.get(i)
        if src is None:
            continue
        link = links.to(src) if links is not None else None
        if link is not None:
            image["uri"] = urllib.parse.quote(link)
            continue
        uri = image["uri"]
        if not src.is_file() and (where := missing(published or out_dir, src)) is not None:
            if warn is not None and src not in said:  # said: a CSM101 named it already
                warn("CSM404", f"image {i} names {uri!r}, which resolves to nothing; named where the scene names "
                               f"it ({where}), so the output names a file it does not have")
            image["uri"] = urllib.parse.quote(where)
            continue
        name = free_name(safe_name(Path(uri).stem), Path(uri).suffix.lower(), taken, others,
                         content=src if src.is_file() else None)
        taken.add(name)
        if src.is_file():
            with atomic_path(out_dir / name) as tmp:
                shutil.copyfile(src, tmp)
            written.append(out_dir / name)
        image["uri"] = name
    return written
