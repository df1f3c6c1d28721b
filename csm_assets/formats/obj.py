"""Wavefront OBJ + MTL scenes (MTL parsed here: trimesh keeps ``disp``/``bump`` only as tokens).

Heights: a material's ``disp`` map, else its ``bump``/``map_bump`` map unless that image
is a tangent-space normal map (Blender exports those under ``map_Bump``), detected by
content. ``-mm base gain`` (disp) and ``-bm mult`` (bump) give the scale, ``-imfchan``
the channel. Writing copies the OBJ as is and adds CSM statements to the MTL (README).
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import FormatError
from ..scene import HeightInput, Material, Mesh, Scene, Texture, resolve_reference, safe_name

STORES_TANGENTS = False  # OBJ has no tangent statement: none are generated for it
STEP_MAP_BITS = (8, 16, 32)

MAP_STATEMENTS = {"map_ka", "map_kd", "map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal",
                  "refl", "map_pr", "map_pm", "map_ps", "map_ke", "norm", "map_kn"}
# option -> how many arguments it takes at most (numbers or on/off words)
OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
           "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}
CHANNELS = {"r": 0, "g": 1, "b": 2, "m": 3, "z": 0, "l": None}


@dataclass
class MapStatement:
    """One texture statement of an MTL: its options and the file it names (``path``, once
    resolved against the scene's folder)."""

    keyword: str
    options: dict[str, list[str]]
    file: str
    line: int
    path: Path | None = None


@dataclass
class MtlMaterial:
    name: str
    lines: list[str] = field(default_factory=list)  # every statement, as written
    maps: dict[str, MapStatement] = field(default_factory=dict)


def parse_map(keyword: str, args: list[str], line: int) -> MapStatement:
    options, i = {}, 0
    while i < len(args) and args[i].lower() in OPTIONS:
        opt = args[i].lower()
        i += 1
        vals = []
        while i < len(args) - 1 and len(vals) < OPTIONS[opt] and _is_value(args[i]):
            vals.append(args[i])
            i += 1
        options[opt] = vals
    return MapStatement(keyword, options, " ".join(args[i:]), line)


def _is_value(token: str) -> bool:
    return token.lower() in ("on", "off", "r", "g", "b", "m", "l", "z") or bool(
        re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", token))


def read_mtl(path: Path) -> dict[str, MtlMaterial]:
    """Materials of an MTL file, each keeping its statements verbatim."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    materials, current = {}, None
    for n, raw in enumerate(text.splitlines(), 1):
        parts = raw.strip().split()
        if not parts or parts[0].startswith("#"):
            if current is not None:
                current.lines.append(raw)
            continue
        key = parts[0].lower()
        if key == "newmtl":
            current = materials.setdefault(" ".join(parts[1:]), MtlMaterial(" ".join(parts[1:])))
            continue
        if current is None:
            continue
        current.lines.append(raw)
        if key in MAP_STATEMENTS and len(parts) > 1:
            current.maps[key] = parse_map(key, parts[1:], n)
    return materials


def is_normal_map(path: Path) -> bool:
    """True for a tangent-space normal map: RGB vectors of about unit length, pointing out
    (blue high, red and green centred), unlike a grey height map."""
    from . import image

    try:
        pixels, _ = image.read_pixels(path)
    except FormatError:
        return False
    if pixels.shape[2] < 3:
        return False
    rgb = image._unit(path, pixels)[..., :3].reshape(-1, 3) * 2 - 1
    lengths = np.linalg.norm(rgb, axis=1)
    mean = rgb.mean(0)
    return bool(np.median(np.abs(lengths - 1)) < 0.15 and mean[2] > 0.5 and abs(mean[0]) < 0.3
                and abs(mean[1]) < 0.3)


def _height(scene: Scene, m: MtlMaterial) -> HeightInput | None:
    for key in ("disp", "bump", "map_bump"):
        st = m.maps.get(key)
        if st is None or st.path is None:
            continue
        file = st.path
        if not file.is_file():
            scene.warn(f"material {m.name!r}: {key} texture {st.file} is missing; left without CSM")
            return None
        if key != "disp" and is_normal_map(file):
            scene.warn(f"material {m.name!r}: {key} {st.file} is a normal map, not heights; skipped")
            continue
        scale, offset = 1.0, 0.0
        if key == "disp" and "-mm" in st.options:
            vals = [float(v) for v in st.options["-mm"]] + [0.0, 1.0][len(st.options["-mm"]):]
            offset, scale = vals[0], vals[1]
        elif "-bm" in st.options and st.options["-bm"]:
            scale = float(st.options["-bm"][0])
        chan = st.options.get("-imfchan", [None])
        channel = CHANNELS.get(chan[0].lower(), None) if chan and chan[0] else None
        return HeightInput(Texture(_stem(st.file), path=file), 0, channel, False, scale, offset,
                           f"mtl {key}")
    return None


def _stem(file: str) -> str:
    """The safe name of the file an MTL statement names, without its extension."""
    return safe_name(Path(file.replace("\\", "/")).stem)


@dataclass
class ObjSource:
    text: str
    mtl_path: Path | None
    mtl: dict[str, MtlMaterial]
    mtllib: str | None


def read(path, heights: dict | None = None, *, allow_outside: bool = False) -> Scene:
    """The scene of an OBJ file and its MTL: one mesh per material that has a height.
    Files named outside the OBJ's folder are refused unless ``allow_outside``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    mtllib = next((ln.split(None, 1)[1].strip() for ln in text.splitlines()
                   if ln.startswith("mtllib ") and len(ln.split()) > 1), None)
    scene = Scene(path, "obj", inputs=[path])
    mtl_path = resolve_reference(path, path.parent, mtllib, allow_outside=allow_outside) if mtllib else None
    mtl = {}
    if mtl_path is not None:
        if mtl_path.is_file():
            mtl = read_mtl(mtl_path)
            scene.inputs.append(mtl_path)
        else:
            scene.warn(f"material library {mtllib} is missing")
    for m in mtl.values():
        for st in m.maps.values():
            if st.file:
                st.path = resolve_reference(path, mtl_path.parent, st.file, allow_outside=allow_outside)
                if st.path.is_file() and st.path not in scene.inputs:
                    scene.inputs.append(st.path)
    scene.source = ObjSource(text, mtl_path, mtl, mtllib)
    heights = heights or {}
    for name, m in mtl.items():
        mat = Material(name, ref=name)
        if name in heights:
            p = Path(heights[name])
            mat.height = HeightInput(Texture(p.stem, path=p), origin="command line")
        else:
            mat.height = _height(scene, m)
        scene.materials.append(mat)
    wanted = {m.name: m for m in scene.materials if m.height is not None}
    if wanted:
        scene.meshes = _meshes(path, text, wanted)
    return scene


def _meshes(path: Path, text: str, wanted: dict[str, Material]) -> list[Mesh]:
    v, vt, vn = [], [], []
    corners: dict[str, list[tuple[int, int, int]]] = {}
    current = None
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        key = parts[0]
        try:
            if key == "v":
                v.append([float(x) for x in parts[1:4]])
            elif key == "vt":
                vt.append([float(x) for x in (parts[1:3] + ["0"])[:2]])
            elif key == "vn":
                vn.append([float(x) for x in parts[1:4]])
            elif key == "usemtl":
                current = " ".join(parts[1:])
            elif key == "f" and current in wanted:
                refs = [_corner(tok, len(v), len(vt), len(vn)) for tok in parts[1:]]
                for i in range(1, len(refs) - 1):  # fan-triangulate polygons
                    corners.setdefault(current, []).extend([refs[0], refs[i], refs[i + 1]])
        except (ValueError, IndexError) as e:
            raise FormatError(path, f"line {n}: malformed {key!r} statement ({e})") from None
    V, VT, VN = np.array(v, float).reshape(-1, 3), np.array(vt, float).reshape(-1, 2), \
        np.array(vn, float).reshape(-1, 3)
    meshes = []
    for name, refs in corners.items():
        arr = np.array(refs, np.int64)
        if (arr[:, 1] < 0).any():
            continue  # faces without uvs: no tangents; convert warns via the missing mesh
        uniq, inverse = np.unique(arr, axis=0, return_inverse=True)
        normals = VN[uniq[:, 2]] if (uniq[:, 2] >= 0).all() else None
        meshes.append(Mesh(name, V[uniq[:, 0]], inverse.reshape(-1, 3), normals, VT[uniq[:, 1]],
                           None, wanted[name], uv_origin="bottom-left", ref=name))
    return meshes


def _corner(token: str, nv: int, nvt: int, nvn: int) -> tuple[int, int, int]:
    parts = (token.split("/") + ["", ""])[:3]

    def index(s: str, count: int) -> int:
        if not s:
            return -1
        i = int(s)
        i = i - 1 if i > 0 else count + i
        if not 0 <= i < count:
            raise IndexError(f"index {s} out of range 1..{count}")
        return i

    return index(parts[0], nv), index(parts[1], nvt), index(parts[2], nvn)


def write(scene: Scene, out_dir) -> list[Path]:
    """The OBJ as it was and its MTL with CSM statements after each converted material;
    textures the MTL names are copied beside it with flat, safe names."""
    src: ObjSource = scene.source
    out_dir = Path(out_dir)
    written = []
    target = out_dir / scene.path.name
    with atomic_path(target) as tmp:
        tmp.write_text(src.text, encoding="utf-8")
    written.append(target)
    if src.mtl_path is None or not src.mtl:
        return written
    csm = {m.name: m.csm for m in scene.materials if m.csm is not None}
    reserved = {c.step_map.name for c in csm.values()}
    copies: dict[Path, str] = {}
    lines = []
    for name, m in src.mtl.items():
        lines.append(f"newmtl {name}")
        for raw in m.lines:
            lines.append(_relocated(raw, m, out_dir, copies, reserved, written))
        if name in csm:
            c = csm[name]
            lines += [f"csm_map {c.step_map.name}", f"csm_depth {c.depth_scale:.9g}",
                      f"csm_max_ratio {c.max_ratio:.9g}", f"csm_tile {int(c.tile[0])} {int(c.tile[1])}",
                      f"csm_variant {c.variant}", f"csm_steps {c.steps}", f"csm_min_step {c.min_step:g}"]
        lines.append("")
    mtl_target = out_dir / Path(src.mtllib).name
    with atomic_path(mtl_target) as tmp:
        tmp.write_text("\n".join(lines), encoding="utf-8")
    written.append(mtl_target)
    return written


def _relocated(raw: str, m: MtlMaterial, out_dir: Path, copies: dict, reserved: set, written: list) -> str:
    """``raw`` with the texture it names copied into ``out_dir`` and renamed there."""
    parts = raw.strip().split()
    if not parts or parts[0].lower() not in MAP_STATEMENTS or len(parts) < 2:
        return raw
    st = m.maps.get(parts[0].lower())
    src = st.path if st is not None else None
    if src is None or not src.is_file():
        return raw
    if src not in copies:
        name, n = f"{_stem(st.file)}{Path(st.file).suffix.lower()}", 1
        while name in reserved or name in copies.values():
            name, n = f"{_stem(st.file)}_{n}{Path(st.file).suffix.lower()}", n + 1
        with atomic_path(out_dir / name) as tmp:
            shutil.copyfile(src, tmp)
        copies[src] = name
        written.append(out_dir / name)
    head = raw[: raw.rstrip().rfind(st.file)] if raw.rstrip().endswith(st.file) else f"{parts[0]} "
    return f"{head}{copies[src]}"
