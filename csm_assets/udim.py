"""UDIM tile sets: tile numbers, a set's tiles on disk, and the tile each face of a mesh lies in.

The standard numbering (Mari, USD, RenderMan, Houdini): tile ``1001 + i + 10 * j`` covers u in
``[i, i + 1]`` and v in ``[j, j + 1]`` with v up (USD's st; glTF's v grows down and is flipped
first), i in 0..9, so 1001..1999. Each tile is its own uv square with its own image: a height
set gets one step map per tile (:mod:`csm_assets.convert.udim`), drawn in the tile's local uvs
(the uv less the tile's corner), and a face belongs to the tile its uv centroid lies in.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import numpy as np

from .errors import FormatError
from .scene import Mesh, Texture, UdimSet, safe_name

TOKEN = "<UDIM>"
TILES = range(1001, 2000)


def is_pattern(path) -> bool:
    """Whether ``path`` (a path or text) names a UDIM set: ``<UDIM>`` in its file name."""
    return TOKEN in Path(str(path)).name


def corner(tile: int) -> tuple[int, int]:
    """The corner of a UDIM tile's uv square.

    Args:
        tile: a tile number, 1001..1999.

    Returns:
        ``(u, v)``, v up: 1001 -> (0, 0), 1002 -> (1, 0), 1011 -> (0, 1).
    """
    return (tile - 1001) % 10, (tile - 1001) // 10


def tile_name(pattern: str, tile: int) -> str:
    """``pattern`` with its ``<UDIM>`` replaced by ``tile``."""
    return pattern.replace(TOKEN, str(tile))


def set_name(pattern) -> str:
    """The name of a set's files (before ``<UDIM>``), as a safe file name: ``h.<UDIM>.png`` -> ``h``."""
    head = Path(str(pattern)).name.split(TOKEN, 1)[0]
    return safe_name(head) if head.strip("._") else "udim"


def tile_files(pattern: Path) -> dict[int, Path]:
    """The tiles of a UDIM set found beside its pattern (one listing of the folder).

    Args:
        pattern: a path with ``<UDIM>`` in its file name (``textures/rock.<UDIM>.png``).

    Returns:
        tile -> file, in tile order: the regular files whose names put a tile number 1001..1999
        in place of ``<UDIM>`` (empty when the folder is missing).
    """
    pattern = Path(pattern)
    match = _matcher(pattern.name)
    try:
        names = os.listdir(pattern.parent)
    except (FileNotFoundError, NotADirectoryError):
        return {}
    found = {int(m.group(1)): pattern.parent / n for n in names if (m := match(n)) and int(m.group(1)) in TILES}
    return {t: found[t] for t in sorted(found) if found[t].is_file()}


def _matcher(name: str):
    """A regular expression's ``fullmatch`` for the tile file names of the pattern ``name``."""
    head, tail = name.split(TOKEN, 1)
    return re.compile(re.escape(head) + r"(1\d\d\d)" + re.escape(tail)).fullmatch


def in_set(pattern: Path, file: Path) -> bool:
    """Whether ``file`` is (or would be) a tile of the set ``pattern`` (both resolved alike)."""
    m = _matcher(Path(pattern).name)(Path(file).name)
    return bool(m) and int(m.group(1)) in TILES and Path(file).resolve().parent == Path(pattern).resolve().parent


def file_set(pattern: Path, what: str = "") -> UdimSet:
    """The :class:`~csm_assets.scene.UdimSet` of the files found for ``pattern``; FormatError naming the
    pattern (and ``what`` named it) when it has no tile."""
    files = tile_files(pattern)
    if not files:
        raise FormatError(pattern, f"is a UDIM set with no tile (no file {tile_name(Path(pattern).name, 1001)}, "
                                   f"... {tile_name(Path(pattern).name, 1999)} beside it){what}")
    name = set_name(pattern)
    return UdimSet({t: Texture(name, path=f) for t, f in files.items()}, Path(pattern))


def record(pattern: Path, tiles=None) -> str:
    """What a manifest records of a set: the tiles it has (``tiles 1001,1002``; ``tiles``: those read,
    else those on disk now), so that a tile added or removed makes the outputs stale (each tile's bytes
    are recorded as an input too)."""
    return "tiles " + ",".join(map(str, sorted(tile_files(pattern) if tiles is None else tiles)))


def records(scene) -> dict[Path, str]:
    """:func:`record` of every UDIM set on disk a converted material of ``scene`` read, as read."""
    return {m.height.udim.pattern: record(m.height.udim.pattern, m.height.udim.tiles) for m in scene.materials
            if m.csm is not None and m.height is not None and m.height.udim is not None
            and m.height.udim.pattern is not None}


def face_tiles(mesh: Mesh) -> np.ndarray:
    """The UDIM tile each face of a mesh lies in, by its uv centroid.

    Args:
        mesh: a scene mesh with uvs (either origin: glTF's v down is flipped first).

    Returns:
        int64 ``(F,)``: tile numbers, 0 for a face outside tiles 1001..1999 (or without finite uvs).
    """
    uv = np.asarray(mesh.uvs, np.float64)[np.asarray(mesh.faces, np.int64)].mean(axis=1)
    if mesh.uv_origin == "top-left":
        uv = uv * [1.0, -1.0] + [0.0, 1.0]
    with np.errstate(invalid="ignore"):
        i, j = np.floor(uv[:, 0]), np.floor(uv[:, 1])
        ok = np.isfinite(uv).all(axis=1) & (i >= 0) & (i <= 9) & (j >= 0) & (j <= 99)
    tile = 1001 + np.where(ok, i, 0) + 10 * np.where(ok, j, 0)
    return np.where(ok & (tile <= TILES[-1]), tile, 0).astype(np.int64)


def tile_mesh(mesh: Mesh, tile: int, faces: np.ndarray) -> Mesh:
    """The faces ``faces`` (a mask or indices) of ``mesh`` as a mesh of their own, named
    ``mesh [tile]``, uvs moved into the tile's own square (less its corner)."""
    u, v = corner(tile)
    shift = [-u, -v] if mesh.uv_origin == "bottom-left" else [-u, v]  # top-left: v down, tile j at -j..1-j
    ct = mesh.corner_tangents
    return dataclasses.replace(mesh, name=f"{mesh.name} [{tile}]", faces=np.asarray(mesh.faces)[faces],
                               uvs=np.asarray(mesh.uvs, np.float64) + shift,
                               corner_tangents=None if ct is None else np.asarray(ct)[faces])


def spans(mesh: Mesh, tiles: np.ndarray, margin: float = 1e-4) -> int:
    """How many faces of ``mesh`` reach outside the square of the tile ``tiles`` gives them."""
    uv = np.asarray(mesh.uvs, np.float64)[np.asarray(mesh.faces, np.int64)]
    if mesh.uv_origin == "top-left":
        uv = uv * [1.0, -1.0] + [0.0, 1.0]
    u0, v0 = (tiles - 1001) % 10, (tiles - 1001) // 10
    local = uv - np.stack([u0, v0], axis=1)[:, None, :]
    return int(((local < -margin) | (local > 1 + margin)).any(axis=(1, 2))[tiles > 0].sum())


def split(mesh: Mesh) -> list[tuple[int, Mesh]]:
    """``mesh`` in parts by the tile its faces lie in (:func:`face_tiles`): ``(tile, part)`` in tile
    order, each part's uvs in its tile's own square (tile 0: faces outside 1001..1999, as they are)."""
    where = face_tiles(mesh)
    return [(t, tile_mesh(mesh, t, where == t) if t else dataclasses.replace(mesh, faces=mesh.faces[where == 0]))
            for t in sorted(set(where.tolist()))]


def parts(meshes, stored: dict):
    """``(mesh, stored CSM, problem)`` for each mesh whose material ``stored`` holds (by ref): the mesh
    itself, or for a UDIM set (``stored.tiles``: tile -> (image, second image)) each tile's faces with
    that tile's images, and faces in a tile the set lacks with a problem saying so (verify draws each
    tile and reports it on its own line)."""
    for mesh in meshes:
        s = stored.get(mesh.material.ref) if mesh.material is not None else None
        if s is None:
            continue
        if not s.tiles:
            yield mesh, s, ""
            continue
        for t, part in split(mesh):
            first, second = s.tiles.get(t, (s.step_map, s.step_map2))
            lacks = "" if t in s.tiles else \
                f"its uvs lie in UDIM tile {t or 'outside 1001-1999'}, which has no step map (no relief there)"
            yield part, dataclasses.replace(s, step_map=first, step_map2=second), lacks
