"""Compressed input written back compressed: what :mod:`.gltf_decode` decoded is encoded again
on writing, so a Draco or meshopt scene keeps its size (issue 35).

- **Draco** (``KHR_draco_mesh_compression``): each decoded primitive is encoded again with
  DracoPy, its TANGENT (and every attribute but POSITION, NORMAL and TEXCOORD_0) as a generic
  attribute (lossless floats: DracoPy 2.2 quantizes no generic attribute, so a float TANGENT costs
  16 bytes a vertex). Quantization bits are the
  input's where its decoded values show them (:func:`grid_bits`, :func:`octahedral_bits`: the
  fewest bits whose grid holds every value, so the input's values come back unchanged), else
  DracoPy's defaults (14 bits for positions, lossless normals and uvs). The primitive gets new
  accessors (counts and bounds from decoding the new data); uncompressed fallback views are
  written only where the input had them, and the extension goes back into the
  ``extensionsUsed``/``extensionsRequired`` lists that declared it.
- **meshopt** (``EXT_meshopt_compression``/``KHR_meshopt_compression``): views the converter
  left alone get their original compressed bytes back (filters kept); the views it added to a
  mesh (tangents, a split primitive's attributes and indices) are encoded with the meshopt
  package (no filter). As in the input, the uncompressed views lie in a fallback buffer with no
  data, unless the input carried the uncompressed data too.
- **Quantized** (``KHR_mesh_quantization``): tangents are written as normalized int8 or int16
  (:func:`add_tangents`, the NORMAL's type), as the input's normals are; floats in a Draco
  primitive (DracoPy takes no signed integers).

What cannot be encoded again (a generic attribute of a type DracoPy does not take, indices of
one byte) stays plain and is named by :func:`compress`; the writer warns (CSM211) with the sizes.
"""

from __future__ import annotations

import copy
import hashlib

import numpy as np

from . import gltf_container as gc
from .gltf_decode import DRACO
from .gltf_prune import prune

QUANTIZATION = "KHR_mesh_quantization"
DRACO_DEFAULT_BITS = 14  # DracoPy's position bits where the input's cannot be told
GENERIC_TYPES = (np.float32, np.uint8, np.uint16, np.uint32)  # what DracoPy takes as a generic attribute
FLOAT_EPS = 4 * np.finfo(np.float32).eps


def grid_bits(values: np.ndarray, most: int = 30) -> int | None:
    """The fewest bits ``b`` whose Draco quantization grid holds every row of ``values`` ``(N, K)``
    (origin the minimum per axis, ``2**b - 1`` steps over the largest extent); None when none up
    to ``most`` does (unquantized floats). Re-quantizing with ``b`` bits gives the values back."""
    values = np.asarray(values, np.float64)
    if len(values) == 0:
        return None
    lo = values.min(0)
    extent = float((values.max(0) - lo).max())
    if extent == 0:
        return 1
    scale = float(np.abs(values).max())
    for bits in range(1, most + 1):
        step = extent / (2 ** bits - 1)
        tol = 0.01 + FLOAT_EPS * scale / step
        if tol > 0.25:
            return None  # float32 cannot tell a finer grid
        q = (values - lo) / step
        if np.abs(q - np.round(q)).max() < tol:
            return bits
    return None


def octahedral_bits(normals: np.ndarray, most: int = 30) -> int | None:
    """The fewest bits of Draco's octahedral normal quantization that hold every unit vector of
    ``normals`` ``(N, 3)`` (integer vectors whose absolute components sum to ``2**(b-1) - 1``);
    None when none up to ``most`` does."""
    n = np.asarray(normals, np.float64)
    if len(n) == 0:
        return None
    l1 = np.abs(n).sum(1, keepdims=True)
    if (l1 == 0).any():
        return None
    n = n / l1
    for bits in range(2, most + 1):
        center = 2 ** (bits - 1) - 1
        tol = 0.01 + FLOAT_EPS * center
        if tol > 0.25:
            return None
        q = n * center
        if np.abs(q - np.round(q)).max() < tol:
            return bits
    return None


def add_tangents(doc: gc.Document, prim: dict, tangents: np.ndarray) -> int:
    """A new TANGENT accessor for ``tangents`` ``(V, 4)`` float: normalized int8 or int16 (the
    type of the primitive's NORMAL, int8 when it has none of those) where the document declares
    KHR_mesh_quantization, else float32 (and in a Draco primitive, which DracoPy stores as floats).
    Its index."""
    tangents = np.asarray(tangents, np.float32)
    draco = any(r["prim"] is prim for r in doc.compressed.get("draco", {}).get("primitives", []))
    if QUANTIZATION not in doc.json.get("extensionsUsed", []) or draco:
        return gc.add_accessor(doc, tangents)
    normal = doc.json["accessors"][prim["attributes"]["NORMAL"]] if "NORMAL" in prim["attributes"] else {}
    dtype = np.int16 if normal.get("componentType") == 5122 else np.int8
    top = np.iinfo(dtype).max
    return gc.add_accessor(doc, np.round(np.clip(tangents, -1, 1) * top).astype(dtype), normalized=True)


def compress(doc: gc.Document) -> list[str]:
    """Encode again what was decoded (see the module doc); what had to stay plain, one phrase each."""
    plain: list[str] = []
    draco = doc.compressed.get("draco")
    if draco:
        replaced: set[int] = set()
        for record in draco["primitives"]:
            why = _draco(doc, record, replaced)
            if why:
                plain.append(why)
        prune(doc, replaced)
        if any(DRACO in p.get("extensions", {}) for m in doc.json.get("meshes", []) for p in m.get("primitives", [])):
            _declare(doc, DRACO, draco["declared"])
    if doc.compressed.get("meshopt"):
        plain += _meshopt(doc, doc.compressed["meshopt"])
    return plain


def _declare(doc: gc.Document, name: str, lists) -> None:
    for key in lists:
        if name not in doc.json.get(key, []):
            doc.items(key).append(name)


def _draco(doc: gc.Document, record: dict, replaced: set[int]) -> str | None:
    """Encode one decoded primitive again; None, or why it stays plain."""
    import DracoPy

    prim, ext = record["prim"], record["ext"]
    attrs = prim["attributes"]
    names = [n for n in attrs if n in ext["attributes"] or n == "TANGENT"]
    keep_order = len(names) < len(attrs) or bool(prim.get("targets"))  # plain data must line up
    data = {n: gc.read_accessor(doc, attrs[n], raw=True) for n in names}
    count = len(data["POSITION"])
    faces = (gc.read_accessor(doc, prim["indices"])[:, 0] if "indices" in prim else np.arange(count))
    kwargs: dict = {"preserve_order": keep_order}
    generic: dict[int, str] = {}
    for n, values in data.items():
        if n == "POSITION":
            kwargs["quantization_bits"] = grid_bits(values) or DRACO_DEFAULT_BITS
        elif n == "NORMAL" and values.dtype == np.float32:
            kwargs.update(normals=values.astype(np.float64), normal_quantization_bits=octahedral_bits(values))
        elif n == "TEXCOORD_0" and values.dtype == np.float32:
            kwargs.update(tex_coord=values.astype(np.float64), tex_coord_quantization_bits=grid_bits(values))
        elif values.dtype in GENERIC_TYPES:
            generic[len(generic)] = n
        else:
            return f"Draco primitive {record['where']}: {n} is {values.dtype}, which DracoPy does not encode"
    if generic:
        kwargs["generic_attributes"] = {uid: data[n] for uid, n in generic.items()}
    try:
        encoded = DracoPy.encode(data["POSITION"].astype(np.float32), faces.reshape(-1, 3).astype(np.uint32), **kwargs)
    except DracoPy.EncodingFailedException as err:
        return f"Draco primitive {record['where']}: DracoPy cannot encode it ({err})"
    mesh = DracoPy.decode(encoded)
    kinds = {0: "POSITION", 1: "NORMAL", 3: "TEXCOORD_0"}
    ids = {(generic.get(a["unique_id"]) if a["attribute_type"] == 4 else kinds.get(a["attribute_type"])): a
           for a in mesh.attributes}
    decoded_faces = np.asarray(mesh.faces).reshape(-1)
    if keep_order and (len(mesh.points) != count or len(decoded_faces) != len(faces)):
        return f"Draco primitive {record['where']}: DracoPy did not keep its vertex order"
    new_ext = {**copy.deepcopy(ext), "bufferView": gc.add_view(doc, encoded), "attributes": {}}
    for n in names:
        old_index = attrs[n]
        new_ext["attributes"][n] = ids[n]["unique_id"]
        attrs[n] = _accessor(doc, doc.json["accessors"][old_index], np.asarray(ids[n]["data"]), record["fallback"],
                             gc.ARRAY_BUFFER, n == "POSITION")
        replaced.add(old_index)
    if "indices" in prim:
        replaced.add(prim["indices"])
        prim["indices"] = _accessor(doc, doc.json["accessors"][prim["indices"]], decoded_faces,
                                    record["fallback"], gc.ELEMENT_ARRAY_BUFFER, False)
    prim.setdefault("extensions", {})[DRACO] = new_ext
    return None


def _accessor(doc: gc.Document, old: dict, values: np.ndarray, with_view: bool, target: int, minmax: bool) -> int:
    """A new accessor like ``old`` holding ``values`` (rows): its count and bounds, and a buffer
    view of them only ``with_view`` (Draco's uncompressed fallback)."""
    dtype = np.dtype(gc.COMPONENT_TYPES[old["componentType"]])
    values = values.reshape(len(values), -1)
    if dtype.kind in "iu" and values.dtype.kind == "f":
        values = np.round(values)
    if dtype == np.uint16 and target == gc.ELEMENT_ARRAY_BUFFER and len(values) and values.max() >= 65535:
        dtype = np.dtype(np.uint32)
    values = values.astype(dtype)
    acc = {"componentType": gc.COMPONENT_CODES[dtype], "count": len(values), "type": old["type"]}
    if old.get("normalized"):
        acc["normalized"] = True
    if (minmax or "min" in old) and len(values):
        acc["min"], acc["max"] = values.min(0).tolist(), values.max(0).tolist()
    if with_view:
        acc = {"bufferView": gc.add_accessor_view(doc, values, target), **acc}
    doc.items("accessors").append(acc)
    return len(doc.json["accessors"]) - 1


def _geometry_views(doc: gc.Document) -> dict[int, tuple[dict, bool, int]]:
    """view index -> (an accessor of a mesh primitive in it, whether it holds indices, the primitive's mode)."""
    out = {}
    accessors = doc.json.get("accessors", [])
    for mesh in doc.json.get("meshes", []):
        for prim in mesh.get("primitives", []):
            refs = [(a, False) for attrs in [prim["attributes"], *prim.get("targets", [])] for a in attrs.values()]
            refs += [(prim["indices"], True)] if "indices" in prim else []
            for a, is_index in refs:
                if "bufferView" in accessors[a]:
                    out.setdefault(accessors[a]["bufferView"], (accessors[a], is_index, prim.get("mode", 4)))
    return out


def _meshopt_params(view: dict, used: tuple[dict, bool, int]) -> dict | None:
    """The extension's mode, count and byteStride for a new view, None where meshopt cannot take it."""
    acc, is_index, mode = used
    if is_index:
        size = {5123: 2, 5125: 4}.get(acc["componentType"])
        if size is None or view["byteLength"] % size:
            return None
        count = view["byteLength"] // size
        kind = "TRIANGLES" if mode == 4 and count % 3 == 0 else "INDICES"
        return {"byteStride": size, "count": count, "mode": kind}
    stride = view.get("byteStride") or np.dtype(gc.COMPONENT_TYPES[acc["componentType"]]).itemsize * \
        gc.TYPE_SIZES[acc["type"]]
    if stride % 4 or stride > 256 or view["byteLength"] % stride or not view["byteLength"]:
        return None
    return {"byteStride": stride, "count": view["byteLength"] // stride, "mode": "ATTRIBUTES"}


def _encode_meshopt(raw: bytes, params: dict) -> bytes:
    import meshopt

    if params["mode"] == "ATTRIBUTES":
        rows = np.frombuffer(raw, np.uint8).reshape(params["count"], params["byteStride"])
        return meshopt.encode_gltf_buffer(rows, "ATTRIBUTES")
    return meshopt.encode_gltf_buffer(np.frombuffer(raw, np.uint16 if params["byteStride"] == 2 else np.uint32),
                                      params["mode"])


def _meshopt(doc: gc.Document, record: dict) -> list[str]:
    """Compress the views again (see the module doc); what stays plain."""
    views = doc.json.get("bufferViews", [])
    geometry = _geometry_views(doc)
    jobs, plain = [], []
    for i, view in enumerate(views):
        raw = gc.view_bytes(doc, i)
        old = record["views"].get(id(view))
        if old is not None and hashlib.sha256(raw).digest() == old["digest"]:
            jobs.append((view, old["params"], old["data"]))
        elif id(view) not in record["originals"] and i in geometry:
            params = _meshopt_params(view, geometry[i])
            if params is None:
                plain.append(f"buffer view {i} ({view['byteLength']} bytes) cannot be meshopt-encoded")
                continue
            jobs.append((view, params, _encode_meshopt(raw, params)))
    if not jobs:
        return plain
    name = record["name"]
    if record["fallback"]:  # the uncompressed views go to a buffer without data, as in the input
        fallback = {"byteLength": 0, "extensions": {name: {"fallback": True}}}
        placeholders = []
        for view, _, _ in jobs:
            placeholders.append({k: view[k] for k in ("buffer", "byteOffset", "byteLength") if k in view})
            fallback["byteLength"] += -fallback["byteLength"] % 4
            view["buffer"], view["byteOffset"] = len(doc.json["buffers"]), fallback["byteLength"]
            fallback["byteLength"] += view["byteLength"]
        doc.json["buffers"].append(fallback)
        doc.buffers.append(bytearray())
        views.extend(placeholders)
        prune(doc, (), range(len(views) - len(placeholders), len(views)))  # the plain bytes leave
    for view, params, data in jobs:
        fresh = doc.json["bufferViews"].pop(gc.add_view(doc, data))  # prune made a new list
        view.setdefault("extensions", {})[name] = {"buffer": fresh["buffer"], "byteOffset": fresh["byteOffset"],
                                                   "byteLength": len(data), **params}
    _declare(doc, name, record["declared"])
    return plain


def warn_growth(scene, plain: list[str], scene_bytes: int) -> None:
    """CSM211 for ``scene``: what stayed plain, with the input's and the output's size (its file,
    ``scene_bytes``, and its buffer files)."""
    doc = scene.source
    before = sum(p.stat().st_size for p in [doc.path, *doc.files] if p.is_file())
    after = scene_bytes + (0 if doc.binary else sum(
        len(doc.buffers[i]) for i, b in enumerate(doc.json.get("buffers", []))
        if isinstance(b.get("uri"), str) and not b["uri"].startswith("data:")))
    scene.warn("CSM211", f"{'; '.join(plain)}: written uncompressed, {before / 1e6:.2f} MB in, {after / 1e6:.2f} MB "
               "out (--ignore CSM211 accepts it)")
