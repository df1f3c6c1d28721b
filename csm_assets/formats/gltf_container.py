"""glTF 2.0 documents as JSON plus buffers: .gltf and .glb containers, accessors.

The document stays a plain dict so that everything we do not touch (extensions,
extras, animations, skins, cameras) is written back exactly as it was read.
"""

from __future__ import annotations

import base64
import json
import math
import os
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import limits
from ..errors import FormatError, not_regular
from ..references import browser_form, is_data_uri
from .gltf_schema import check_document

COMPONENT_TYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
                   5125: np.uint32, 5126: np.float32}
COMPONENT_CODES = {np.dtype(v): k for k, v in COMPONENT_TYPES.items()}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
SIZE_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
GLB_MAGIC, JSON_CHUNK, BIN_CHUNK = b"glTF", 0x4E4F534A, 0x004E4942


@dataclass
class Document:
    """A glTF document: ``json`` (the dict), the bytes of each buffer, where it came from."""

    path: Path
    json: dict
    buffers: list[bytearray] = field(default_factory=list)
    binary: bool = False
    files: list[Path] = field(default_factory=list)  # buffer files read
    image_files: dict[int, Path] = field(default_factory=dict)  # image index -> file it names
    # material index -> how its heights lie on the surface: {"texCoord", "transform", "wraps"}
    placements: dict[int, dict] = field(default_factory=dict)
    orphaned_views: set[int] = field(default_factory=set)  # views only decoded Draco data used
    compressed: dict = field(default_factory=dict)  # what gltf_decode decoded, for gltf_compress to encode again

    def fail(self, message: str) -> FormatError:
        return FormatError(self.path, message)

    def items(self, key: str) -> list:
        return self.json.setdefault(key, [])


def _parse_glb(path: Path, data: bytes) -> tuple[dict, bytes | None]:
    if len(data) < 20:
        raise FormatError(path, "truncated GLB: shorter than its header")
    magic, version, length = struct.unpack_from("<4sII", data)
    if version != 2:
        raise FormatError(path, f"GLB version {version}; expected 2")
    if length > len(data):
        raise FormatError(path, f"truncated GLB: header says {length} bytes, file has {len(data)}")
    chunks, at = [], 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise FormatError(path, f"GLB chunk at byte {at} runs past the end of the file")
        chunks.append((kind, data[at + 8: at + 8 + size]))
        at += 8 + size
    if not chunks or chunks[0][0] != JSON_CHUNK:
        raise FormatError(path, "GLB does not start with a JSON chunk")
    bin_chunk = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == BIN_CHUNK else None
    return _parse_json(path, chunks[0][1]), bin_chunk


class _NonFinite(str):
    """Stands in for NaN, Infinity or an overflowing number while parsing."""


def _number(text: str):
    value = float(text)
    return value if math.isfinite(value) else _NonFinite(text)


def _find_non_finite(value, pointer: str = "") -> str | None:
    if isinstance(value, _NonFinite):
        return f"{pointer or '/'} is {str(value)}"
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for k, v in items:
        found = _find_non_finite(v, f"{pointer}/{k}")
        if found:
            return found
    return None


def _parse_json(path: Path, raw: bytes) -> dict:
    limits.check(path, "json_objects", raw.count(b"{"), "its JSON", "objects")  # before parsing
    seen = []

    def non_finite(text):
        seen.append(text)
        return _NonFinite(text)

    def number(text):
        value = _number(text)
        if isinstance(value, _NonFinite):
            seen.append(text)
        return value

    try:
        doc = json.loads(raw.decode("utf-8"), parse_constant=non_finite, parse_float=number)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise FormatError(path, f"not valid glTF JSON ({str(e).splitlines()[0][:200]})") from None
    if seen:
        raise FormatError(path, f"{_find_non_finite(doc) or seen[0]}: glTF numbers must be finite")
    asset = doc.get("asset") if isinstance(doc, dict) else None
    if not isinstance(asset, dict) or not str(asset.get("version", "")).startswith("2"):
        raise FormatError(path, "not a glTF 2.0 document (asset.version must be 2.x)")
    return doc


def resolve_uri(path: Path, uri: str) -> Path:
    """The file a relative glTF ``uri`` names, beside the document."""
    return path.parent / urllib.parse.unquote(uri)


def data_uri_bytes(path: Path, uri: str) -> bytes:
    """The bytes of a base64 ``data:`` URI; FormatError naming ``path`` otherwise."""
    head, _, payload = browser_form(uri).partition(",")
    if ";base64" not in head.lower():
        raise FormatError(path, "data URIs must be base64-encoded")
    try:
        return base64.b64decode(payload, validate=True)
    except ValueError:
        raise FormatError(path, "a data URI is not valid base64") from None


def load(path, resolve=None) -> Document:
    """Read a .gltf or .glb file and every buffer it names; FormatError when malformed.

    resolve: ``resolve(uri) -> Path`` for buffer files (default: beside the document);
    it may raise FormatError to refuse a uri.
    """
    path = Path(path)
    resolve = resolve or (lambda uri: resolve_uri(path, uri))
    try:
        data = path.read_bytes()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    binary = data[:4] == GLB_MAGIC
    doc_json, bin_chunk = _parse_glb(path, data) if binary else (_parse_json(path, data), None)
    check_document(path, doc_json)
    doc = Document(path, doc_json, [], binary)
    for i, buf in enumerate(doc_json.get("buffers", [])):
        uri = buf.get("uri")
        if uri is None and is_fallback(buf):
            raw = b""  # meshopt's fallback: its views are decoded from compressed data, never read
        elif uri is None:
            if not (binary and i == 0 and bin_chunk is not None):
                raise doc.fail(f"buffer {i} has no uri and no GLB binary chunk")
            raw = bin_chunk
        elif is_data_uri(uri):
            raw = data_uri_bytes(path, uri)
        else:
            file = resolve(uri)
            try:
                if kind := _not_regular(file):  # a FIFO blocks the read for ever, a device never ends
                    raise doc.fail(f"buffer {i} ({uri}) is {kind}, not a file (expected a regular file)")
                raw = file.read_bytes()
                doc.files.append(file)
            except OSError as e:
                raise doc.fail(f"buffer {i} ({uri}) cannot be read: {e.strerror or e}") from None
        length = buf["byteLength"]
        if length > len(raw) and not is_fallback(buf):
            raise doc.fail(f"buffer {i} declares {length} bytes but holds {len(raw)}")
        doc.buffers.append(bytearray(raw))
    for i, view in enumerate(doc_json.get("bufferViews", [])):
        end = view.get("byteOffset", 0) + view["byteLength"]
        if end > doc_json["buffers"][view["buffer"]]["byteLength"]:
            raise doc.fail(f"/bufferViews/{i}: ends at byte {end}, past the end of buffer {view['buffer']} "
                           f"({doc_json['buffers'][view['buffer']]['byteLength']} bytes)")
    return doc


def _not_regular(file: Path) -> str | None:
    """What ``file`` is when it is there but no regular file ("a FIFO", ...), else None."""
    try:
        return not_regular(os.stat(file).st_mode)
    except OSError:
        return None  # missing or unreadable: the read says so


def is_fallback(buffer: dict) -> bool:
    """Whether a buffer is meshopt's fallback (declared, never read: its views are compressed)."""
    ext = buffer.get("extensions")
    return isinstance(ext, dict) and any(isinstance(ext.get(k), dict) and ext[k].get("fallback")
                                         for k in ("EXT_meshopt_compression", "KHR_meshopt_compression"))


def view_bytes(doc: Document, view_index: int) -> bytes:
    """The bytes of buffer view ``view_index`` (KeyError/IndexError/TypeError if malformed)."""
    view = doc.json["bufferViews"][view_index]
    start = view.get("byteOffset", 0)
    return bytes(doc.buffers[view["buffer"]][start:start + view["byteLength"]])


def read_accessor(doc: Document, index: int, *, raw: bool = False) -> np.ndarray:
    """Accessor ``index`` as a ``(count, components)`` array (sparse applied; normalized
    integers become float64 per the specification unless ``raw``)."""
    try:
        acc = doc.json["accessors"][index]
        dtype = np.dtype(COMPONENT_TYPES[acc["componentType"]])
        ncomp = TYPE_SIZES[acc["type"]]
        count = int(acc["count"])
    except (KeyError, IndexError, TypeError, ValueError):
        raise doc.fail(f"accessor {index} is missing or malformed") from None
    if count < 0:
        raise doc.fail(f"accessor {index} has a negative count")
    if "bufferView" in acc:
        out = _view_array(doc, acc["bufferView"], acc.get("byteOffset", 0), dtype, ncomp, count,
                          f"accessor {index}")
    else:
        if count * ncomp > 1 << 28:
            raise doc.fail(f"accessor {index} declares an enormous count {count}")
        out = np.zeros((count, ncomp), dtype)
    sparse = acc.get("sparse")
    if sparse:
        n = int(sparse["count"])
        idx_t = np.dtype(COMPONENT_TYPES[sparse["indices"]["componentType"]])
        idx = _view_array(doc, sparse["indices"]["bufferView"], sparse["indices"].get("byteOffset", 0),
                          idx_t, 1, n, f"accessor {index} sparse indices")[:, 0]
        vals = _view_array(doc, sparse["values"]["bufferView"], sparse["values"].get("byteOffset", 0),
                           dtype, ncomp, n, f"accessor {index} sparse values")
        if n and idx.max() >= count:
            raise doc.fail(f"accessor {index} sparse index out of range")
        out[idx.astype(np.int64)] = vals
    if acc.get("normalized") and dtype.kind in "iu" and not raw:
        top = float(np.iinfo(dtype).max)
        return np.maximum(out.astype(np.float64) / top, -1.0)
    return out


def _view_array(doc, view_index, offset, dtype, ncomp, count, what) -> np.ndarray:
    try:
        view = doc.json["bufferViews"][view_index]
        buf = doc.buffers[view["buffer"]]
        start = int(view.get("byteOffset", 0)) + int(offset)
        length = int(view["byteLength"])
    except (KeyError, IndexError, TypeError, ValueError):
        raise doc.fail(f"{what}: buffer view {view_index} is missing or malformed") from None
    elem = dtype.itemsize * ncomp
    stride = int(view.get("byteStride") or elem)
    if count == 0:
        return np.zeros((0, ncomp), dtype)
    end = start + stride * (count - 1) + elem
    view_end = int(view.get("byteOffset", 0)) + length
    if start < 0 or stride < elem or end > view_end or view_end > len(buf):
        raise doc.fail(f"{what}: needs bytes {start}..{end} but its buffer view ends at "
                       f"{min(view_end, len(buf))}")
    arr = np.ndarray((count, ncomp), dtype, buffer=bytes(buf[start:end]), offset=0,
                     strides=(stride, dtype.itemsize))
    return arr.copy()


def add_accessor(doc: Document, data: np.ndarray, *, target: int | None = ARRAY_BUFFER,
                 minmax: bool = False, normalized: bool = False) -> int:
    """Append ``data`` ``(count, components)`` (or ``(count,)``) as a new accessor; its index."""
    data = np.ascontiguousarray(data)
    if data.ndim == 1:
        data = data[:, None]
    view = add_accessor_view(doc, data, target)
    acc = {"bufferView": view, "componentType": COMPONENT_CODES[data.dtype], "count": int(data.shape[0]),
           "type": SIZE_TYPES[data.shape[1]]}
    if normalized:
        acc["normalized"] = True
    if minmax and len(data):
        acc["min"] = data.min(0).tolist()
        acc["max"] = data.max(0).tolist()
    doc.items("accessors").append(acc)
    return len(doc.json["accessors"]) - 1


def add_accessor_view(doc: Document, data: np.ndarray, target: int | None = ARRAY_BUFFER) -> int:
    """A new buffer view holding the rows of ``data`` ``(count, components)``: vertex
    attributes (``target`` ARRAY_BUFFER) whose rows are not a multiple of 4 bytes (int8 or
    int16 VEC3, as KHR_mesh_quantization allows) are padded to a 4-byte ``byteStride``,
    as the specification requires of every vertex attribute."""
    data = np.ascontiguousarray(data)
    data = data.reshape(len(data), -1)
    elem = data.dtype.itemsize * data.shape[1]
    if target == ARRAY_BUFFER and elem % 4:
        stride = elem + (-elem % 4)
        rows = np.zeros((len(data), stride), np.uint8)
        rows[:, :elem] = data.view(np.uint8).reshape(len(data), elem)
        view = add_view(doc, rows.tobytes(), target)
        doc.json["bufferViews"][view]["byteStride"] = stride
        return view
    return add_view(doc, data.tobytes(), target)


def add_view(doc: Document, raw: bytes, target: int | None = None) -> int:
    """Append bytes to the document's own new-data buffer (4-byte aligned); the view index."""
    buf_index = _data_buffer(doc)
    buf = doc.buffers[buf_index]
    buf.extend(b"\0" * (-len(buf) % 4))
    view = {"buffer": buf_index, "byteOffset": len(buf), "byteLength": len(raw)}
    if target is not None:
        view["target"] = target
    buf.extend(raw)
    doc.json["buffers"][buf_index]["byteLength"] = len(buf)
    doc.items("bufferViews").append(view)
    return len(doc.json["bufferViews"]) - 1


def _data_buffer(doc: Document) -> int:
    """The buffer new data goes to: the GLB binary chunk, else a new external buffer."""
    buffers = doc.items("buffers")
    if doc.binary:
        if buffers and "uri" not in buffers[0]:
            return 0
        if not buffers:
            buffers.append({"byteLength": 0})
            doc.buffers.append(bytearray())
            return 0
    for i, b in enumerate(buffers):
        if b.get("uri") == NEW_BUFFER_URI.format(stem=doc.path.stem):
            return i
    buffers.append({"uri": NEW_BUFFER_URI.format(stem=doc.path.stem), "byteLength": 0})
    doc.buffers.append(bytearray())
    return len(buffers) - 1


NEW_BUFFER_URI = "{stem}_csm.bin"


def glb_bytes(doc: Document) -> bytes:
    """The document as a GLB file (JSON chunk padded with spaces, BIN with zeros)."""
    text = json.dumps(doc.json, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), JSON_CHUNK) + text
    if doc.json.get("buffers") and "uri" not in doc.json["buffers"][0]:
        blob = bytes(doc.buffers[0]) + b"\0" * (-len(doc.buffers[0]) % 4)
        body += struct.pack("<II", len(blob), BIN_CHUNK) + blob
    return struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(body)) + body


def gltf_bytes(doc: Document) -> bytes:
    return (json.dumps(doc.json, indent=2) + "\n").encode("utf-8")
