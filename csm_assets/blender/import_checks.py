"""What the importer's hook checks before it builds a material's relief nodes: every value Blender's
importer or the nodes would take from the file (bpy itself is not imported here). Each check
returns a problem (one line) or None; a problem is a per-material warning and that material gets
no relief (or, for the Blender extras, its default), never a failed import.

- the step map's textureInfo as glTF's schema has it (index, texCoord, KHR_texture_transform, whose
  numbers must fit 32-bit floats), its texture's image and sampler indices (``source``,
  ``EXT_texture_webp``'s, ``sampler``);
- the step map image: a regular file (not a FIFO or a device, on which Blender would block), its
  size read from its header before Blender loads it: at most
  ``CSM_ASSETS_MAX_TEXELS`` texels (:mod:`csm_assets.limits`, 2**28 by default, 16384 x 16384);
- depthScale and the node's factor within Blender's 32-bit float range (:data:`FLOAT32_MAX`);
- ``extras.blender`` (node, space, midlevel, strength) as the exporter writes them.
"""

from __future__ import annotations

import base64
import math
import tempfile
import urllib.parse
from pathlib import Path

from .. import limits
from ..checks import FLOAT32_MAX
from ..errors import FormatError
from ..formats.gltf_schema import check_texture_info

SUFFIXES = {"image/png": ".png", "image/jpeg": ".jpg", "image/webp": ".webp"}
EXTRAS = {"node": ("DISPLACEMENT", "BUMP"), "space": ("OBJECT", "WORLD")}


def step_map_problem(gltf, info: dict, pointer: str) -> str | None:
    """What is wrong with the step map's textureInfo ``info`` in importer ``gltf``'s file, or None."""
    textures, images = gltf.data.textures or [], gltf.data.images or []
    try:
        check_texture_info(gltf.filename, info, pointer, len(textures))
    except FormatError as e:
        return str(e).removeprefix(f"{e.path}: ")
    moved = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
    for name in ("offset", "rotation", "scale"):  # types checked above; Blender's Mapping node holds 32-bit floats
        v = moved.get(name)
        if any(abs(x) > FLOAT32_MAX for x in (v if isinstance(v, list) else [] if v is None else [v])):
            return f"its KHR_texture_transform {name} {v!r} is beyond Blender's 32-bit float range"
    texture = textures[info["index"]]
    webp = (texture.extensions or {}).get("EXT_texture_webp")
    sources = [("source", texture.source), ("EXT_texture_webp source", webp.get("source") if isinstance(webp, dict)
                                            else None)]
    for what, index in sources:
        if index is not None and not _index(index, len(images)):
            return f"its texture {info['index']}'s {what} {index!r} names no image (the file has {len(images)})"
    if texture.sampler is not None and not _index(texture.sampler, len(gltf.data.samplers or [])):
        return f"its texture {info['index']}'s sampler {texture.sampler!r} names no sampler of the file"
    for _, index in sources:
        if index is not None:
            why = image_size_problem(gltf, index)
            if why:
                return why
    return None


def image_size_problem(gltf, index: int) -> str | None:
    """Whether image ``index`` declares more texels than the limit (from its header; nothing decoded)."""
    image = gltf.data.images[index]
    try:
        if image.uri is not None and not image.uri.startswith("data:"):
            path = Path(gltf.filename).parent / urllib.parse.unquote(image.uri)
            if not path.exists():
                return None  # Blender's importer warns and shows a placeholder
            if not path.is_file():  # a FIFO or a device: Blender would block on it or read it for ever
                return f"step map image {index} ({image.uri}) is not a regular file"
            _check_size(path)
            return None
        data = _bytes(gltf, image)
        if data is None:
            return None
        with tempfile.TemporaryDirectory(prefix="csm-blender-") as tmp:
            path = Path(tmp) / f"step_map{SUFFIXES.get(image.mime_type, '.png')}"
            path.write_bytes(data)
            _check_size(path)
    except FormatError as e:
        return f"step map image {index}: {str(e).removeprefix(f'{e.path}: ')}"
    return None


def _check_size(path: Path) -> None:
    from ..formats.image import read_size

    w, h = read_size(path)
    limits.check(path, "TEXELS", w * h, f"a {w}x{h}-pixel image")


def _bytes(gltf, image) -> bytes | None:
    """An embedded image's bytes (a data URI's or its buffer view's), None when it has none."""
    if image.uri is not None:
        head, _, body = image.uri.partition(",")
        if not head.endswith(";base64"):
            return urllib.parse.unquote_to_bytes(body)
        try:
            return base64.b64decode(body, validate=False)
        except ValueError:
            raise FormatError("data URI", "is not base64") from None
    view = image.buffer_view
    views = gltf.data.buffer_views or []
    if not _index(view, len(views)):
        raise FormatError("image", f"bufferView {view!r} names no buffer view of the file")
    from .gltf_io import importer

    return bytes(importer().BinaryData.get_buffer_view(gltf, view))


def depth_problem(depth_scale: float) -> str | None:
    """A depthScale Blender cannot hold (beyond its 32-bit floats), or None."""
    if not depth_scale <= FLOAT32_MAX:
        return f"depthScale {depth_scale:g} is beyond Blender's 32-bit float range ({FLOAT32_MAX:.4g})"
    return None


def blender_extras(ext: dict, problems: list) -> dict:
    """The extension's ``extras.blender`` object ({} when absent; when not an object, noted in ``problems``)."""
    extras = ext.get("extras", {})
    if not isinstance(extras, dict):
        problems.append("extras is not an object; the Blender hints' defaults are used")
        return {}
    hint = extras.get("blender", {})
    if not isinstance(hint, dict):
        problems.append("extras.blender is not an object; its defaults are used")
        return {}
    return hint


def extras_value(extras: dict, key: str, problems: list):
    """``extras.blender[key]`` when valid (None when absent or not; a present but bad value is noted in
    ``problems``): node and space one of :data:`EXTRAS`, midlevel a finite 32-bit float, strength in (0, 1]."""
    if key not in extras:
        return None
    v = extras[key]
    if key in EXTRAS:
        ok = isinstance(v, str) and v in EXTRAS[key]
    else:
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and _finite32(v)
        ok = ok and (key != "strength" or 0 < v <= 1)
    if not ok:
        shown = repr(v) if len(repr(v)) <= 40 else repr(v)[:30] + "..."
        problems.append(f"extras.blender.{key} {shown} is not {_expected(key)}; its default is used")
        return None
    return v if key in EXTRAS else float(v)


def _expected(key: str) -> str:
    if key in EXTRAS:
        return " or ".join(EXTRAS[key])
    return "in (0, 1]" if key == "strength" else "a finite number within 32-bit floats"


def _finite32(v) -> bool:
    try:
        return math.isfinite(float(v)) and abs(float(v)) <= FLOAT32_MAX
    except OverflowError:
        return False


def _index(v, count: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 0 <= v < count
