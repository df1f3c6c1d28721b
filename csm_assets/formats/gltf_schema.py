"""Checks a glTF document's JSON types and references before anything is read or allocated.

Only what the tool reads or rewrites is checked (buffers, views, accessors, images,
samplers, textures, materials, meshes), against the glTF 2.0 schema's types, ranges and
cross references, plus the resource limits of :mod:`csm_assets.limits`. A violation is a
:class:`~csm_assets.errors.FormatError` naming the file and the JSON pointer of the
offending value (``/accessors/3/count``). Nodes, animations, skins and unknown extensions
are passed through untouched and so are not checked here.
"""

from __future__ import annotations

import math

from .. import limits
from ..errors import FormatError
from .csm_params import GLTF_TEXTURES

COMPONENT_SIZES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
INDEX_TYPES = {5121, 5123, 5125}
WRAPS = {33071, 33648, 10497}
# attribute -> (types, component types allowed with KHR_mesh_quantization or not)
ATTRIBUTES = {
    "POSITION": ({"VEC3"}, {5126, 5120, 5121, 5122, 5123}),
    "NORMAL": ({"VEC3"}, {5126, 5120, 5122}),
    "TANGENT": ({"VEC4"}, {5126, 5120, 5122}),
    "TEXCOORD": ({"VEC2"}, {5126, 5120, 5121, 5122, 5123}),
}
TEXTURE_INFOS = [("pbrMetallicRoughness", "baseColorTexture"), ("pbrMetallicRoughness", "metallicRoughnessTexture"),
                 (None, "normalTexture"), (None, "occlusionTexture"), (None, "emissiveTexture")]


class Checker:
    """Type checks that raise FormatError naming ``path`` and a JSON pointer."""

    def __init__(self, path):
        self.path = path

    def fail(self, pointer: str, expected: str, value=None) -> FormatError:
        got = f", not {type(value).__name__} {_short(value)}" if value is not None else ""
        return FormatError(self.path, f"{pointer or '/'}: expected {expected}{got}")

    def obj(self, value, pointer: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(pointer, "a JSON object", value)
        return value

    def array(self, doc: dict, key: str, pointer: str = "") -> list:
        value = doc.get(key, [])
        if not isinstance(value, list):
            raise self.fail(f"{pointer}/{key}", "an array", value)
        return value

    def integer(self, d: dict, key: str, pointer: str, *, lo: int = 0, hi: int | None = None,
                required: bool = False, choices=None) -> int | None:
        value = d.get(key)
        if value is None:
            if required:
                raise self.fail(f"{pointer}/{key}", "an integer (it is required)")
            return None
        ok = isinstance(value, int) and not isinstance(value, bool)
        if ok and choices is not None:
            ok = value in choices
            expected = f"one of {sorted(choices)}"
        else:
            ok = ok and value >= lo and (hi is None or value < hi)
            expected = f"an integer >= {lo}" + (f" and < {hi}" if hi is not None else "")
        if not ok:
            raise self.fail(f"{pointer}/{key}", expected, value)
        return value

    def ref(self, d: dict, key: str, pointer: str, count: int, what: str, *, required=False) -> int | None:
        """An index into an array of ``count`` items (``what``, for the message)."""
        value = d.get(key)
        if value is None and not required:
            return None
        if not (isinstance(value, int) and not isinstance(value, bool) and 0 <= value < count):
            raise self.fail(f"{pointer}/{key}", f"the index of one of the {count} {what}", value)
        return value

    def string(self, d: dict, key: str, pointer: str) -> None:
        if key in d and not isinstance(d[key], str):
            raise self.fail(f"{pointer}/{key}", "a string", d[key])

    def boolean(self, d: dict, key: str, pointer: str) -> None:
        if key in d and not isinstance(d[key], bool):
            raise self.fail(f"{pointer}/{key}", "true or false", d[key])

    def number(self, d: dict, key: str, pointer: str) -> None:
        value = d.get(key)
        if value is not None and not (_is_finite(value)):
            raise self.fail(f"{pointer}/{key}", "a finite number", value)

    def numbers(self, d: dict, key: str, pointer: str, length: int | None = None) -> None:
        value = d.get(key)
        if value is None:
            return
        if (not isinstance(value, list) or (length is not None and len(value) != length)
                or not all(_is_finite(v) for v in value)):
            raise self.fail(f"{pointer}/{key}", f"an array of {length or 'some'} finite numbers", value)


def check_document(path, doc: dict) -> None:
    """FormatError (naming ``path`` and a JSON pointer) for the first type, range or
    reference error in the parts of ``doc`` the tool reads, or a count over a limit."""
    c = Checker(path)
    arrays = {k: c.array(doc, k) for k in ("buffers", "bufferViews", "accessors", "images", "samplers",
                                          "textures", "materials", "meshes")}
    for key in ("materials", "textures", "images"):
        limits.check(path, "materials", len(arrays[key]), f"/{key}", key)
    n = {k: len(v) for k, v in arrays.items()}
    for i, b in enumerate(arrays["buffers"]):
        p = f"/buffers/{i}"
        c.obj(b, p)
        c.string(b, "uri", p)
        c.string(b, "name", p)
        c.integer(b, "byteLength", p, lo=0, required=True)
    for i, v in enumerate(arrays["bufferViews"]):
        p = f"/bufferViews/{i}"
        c.obj(v, p)
        c.ref(v, "buffer", p, n["buffers"], "buffers", required=True)
        c.integer(v, "byteOffset", p)
        c.integer(v, "byteLength", p, lo=1, required=True)
        stride = c.integer(v, "byteStride", p, lo=4, hi=253)
        if stride is not None and stride % 4:
            raise c.fail(f"{p}/byteStride", "a multiple of 4 from 4 to 252", stride)
    for i, a in enumerate(arrays["accessors"]):
        _accessor(c, a, f"/accessors/{i}", n["bufferViews"])
    for i, im in enumerate(arrays["images"]):
        p = f"/images/{i}"
        c.obj(im, p)
        for key in ("uri", "mimeType", "name"):
            c.string(im, key, p)
        c.ref(im, "bufferView", p, n["bufferViews"], "buffer views")
    for i, s in enumerate(arrays["samplers"]):
        p = f"/samplers/{i}"
        c.obj(s, p)
        c.integer(s, "wrapS", p, choices=WRAPS)
        c.integer(s, "wrapT", p, choices=WRAPS)
    for i, t in enumerate(arrays["textures"]):
        p = f"/textures/{i}"
        c.obj(t, p)
        c.ref(t, "source", p, n["images"], "images")
        c.ref(t, "sampler", p, n["samplers"], "samplers")
    for i, m in enumerate(arrays["materials"]):
        _material(c, m, f"/materials/{i}", n["textures"])
    for i, mesh in enumerate(arrays["meshes"]):
        _mesh(c, mesh, f"/meshes/{i}", doc, n)


def _accessor(c: Checker, a, p: str, n_views: int) -> None:
    c.obj(a, p)
    view = c.ref(a, "bufferView", p, n_views, "buffer views")
    ctype = c.integer(a, "componentType", p, required=True, choices=COMPONENT_SIZES)
    count = c.integer(a, "count", p, lo=1, required=True)
    if a.get("type") not in TYPE_SIZES:
        raise c.fail(f"{p}/type", f"one of {', '.join(TYPE_SIZES)}", a.get("type"))
    limits.check(c.path, "vertices", count, p, "elements")
    offset = c.integer(a, "byteOffset", p)
    if offset is not None and offset % COMPONENT_SIZES[ctype]:
        raise c.fail(f"{p}/byteOffset", f"a multiple of the component size {COMPONENT_SIZES[ctype]}", offset)
    if offset and view is None:
        raise c.fail(f"{p}/byteOffset", "no byteOffset without a bufferView", offset)
    c.boolean(a, "normalized", p)
    c.numbers(a, "min", p, TYPE_SIZES[a["type"]])
    c.numbers(a, "max", p, TYPE_SIZES[a["type"]])
    c.string(a, "name", p)
    if "sparse" in a:
        s = c.obj(a["sparse"], f"{p}/sparse")
        c.integer(s, "count", f"{p}/sparse", lo=1, hi=count + 1, required=True)
        for key in ("indices", "values"):
            sub = c.obj(s.get(key), f"{p}/sparse/{key}")
            c.ref(sub, "bufferView", f"{p}/sparse/{key}", n_views, "buffer views", required=True)
            c.integer(sub, "byteOffset", f"{p}/sparse/{key}")
        c.integer(s["indices"], "componentType", f"{p}/sparse/indices", required=True, choices=INDEX_TYPES)


def check_texture_info(path, info, pointer: str, n_textures: int) -> None:
    """FormatError (naming ``path`` and the JSON pointer) for a textureInfo ``info`` at ``pointer`` that
    breaks glTF's schema: its index (one of ``n_textures``), texCoord, scale, strength, KHR_texture_transform."""
    _texture_info(Checker(path), info, pointer, n_textures)


def _texture_info(c: Checker, info, p: str, n_textures: int) -> None:
    c.obj(info, p)
    c.ref(info, "index", p, n_textures, "textures", required=True)
    c.integer(info, "texCoord", p)
    for key in ("scale", "strength"):
        c.number(info, key, p)
    ext = c.obj(info.get("extensions", {}), f"{p}/extensions")
    if "KHR_texture_transform" in ext:
        t = c.obj(ext["KHR_texture_transform"], f"{p}/extensions/KHR_texture_transform")
        tp = f"{p}/extensions/KHR_texture_transform"
        c.numbers(t, "offset", tp, 2)
        c.numbers(t, "scale", tp, 2)
        c.number(t, "rotation", tp)
        c.integer(t, "texCoord", tp)


def _material(c: Checker, m, p: str, n_textures: int) -> None:
    c.obj(m, p)
    c.string(m, "name", p)
    for parent, key in TEXTURE_INFOS:
        holder = c.obj(m.get(parent, {}), f"{p}/{parent}") if parent else m
        pp = f"{p}/{parent}" if parent else p
        if key in holder:
            _texture_info(c, holder[key], f"{pp}/{key}", n_textures)
    pbr = m.get("pbrMetallicRoughness", {})
    c.numbers(pbr, "baseColorFactor", f"{p}/pbrMetallicRoughness", 4)
    for key in ("metallicFactor", "roughnessFactor"):
        c.number(pbr, key, f"{p}/pbrMetallicRoughness")
    c.numbers(m, "emissiveFactor", p, 3)
    c.number(m, "alphaCutoff", p)
    ext = c.obj(m.get("extensions", {}), f"{p}/extensions")
    if "KHR_materials_displacement" in ext:
        ep = f"{p}/extensions/KHR_materials_displacement"
        d = c.obj(ext["KHR_materials_displacement"], ep)
        if "displacementGeometryTexture" in d:
            _texture_info(c, d["displacementGeometryTexture"], f"{ep}/displacementGeometryTexture", n_textures)
        c.number(d, "displacementGeometryFactor", ep)
        c.number(d, "displacementGeometryOffset", ep)
    csm = ext.get("EXT_materials_cone_step_mapping")
    if isinstance(csm, dict) and isinstance(csm.get("stepMapTexture"), dict):  # converted: placed by it
        for key in GLTF_TEXTURES:  # a quadrant map's second image, the levels images
            if key in csm:
                _texture_info(c, csm[key], f"{p}/extensions/EXT_materials_cone_step_mapping/{key}", n_textures)
    if "KHR_materials_parallax_mapping" in ext:
        ep = f"{p}/extensions/KHR_materials_parallax_mapping"
        d = c.obj(ext["KHR_materials_parallax_mapping"], ep)
        if isinstance(d.get("heightTexture"), dict):
            _texture_info(c, d["heightTexture"], f"{ep}/heightTexture", n_textures)
        elif "heightTexture" in d:
            c.ref(d, "heightTexture", ep, n_textures, "textures")
        c.number(d, "heightFactor", ep)
    extras = m.get("extras")
    if isinstance(extras, dict) and "csm_height" in extras:
        ep = f"{p}/extras/csm_height"
        _texture_info(c, extras["csm_height"], ep, n_textures)
        h = extras["csm_height"]
        c.boolean(h, "invert", ep)
        if "channel" in h and not (isinstance(h["channel"], (int, str)) and not isinstance(h["channel"], bool)):
            raise c.fail(f"{ep}/channel", "a channel index or name", h["channel"])


def _mesh(c: Checker, mesh, p: str, doc: dict, n: dict) -> None:
    c.obj(mesh, p)
    c.string(mesh, "name", p)
    prims = c.array(mesh, "primitives", p)
    accessors = doc.get("accessors", [])
    for j, prim in enumerate(prims):
        pp = f"{p}/primitives/{j}"
        c.obj(prim, pp)
        c.ref(prim, "material", pp, n["materials"], "materials")
        c.integer(prim, "mode", pp, hi=7)
        attrs = c.obj(prim.get("attributes", {}), f"{pp}/attributes")
        counts = set()
        for name, acc in attrs.items():
            index = c.ref(attrs, name, f"{pp}/attributes", n["accessors"], "accessors", required=True)
            a = accessors[index]
            counts.add(a["count"])
            base = name.split("_")[0] if name.startswith("TEXCOORD_") else name
            if base in ATTRIBUTES:
                types, ctypes = ATTRIBUTES[base]
                if a["type"] not in types or a["componentType"] not in ctypes:
                    raise c.fail(f"{pp}/attributes/{name}", f"an accessor of type {'/'.join(types)} with a "
                                 f"component type of {sorted(ctypes)} (accessor {index} is {a['type']} of "
                                 f"{a['componentType']})")
        if len(counts) > 1:
            raise c.fail(f"{pp}/attributes", f"attributes of one count (their accessors have counts "
                                             f"{sorted(counts)})")
        index = c.ref(prim, "indices", pp, n["accessors"], "accessors")
        if index is not None:
            a = accessors[index]
            if a["type"] != "SCALAR" or a["componentType"] not in INDEX_TYPES:
                raise c.fail(f"{pp}/indices", f"a SCALAR accessor of unsigned integers (accessor {index} is "
                                              f"{a['type']} of component type {a['componentType']})")
        for k, target in enumerate(c.array(prim, "targets", pp)):
            tp = f"{pp}/targets/{k}"
            c.obj(target, tp)
            for name in target:
                c.ref(target, name, tp, n["accessors"], "accessors", required=True)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_finite(v) -> bool:
    """A number float can hold, finite (an integer of 400 digits is not: it overflows float)."""
    try:
        return _is_number(v) and math.isfinite(v)
    except OverflowError:
        return False


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
