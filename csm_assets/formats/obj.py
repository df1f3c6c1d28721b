"""Wavefront OBJ + MTL scenes (MTL parsed in :mod:`.mtl`: trimesh keeps ``disp``/``bump`` only as tokens).

Heights: a material's ``disp`` map, else its ``bump``/``map_bump`` map (convert then
skips tangent-space normal maps, which Blender exports under ``map_Bump``: see
:mod:`csm_assets.height_source`). ``-mm base gain`` (disp) and ``-bm mult`` (bump) give
the displacement factor; without them the depth is ``DEFAULT_DEPTH`` (0.1 of the
texture's width). ``-imfchan`` picks the channel. Writing copies the OBJ byte for byte
and adds CSM statements to the MTL (docs/reference/materials.md), every other byte of it kept;
faces no ``usemtl`` names get a material of their own when ``--height =FILE`` gives them a
height (:mod:`.obj_default`).

Malformed geometry (a ``v``/``vn`` with fewer than three numbers, a non-finite number,
an index out of range) is a FormatError naming the file and line; faces with fewer
than three vertices are skipped with a warning; faces without uvs leave their
material without CSM, with a warning.
"""

from __future__ import annotations

import math
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..convert.links import missing
from ..convert.output_folder import free_name
from ..errors import FormatError, case_hint
from ..height_source import DEFAULT_DEPTH, material_height
from ..scene import HeightInput, Material, Mesh, Scene, Texture, resolve_reference, safe_name
from . import mtl, obj_default
from .csm_params import mtl_lines
from .mtl import CHANNELS, MAP_STATEMENTS, MtlLibrary, MtlMaterial, parse_map  # noqa: F401 (public names)
from .registry import module_bits, module_stores_tangents

STORES_TANGENTS = module_stores_tangents("obj")  # OBJ has no tangent statement: none are generated for it
STEP_MAP_BITS = module_bits("obj")
HEIGHT_KEYS = ("disp", "bump", "map_bump")


def _height(scene: Scene, m: MtlMaterial, lib: MtlLibrary) -> HeightInput | None:
    for key in HEIGHT_KEYS:
        st = m.maps.get(key)
        if st is None or st.path is None:
            continue
        if not st.path.is_file():
            scene.warn("CSM101", f"{key} texture {st.file} is missing{case_hint(st.path)}; left without CSM",
                       f"material {m.name!r}")
            scene.said_missing.add(st.path)
            return None
        depth = None
        if key == "disp" and "-mm" in st.options:
            offset, scale = (mtl.number(lib.path, st, "-mm", 0, 0.0), mtl.number(lib.path, st, "-mm", 1, 1.0))
        elif key != "disp" and st.options.get("-bm"):
            offset, scale = 0.0, mtl.number(lib.path, st, "-bm", 0, 1.0)
        else:  # no factor stated: a default texture-space depth, not 1 model unit
            offset, scale, depth = 0.0, 1.0, DEFAULT_DEPTH
        chan = st.options.get("-imfchan", [None])
        channel = CHANNELS.get(chan[0].lower(), None) if chan and chan[0] else None
        return HeightInput(Texture(_stem(st.file), path=st.path), 0, channel, False, scale, offset,
                           f"mtl {key}", depth=depth)
    return None


def _stem(file: str) -> str:
    """The safe name of the file an MTL statement names, without its extension."""
    return safe_name(Path(file.replace("\\", "/")).stem)


@dataclass
class ObjSource:
    path: Path
    libraries: list[MtlLibrary]
    default: Material | None = None  # the faces no usemtl names, given a height (:mod:`.obj_default`)
    default_faces: bool = False      # some faces take the default material (no usemtl before them)


def _libraries(path: Path, text: str, scene: Scene, ref) -> list[MtlLibrary]:
    """The material libraries every ``mtllib`` statement names (several per statement
    when the whole name is not a file), each once; ``ref(base, name)`` resolves a name."""
    libs, seen = [], set()
    for line in text.splitlines():
        parts = line.split(None, 1)
        if len(parts) < 2 or parts[0] != "mtllib":
            continue
        whole = parts[1].strip()
        names = [whole]
        if not ref(path.parent, whole).is_file():
            names = whole.split() if len(whole.split()) > 1 else names
        for name in names:
            file = ref(path.parent, name)
            if file.resolve() in seen:
                continue
            seen.add(file.resolve())
            if not file.is_file():
                scene.warn("CSM101", f"material library {name} is missing{case_hint(file)}; its materials get no CSM")
                scene.absent.append(file)
                continue
            libs.append(mtl.read(file, name))
            scene.inputs.append(file)
    return libs


def read(path, heights: dict | None = None, *, allow_outside: bool = False, root=None) -> Scene:
    """The scene of an OBJ file and its MTL: one mesh per material that has a height.
    Files named outside the project root ``root`` (default: the OBJ's folder) are refused
    unless ``allow_outside``."""
    path = Path(path)

    def ref(base, name):
        return resolve_reference(path, base, name, allow_outside=allow_outside, root=root)

    try:
        data = path.read_bytes()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    utf16 = data[:2] in (b"\xfe\xff", b"\xff\xfe")  # assimp's box_UTF16BE.obj
    text = data.decode("utf-16" if utf16 else "utf-8-sig", errors="replace")
    _check_numbers(path, text)
    scene = Scene(path, "obj", inputs=[path])
    libs = _libraries(path, text, scene, ref)
    for lib in libs:
        for m in lib.materials.values():
            for st in m.maps.values():
                if st.file:
                    st.path = ref(lib.path.parent, st.file)
                    if st.path.is_file() and st.path not in scene.inputs:
                        scene.inputs.append(st.path)
                    elif not st.path.is_file():
                        scene.absent.append(st.path)
    scene.source = ObjSource(path, libs)
    heights = heights or {}
    for lib in libs:
        for name, m in lib.materials.items():
            if any(mat.name == name for mat in scene.materials):
                continue  # the first library defining a name wins
            mat = Material(name, ref=name)
            mat.height, _ = material_height(heights, [name], scene, lambda m=m, lib=lib: _height(scene, m, lib))
            scene.materials.append(mat)
    scene.source.default_faces = obj_default.has_default_faces(text)
    scene.source.default = obj_default.default_material(scene, text, heights, {m.name for m in scene.materials})
    if scene.source.default is not None:
        scene.materials.append(scene.source.default)
    wanted = {m.name: m for m in scene.materials if m.height is not None}
    if wanted:
        scene.meshes = _meshes(scene, text, wanted, "" if scene.source.default is not None else None)
    return scene


SUSPECT = re.compile(r"^[ \t]*(v|vt|vn)[ \t][^\n]*(nan|inf|#ind)", re.IGNORECASE | re.MULTILINE)


def _check_numbers(path: Path, text: str) -> None:
    """FormatError at the first ``v``/``vt``/``vn`` holding a NaN or infinity, anywhere in
    the file (a fast scan: the geometry of materials without heights is not parsed, but
    is copied to the output, which must never hold non-finite numbers)."""
    for m in SUSPECT.finditer(text):
        parts = text[m.start():text.find("\n", m.start()) % (len(text) + 1)].split()
        _floats(path, text.count("\n", 0, m.start()) + 1, parts[0], parts[1:4], 1)


def _floats(path: Path, n: int, key: str, values: list[str], least: int) -> list[float]:
    if len(values) < least:
        raise FormatError(path, f"line {n}: {key!r} needs {least} numbers, got {len(values)}")
    try:
        xs = [float(x) for x in values]
    except ValueError:
        raise FormatError(path, f"line {n}: {key!r} holds a value that is not a number: "
                                f"{' '.join(values)[:60]!r}") from None
    if not all(math.isfinite(x) for x in xs):
        raise FormatError(path, f"line {n}: {key!r} holds a NaN or infinite value")
    return xs


def _meshes(scene: Scene, text: str, wanted: dict[str, Material], default: str | None = None) -> list[Mesh]:
    """default: the material name faces before any ``usemtl`` take (None: none)."""
    path = scene.path
    v, vt, vn = [], [], []
    corners: dict[str, list[tuple[int, int, int]]] = {}
    short: dict[str, list[int]] = {}  # material -> line numbers of its faces with fewer than three vertices
    current = default
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            v.append(_floats(path, n, key, parts[1:4], 3))
        elif key == "vt":
            vt.append((_floats(path, n, key, parts[1:3], 1) + [0.0])[:2])
        elif key == "vn":
            vn.append(_floats(path, n, key, parts[1:4], 3))
        elif key == "usemtl":
            current = " ".join(parts[1:])
        elif key == "f" and current in wanted:
            if len(parts) < 4:
                short.setdefault(current, []).append(n)
                continue
            try:
                refs = [_corner(tok, len(v), len(vt), len(vn)) for tok in parts[1:]]
            except (ValueError, IndexError) as e:
                raise FormatError(path, f"line {n}: malformed 'f' statement ({e})") from None
            for i in range(1, len(refs) - 1):  # fan-triangulate polygons
                corners.setdefault(current, []).extend([refs[0], refs[i], refs[i + 1]])
    for name, lines in short.items():
        scene.warn("CSM207", f"{len(lines)} face(s) with fewer than three vertices skipped (first on line {lines[0]})",
                   f"mesh {name}")
    V, VT, VN = np.array(v, float).reshape(-1, 3), np.array(vt, float).reshape(-1, 2), \
        np.array(vn, float).reshape(-1, 3)
    meshes = []
    for name, refs in corners.items():
        arr = np.array(refs, np.int64)
        if (arr[:, 1] < 0).any():
            bare = int((arr[:, 1] < 0).reshape(-1, 3).any(1).sum())
            scene.warn("CSM202", f"{bare} of {len(arr) // 3} triangle(s) have no uvs, so no CSM material (the relief "
                       "needs texture coordinates); add uvs to it", f"mesh {name} (material {name!r})")
            wanted[name].height = None
            continue
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

    if not parts[0]:
        raise ValueError(f"corner {token!r} names no vertex")
    return index(parts[0], nv), index(parts[1], nvt), index(parts[2], nvn)


def write(scene: Scene, out_dir) -> list[Path]:
    """The OBJ byte for byte and its MTLs with CSM statements after each converted
    material; textures the MTLs name are copied beside them with flat, safe names."""
    src: ObjSource = scene.source
    out_dir = Path(out_dir)
    csm = {m.name: m.csm for m in scene.materials if m.csm is not None and m is not src.default}
    reserved = {p.name for c in csm.values() for p in c.step_maps()} | {scene.path.name} | scene.reserved | {
        Path(lib.name).name for lib in src.libraries}
    if src.default is not None and src.default.csm is not None:  # the OBJ names a material for it now
        written = obj_default.write(scene, src.path, out_dir, src.default.csm,
                                    {n for lib in src.libraries for n in lib.materials}, reserved)
        reserved.add(written[1].name)
    else:
        target = out_dir / scene.path.name
        with atomic_path(target) as tmp:
            shutil.copyfile(src.path, tmp)
        written = [target]
    copies: dict[Path, str] = {}
    done: set[str] = set()
    for lib in src.libraries:
        added = {}
        for name in lib.materials:
            if name in csm and name not in done:
                added[name] = mtl_lines(csm[name], csm[name].step_map.name)
                done.add(name)
        renamed = {}
        for m in lib.materials.values():
            for st in m.maps.values():
                new = _copy(st, out_dir, copies, reserved, written, scene.others, scene.links,
                            scene.warn, scene.published or out_dir, scene.said_missing)
                if new is not None and new != st.file:
                    renamed[st.line - 1] = new
        mtl_target = out_dir / Path(lib.name).name
        with atomic_path(mtl_target) as tmp:
            tmp.write_bytes(mtl.render(lib, added, renamed))
        written.append(mtl_target)
    return written


def _copy(st: mtl.MapStatement, out_dir: Path, copies: dict, reserved: set, written: list,
          others: dict, links=None, warn=None, published=None, said=frozenset()) -> str | None:
    """The flat name the texture of ``st`` is copied to in ``out_dir`` (None: not a file): its own
    name when that is safe and free (:func:`~csm_assets.convert.output_folder.free_name`); the
    relative path to it where ``links`` (:class:`~csm_assets.convert.links.Links`) can name it
    and the path holds no white space (an MTL file name is words joined by one space). A missing
    file is named where the MTL names it, relative to ``published`` (the output folder, else
    ``out_dir``), with a CSM404 through ``warn`` (unless ``said``: a CSM101 named it), so it
    resolves once there."""
    src = st.path
    if src is not None and not src.exists() and (where := missing(published or out_dir, src)) is not None \
            and not any(c.isspace() for c in where):
        if warn is not None and src not in said:
            warn("CSM404", f"{st.keyword} {st.file} resolves to nothing; named where the MTL names it ({where}), "
                           "so the output names a file it does not have")
        return where
    if src is None or not src.is_file():
        return None
    link = links.to(src) if links is not None and src not in copies else None
    if link is not None and not any(c.isspace() for c in link):
        copies[src] = link
    if src not in copies:
        stem, suffix = Path(st.file).stem, Path(st.file).suffix
        if safe_name(st.file) != st.file:
            stem, suffix = _stem(st.file), suffix.lower()
        name = free_name(stem, suffix, lambda n: n in reserved or n in copies.values(), others, content=src)
        with atomic_path(out_dir / name) as tmp:
            shutil.copyfile(src, tmp)
        copies[src] = name
        written.append(out_dir / name)
    return copies[src]
