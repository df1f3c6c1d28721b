"""Compressed glTF geometry made plain: Draco primitives and meshopt buffer views.

``KHR_draco_mesh_compression`` is decoded with DracoPy (Google's Draco decoder) and
``EXT_meshopt_compression`` / ``KHR_meshopt_compression`` with meshopt (meshoptimizer's
decoder). Decoded data goes into the document's own new-data buffer as ordinary,
4-byte aligned buffer views; the extension is removed from what was decoded and from
``extensionsUsed``/``extensionsRequired`` once nothing uses it, and meshopt's fallback
buffers, then unused, are dropped. Without the decoder package, or on corrupt data,
a FormatError names the file and the extension. What was decoded is recorded in
``doc.compressed`` (the primitives, the views and their compressed bytes, which lists declared
the extension) so that :mod:`.gltf_compress` encodes it again on writing; the compressed bytes
themselves are left to :func:`~.gltf_prune.prune` (``doc.orphaned_views``).
"""

from __future__ import annotations

import copy
import hashlib

import numpy as np

from .. import limits
from . import gltf_container as gc

DRACO = "KHR_draco_mesh_compression"
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
MODES = {"ATTRIBUTES", "TRIANGLES", "INDICES"}
FILTERS = {"NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR"}


def _require(doc: gc.Document, module: str, extension: str, package: str):
    try:
        return __import__(module)
    except ImportError:
        raise doc.fail(f"uses {extension}, but its decoder is not installed (pip install {package})") from None


def meshopt_views(doc: gc.Document) -> list[int]:
    """Indices of the buffer views compressed with meshopt."""
    return [i for i, v in enumerate(doc.json.get("bufferViews", []))
            if any(k in v.get("extensions", {}) for k in MESHOPT)]


def decode_meshopt(doc: gc.Document) -> int:
    """Decode every meshopt-compressed buffer view in place; the number decoded."""
    views = meshopt_views(doc)
    if not views:
        return 0
    name = next(k for k in MESHOPT if k in doc.json["bufferViews"][views[0]]["extensions"])
    meshopt = _require(doc, "meshopt", name, "meshopt")
    buffers = [doc.json["buffers"][doc.json["bufferViews"][i]["buffer"]] for i in views]
    record = doc.compressed["meshopt"] = {"name": name, "declared": _declared(doc, name), "views": {},
                                          "originals": {id(v): v for v in doc.json["bufferViews"]},
                                          "fallback": all(gc.is_fallback(b) for b in buffers)}
    for i in views:
        view = doc.json["bufferViews"][i]
        ext_name = next(k for k in MESHOPT if k in view["extensions"])
        e = view["extensions"][ext_name]
        where = f"/bufferViews/{i}/extensions/{ext_name}"
        if not isinstance(e, dict):
            raise doc.fail(f"{where}: expected a JSON object")
        count, stride = e.get("count"), e.get("byteStride")
        buf, offset, length = e.get("buffer"), e.get("byteOffset", 0), e.get("byteLength")
        ints = [count, stride, buf, offset, length]
        if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in ints) or buf >= len(doc.buffers):
            raise doc.fail(f"{where}: count, byteStride, buffer, byteOffset and byteLength must be "
                           "non-negative integers naming a buffer")
        if e.get("mode") not in MODES or e.get("filter", "NONE") not in FILTERS:
            raise doc.fail(f"{where}: unknown mode {e.get('mode')!r} or filter {e.get('filter')!r}")
        limits.check(doc.path, "vertices", count, where, "elements")
        if count * stride != view["byteLength"]:
            raise doc.fail(f"{where}: count x byteStride = {count * stride}, but the view holds "
                           f"{view['byteLength']} bytes")
        data = bytes(doc.buffers[buf][offset:offset + length])
        if len(data) != length:
            raise doc.fail(f"{where}: bytes {offset}..{offset + length} lie outside buffer {buf}")
        filt = e.get("filter", "NONE")
        try:
            rows = meshopt.decode_gltf_buffer(data, count, stride, e["mode"], None if filt == "NONE" else filt)
        except (ValueError, RuntimeError) as err:
            raise doc.fail(f"{where}: cannot decode ({err})") from None
        raw = np.ascontiguousarray(rows).tobytes()
        doc.json["bufferViews"].append({"buffer": buf, "byteOffset": offset, "byteLength": length})
        doc.orphaned_views.add(len(doc.json["bufferViews"]) - 1)  # its compressed bytes: cut on writing
        params = {k: e[k] for k in ("byteStride", "count", "mode", "filter") if k in e}
        record["views"][id(view)] = {"view": view, "params": params, "data": data,
                                     "digest": hashlib.sha256(raw).digest()}
        new = gc.add_view(doc, raw, view.get("target"))
        fresh = doc.json["bufferViews"].pop(new)  # the decoded bytes take this view's place
        view.update(buffer=fresh["buffer"], byteOffset=fresh["byteOffset"], byteLength=len(raw))
        del view["extensions"][ext_name]
        if not view["extensions"]:
            del view["extensions"]
    _drop_unused_fallbacks(doc)
    for ext in MESHOPT:
        _forget_extension(doc, ext, used=any(ext in v.get("extensions", {}) for v in doc.json["bufferViews"]))
    return len(views)


def _drop_unused_fallbacks(doc: gc.Document) -> None:
    """Remove meshopt fallback buffers no view uses any more, renumbering the others."""
    used = {v["buffer"] for v in doc.json.get("bufferViews", [])}
    keep = [i for i, b in enumerate(doc.json["buffers"])
            if i in used or not any(k in b.get("extensions", {}) for k in MESHOPT)]
    if len(keep) == len(doc.json["buffers"]):
        return
    renumber = {old: new for new, old in enumerate(keep)}
    doc.json["buffers"] = [doc.json["buffers"][i] for i in keep]
    doc.buffers = [doc.buffers[i] for i in keep]
    for v in doc.json["bufferViews"]:
        v["buffer"] = renumber[v["buffer"]]


def decode_draco(doc: gc.Document, prim: dict, where: str) -> bool:
    """Decode one primitive's Draco data into plain accessors; False when it has none."""
    ext = prim.get("extensions", {}).get(DRACO)
    if ext is None:
        return False
    draco = _require(doc, "DracoPy", DRACO, "DracoPy")
    where = f"{where}/extensions/{DRACO}"
    if not isinstance(ext, dict) or not isinstance(ext.get("attributes"), dict):
        raise doc.fail(f"{where}: expected an object with bufferView and attributes")
    try:
        data = gc.view_bytes(doc, ext["bufferView"])
    except (KeyError, IndexError, TypeError):
        raise doc.fail(f"{where}/bufferView: expected the index of a buffer view") from None
    try:
        mesh = draco.decode(data)
    except Exception as err:  # DracoPy raises its own and plain ValueErrors on corrupt data
        raise doc.fail(f"{where}: Draco data cannot be decoded ({type(err).__name__})") from None
    by_id = {a["unique_id"]: a["data"] for a in mesh.attributes}
    record = doc.compressed.setdefault("draco", {"declared": _declared(doc, DRACO), "primitives": []})
    record["primitives"].append({"prim": prim, "ext": copy.deepcopy(ext), "where": where, "fallback": all(
        "bufferView" in doc.json["accessors"][a] for a in prim.get("attributes", {}).values())})
    for name, uid in ext["attributes"].items():
        if name not in prim.get("attributes", {}) or uid not in by_id:
            raise doc.fail(f"{where}/attributes/{name}: names no decoded attribute of the primitive")
        acc_index = prim["attributes"][name]
        _fill_accessor(doc, acc_index, np.asarray(by_id[uid]), gc.ARRAY_BUFFER, f"{where}/attributes/{name}")
    if "indices" in prim:
        faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3)))).reshape(-1, 1)
        _fill_accessor(doc, prim["indices"], faces, gc.ELEMENT_ARRAY_BUFFER, f"{where} (indices)")
    del prim["extensions"][DRACO]
    doc.orphaned_views.add(ext["bufferView"])  # pruned on writing once no primitive reads it
    if not prim["extensions"]:
        del prim["extensions"]
    still = any(DRACO in p.get("extensions", {}) for m in doc.json.get("meshes", [])
                for p in m.get("primitives", []))
    _forget_extension(doc, DRACO, used=still)
    return True


def _fill_accessor(doc: gc.Document, index: int, values: np.ndarray, target: int, where: str) -> None:
    """Give accessor ``index`` its decoded ``values`` (rows) in its own component type."""
    acc = doc.json["accessors"][index]
    dtype = np.dtype(gc.COMPONENT_TYPES[acc["componentType"]])
    values = values.reshape(len(values), -1)
    if values.shape != (acc["count"], gc.TYPE_SIZES[acc["type"]]):
        raise doc.fail(f"{where}: decoded {values.shape[0]} x {values.shape[1]} values, but accessor "
                       f"{index} declares {acc['count']} x {acc['type']}")
    if values.dtype.kind == "f" and dtype.kind in "iu":
        scale = float(np.iinfo(dtype).max) if acc.get("normalized") else 1.0
        values = np.round(values * scale)
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        raise doc.fail(f"{where}: decoded values hold NaN or infinity")
    values = values.astype(dtype)
    if isinstance(acc.get("bufferView"), int):  # an uncompressed fallback, replaced by the decoded values
        doc.orphaned_views.add(acc["bufferView"])
    acc["bufferView"] = gc.add_accessor_view(doc, values, target)
    acc.pop("byteOffset", None)
    if "min" in acc or "max" in acc:  # encoders may state the quantization grid's bounds instead
        acc["min"], acc["max"] = values.min(0).tolist(), values.max(0).tolist()


def _declared(doc: gc.Document, name: str) -> list[str]:
    """Which of ``extensionsUsed``/``extensionsRequired`` name extension ``name``."""
    return [k for k in ("extensionsUsed", "extensionsRequired") if name in doc.json.get(k, [])]


def _forget_extension(doc: gc.Document, name: str, *, used: bool) -> None:
    if used:
        return
    for key in ("extensionsUsed", "extensionsRequired"):
        if name in doc.json.get(key, []):
            doc.json[key].remove(name)
            if not doc.json[key]:
                del doc.json[key]


def decode_all(doc: gc.Document) -> gc.Document:
    """``doc`` with every meshopt view and Draco primitive decoded in place (to read a compressed
    output's geometry as plain accessors); the document."""
    decode_meshopt(doc)
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            decode_draco(doc, prim, f"/meshes/{mi}/primitives/{pi}")
    return doc
