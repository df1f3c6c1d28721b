"""Leaving nothing behind: accessors a conversion replaced (old TANGENT, attributes and
indices of a split primitive), the buffer views only they used, the compressed bytes of Draco
primitives it decoded, and those views' bytes.

:func:`prune` drops the given accessors once nothing references them, then the views no one
else uses, cuts their bytes out of the buffers they lay in (whole multiples of 16 bytes, so
every later offset keeps its alignment; a buffer an extension addresses by offset, or a data
URI, keeps its bytes) and renumbers every reference. Objects the input already left unused
are not touched: the output has no unused object the input did not have.
"""

from __future__ import annotations

ALIGN = 16  # bytes cut out at a time: later views and accessors keep their alignment


def accessor_refs(doc_json: dict):
    """Every place an accessor index is stored: ``(container, key)`` pairs, where
    ``container[key]`` is the index (primitives' attributes, indices and morph targets,
    skins, animation samplers, EXT_mesh_gpu_instancing attributes)."""
    for mesh in doc_json.get("meshes", []):
        for prim in mesh.get("primitives", []):
            for attrs in [prim.get("attributes", {}), *prim.get("targets", [])]:
                yield from ((attrs, k) for k in attrs)
            if "indices" in prim:
                yield prim, "indices"
    for skin in doc_json.get("skins", []):
        if "inverseBindMatrices" in skin:
            yield skin, "inverseBindMatrices"
    for anim in doc_json.get("animations", []):
        for sampler in anim.get("samplers", []):
            yield from ((sampler, k) for k in ("input", "output") if k in sampler)
    for node in doc_json.get("nodes", []):
        attrs = node.get("extensions", {}).get("EXT_mesh_gpu_instancing", {}).get("attributes", {})
        yield from ((attrs, k) for k in attrs)


def _walk(value, skip=()):
    """Every dict inside ``value`` (depth first), leaving out the objects in ``skip`` (by id)."""
    if isinstance(value, dict):
        if id(value) in skip:
            return
        yield value
        for v in value.values():
            yield from _walk(v, skip)
    elif isinstance(value, list):
        for v in value:
            yield from _walk(v, skip)


def prune(doc, accessors, views=()) -> None:
    """Drop the accessors ``accessors`` (indices) that nothing references, the buffer views
    only they used, the ``views`` (indices: a decoded Draco primitive's compressed bytes) that
    nothing references, and those views' bytes (see the module doc); renumber what is left."""
    j = doc.json
    used = {c[k] for c, k in accessor_refs(j)}
    gone = sorted(set(accessors) - used)
    if not gone and not views:
        return
    removed = [j["accessors"][i] for i in gone]
    candidate_views = set(views)
    for acc in removed:
        candidate_views.update(d["bufferView"] for d in _walk(acc) if isinstance(d.get("bufferView"), int))
    kept_views = {d["bufferView"] for d in _walk(j, {id(a) for a in removed})
                  if isinstance(d.get("bufferView"), int) and d is not j}
    dead_views = sorted(candidate_views - kept_views)
    new_acc = _renumber(len(j["accessors"]), gone)
    j["accessors"] = [a for i, a in enumerate(j["accessors"]) if i not in set(gone)]
    for c, k in accessor_refs(j):
        c[k] = new_acc[c[k]]
    if not dead_views:
        return
    _cut_bytes(doc, dead_views)
    emptied = {j["bufferViews"][i]["buffer"] for i in dead_views}
    new_view = _renumber(len(j["bufferViews"]), dead_views)
    j["bufferViews"] = [v for i, v in enumerate(j["bufferViews"]) if i not in set(dead_views)]
    for d in _walk({k: v for k, v in j.items() if k != "bufferViews"}):
        if isinstance(d.get("bufferView"), int):
            d["bufferView"] = new_view[d["bufferView"]]
    _drop_buffers(doc, emptied)


def _drop_buffers(doc, candidates) -> None:
    """Drop the buffers of ``candidates`` no view or extension refers to any more (a file that
    held only replaced tangents), renumbering the references to the others. A GLB's own
    buffer 0 stays: its binary chunk is where new data goes."""
    j = doc.json
    used = {d["buffer"] for d in _walk(j) if isinstance(d.get("buffer"), int)}
    gone = sorted(b for b in candidates if b not in used and not (doc.binary and b == 0 and "uri" not in j["buffers"][0]))
    if not gone:
        return
    new = _renumber(len(j["buffers"]), gone)
    j["buffers"] = [b for i, b in enumerate(j["buffers"]) if i not in set(gone)]
    doc.buffers[:] = [b for i, b in enumerate(doc.buffers) if i not in set(gone)]
    for d in _walk(j):
        if isinstance(d.get("buffer"), int):
            d["buffer"] = new[d["buffer"]]


def _renumber(count: int, gone) -> dict[int, int]:
    out, gone, n = {}, set(gone), 0
    for i in range(count):
        if i not in gone:
            out[i] = n
            n += 1
    return out


def _cut_bytes(doc, dead_views) -> None:
    """Cut the bytes of ``dead_views`` that no other view covers out of their buffers."""
    j = doc.json
    views = j["bufferViews"]
    addressed = {d["buffer"] for d in _walk({k: v for k, v in j.items() if k != "bufferViews"})
                 if isinstance(d.get("buffer"), int)}  # EXT_meshopt_compression and the like
    addressed |= {d["buffer"] for v in views for d in _walk(v.get("extensions", {})) if isinstance(d.get("buffer"), int)}
    dead = set(dead_views)
    for b, buf in enumerate(j.get("buffers", [])):
        if b in addressed or str(buf.get("uri", "")).startswith("data:") or b >= len(doc.buffers):
            continue
        live = [(v.get("byteOffset", 0), v.get("byteOffset", 0) + v["byteLength"])
                for i, v in enumerate(views) if v.get("buffer") == b and i not in dead]
        cuts = []
        for i in sorted((i for i in dead if views[i].get("buffer") == b), key=lambda i: views[i].get("byteOffset", 0)):
            start = views[i].get("byteOffset", 0)
            end = start + views[i]["byteLength"]
            for lo, hi in live:  # bytes another view uses stay
                if lo < end and hi > start:
                    end = min(end, lo) if lo > start else start
            end = start + (end - start) // ALIGN * ALIGN
            if end > start:
                cuts.append((start, end))
        data = doc.buffers[b]
        if cuts and sum(e - s for s, e in cuts) >= len(data):  # a buffer is never empty: keep its last bytes
            cuts.pop()
        if not cuts:
            continue
        for start, end in reversed(cuts):
            del data[start:end]
        for i, v in enumerate(views):
            if v.get("buffer") == b and i not in dead:
                off = v.get("byteOffset", 0)
                shift = sum(e - s for s, e in cuts if e <= off)
                if shift:
                    v["byteOffset"] = off - shift
        buf["byteLength"] = len(data)
