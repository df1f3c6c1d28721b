"""The in-memory scene model every scene reader makes and every writer takes.

Only what conversion needs is lifted out of a file (meshes, materials, their height
textures); ``Scene.source`` keeps the format's own document so a writer can hand the
rest back untouched.
"""

from __future__ import annotations

import contextlib
import hashlib
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import references
from .stepmap import DEFAULTS, StepMapSettings, levels_path, second_path
from .warning_codes import Notice, add


@dataclass
class Texture:
    """An image a material refers to: a file (``path``) or embedded bytes (``data``)."""

    name: str
    path: Path | None = None
    data: bytes | None = None
    mime: str | None = None

    def read_bytes(self) -> bytes:
        return self.data if self.data is not None else Path(self.path).read_bytes()

    @property
    def suffix(self) -> str:
        """The file extension the image's bytes call for ('.png', '.jpg', ...)."""
        if self.path is not None and Path(self.path).suffix:
            return Path(self.path).suffix.lower()
        return {"image/png": ".png", "image/jpeg": ".jpg", "image/x-exr": ".exr",
                "image/tiff": ".tif", "image/x-tga": ".tga"}.get(self.mime or "", ".png")

    def content_hash(self) -> str:
        return hashlib.sha256(self.read_bytes()).hexdigest()

    @contextlib.contextmanager
    def as_file(self):
        """A path holding the image, for readers that want files: its own file, or a
        temporary one (removed afterwards) holding the embedded bytes."""
        if self.path is not None:
            yield Path(self.path)
            return
        with tempfile.TemporaryDirectory() as tmp:
            file = Path(tmp) / f"{safe_name(self.name)}{self.suffix}"
            file.write_bytes(self.data)
            yield file


def safe_name(text: str) -> str:
    """A file name that cannot leave a folder: the last part of ``text`` ('/' or '\\'
    separated) in letters, digits, '-', '_' and '.', at most 100 characters."""
    last = text.replace("\\", "/").rsplit("/", 1)[-1]
    return (re.sub(r"[^A-Za-z0-9._-]+", "_", last).strip("._") or "texture")[:100]


@dataclass
class UdimSet:
    """A UDIM height set (``name.<UDIM>.ext``): ``tiles`` maps each tile number present (1001 is
    u 0..1, v 0..1; 1002 u 1..2; 1011 v 1..2, v up) to its image; ``pattern`` is the set's path on
    disk with ``<UDIM>`` in it (None inside a package), for freshness (:mod:`csm_assets.udim`)."""

    tiles: dict[int, Texture]
    pattern: Path | None = None

    def first(self) -> Texture:
        """The lowest tile's image (it stands for the set where one texture is asked for)."""
        return self.tiles[min(self.tiles)]


@dataclass
class HeightInput:
    """Where a material's heights come from and how to read them.

    scale/offset: the material's displacement factor and offset (model units per unit
    of texture value), as the source format states them. depth: the texture-space depth
    (uv units per unit of height) when the source states no factor and a default
    stands in (see ``height_source.DEFAULT_DEPTH``); None to derive it from ``scale``.
    """

    texture: Texture
    tex_coord: int = 0
    channel: int | str | None = None
    invert: bool = False
    scale: float = 1.0
    offset: float = 0.0
    origin: str = ""
    tile: tuple[bool, bool] | None = None  # from the texture's wrap modes, where the format says
    depth: float | None = None
    udim: UdimSet | None = None  # a UDIM set (``texture``: its first tile, named after the set)

    def files(self) -> list[Path]:
        """The files the heights are read from: the texture's, or every tile's of a UDIM set."""
        textures = self.udim.tiles.values() if self.udim is not None else [self.texture]
        return [t.path for t in textures if t.path is not None]


@dataclass
class CsmSettings:
    """What a converted material carries for the CSM shader (see docs/reference/materials.md and
    :data:`csm_assets.formats.csm_params.PARAMETERS`): the step map file and the
    :class:`~csm_assets.stepmap.StepMapSettings` it was made with (``settings``: max ratio,
    tiling, bits, height scale and offset, and the minimum step derived from them, read
    from there only), plus what belongs to the material: depth, variant, steps, self-shadowing."""

    step_map: Path
    depth_scale: float
    settings: StepMapSettings = DEFAULTS
    variant: str = "exact"
    steps: int = 0
    self_shadow: bool = False
    light_size: float = 0.0  # the light's angular radius in radians (0: hard shadows)
    map: Any = field(default=None, repr=False, compare=False)  # the StepMap in memory, when made here
    picked_min_step: float | None = None  # the minimum step --max-error picked (quadrant maps), else the map's
    tiles: dict = field(default_factory=dict)  # a UDIM set's: tile -> its step map (``step_map``: the pattern)

    @classmethod
    def of(cls, step_map: Path, sm, depth_scale: float, variant: str = "exact", steps: int = 0,
           **material) -> CsmSettings:
        """The material settings of :class:`~csm_assets.stepmap.StepMap` ``sm`` written to ``step_map``."""
        return cls(step_map, depth_scale, sm.settings, variant, steps, map=sm, **material)

    def use_map(self, step_map: Path, sm) -> None:
        """Point at another step map (``sm`` written to ``step_map``), its settings with it."""
        self.step_map, self.map, self.settings = step_map, sm, sm.settings

    @property
    def step_map2(self) -> Path | None:
        """A quadrant map's second image, beside the first as ``save_step_map`` names it; else None."""
        return second_path(self.step_map) if self.settings.cones == "quadrant" else None

    @property
    def levels_images(self) -> list[Path]:
        """Each image's levels 1..n (``settings.levels`` not "none"), beside it as ``save_step_map``
        names them (:func:`~csm_assets.stepmap.levels_path`): the first's, then the second's."""
        images = [self.step_map, *([self.step_map2] if self.step_map2 is not None else [])]
        return [levels_path(p) for p in images] if self.settings.levels != "none" else []

    def step_maps(self) -> list[Path]:
        """The step map's files: the first image and a quadrant map's second (each tile's of a
        UDIM set), then their levels images."""
        firsts = list(self.tiles.values()) or [self.step_map]
        images = [f for p in firsts for f in (p, *([second_path(p)] if self.settings.cones == "quadrant" else []))]
        return images + ([levels_path(p) for p in images] if self.settings.levels != "none" else [])

    max_ratio = property(lambda self: self.settings.max_ratio)
    tile = property(lambda self: self.settings.tile)
    bits = property(lambda self: self.settings.bits)
    height_scale = property(lambda self: self.settings.height_scale)
    height_offset = property(lambda self: self.settings.height_offset)
    min_step = property(lambda self: self.picked_min_step or self.settings.min_step,
                        doc="the minimum step in texels: the picked one, else the map's (_exact's)")


@dataclass
class Material:
    name: str
    height: HeightInput | None = None
    csm: CsmSettings | None = None
    ref: Any = None


@dataclass
class Mesh:
    """One triangle mesh (a glTF primitive, an OBJ material group, a USD mesh).

    positions/normals: float64 ``(V, 3)``; uvs: float64 ``(V, 2)`` in the format's own
    convention (``uv_origin`` says which); faces: int64 ``(F, 3)``; tangents: float64
    ``(V, 4)`` (w = handedness) or None; corner_tangents: ``(F, 3, 4)`` once generated.
    """

    name: str
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    tangents: np.ndarray | None = None
    material: Material | None = None
    uv_origin: str = "top-left"
    corner_tangents: np.ndarray | None = None
    ref: Any = None


@dataclass
class Scene:
    """A scene as read. ``inputs`` lists every file reading and writing it used (the scene,
    buffers, material libraries, textures), for staleness checks."""

    path: Path
    format: str
    meshes: list[Mesh] = field(default_factory=list)
    materials: list[Material] = field(default_factory=list)
    source: Any = None
    warnings: list[Notice] = field(default_factory=list)  # see Scene.warn
    inputs: list[Path] = field(default_factory=list)
    # files the scene names that do not exist (a texture, a library): the manifest records them, so that
    # their appearing makes the outputs stale
    absent: list[Path] = field(default_factory=list)
    # missing height textures a CSM101 already named: the writers' CSM404 leaves them out (one line a file)
    said_missing: set[Path] = field(default_factory=set)
    # file names the writers must not take in the output folder (the manifest's, the
    # scene's own); writers add their own library names
    reserved: set[str] = field(default_factory=set)
    # name -> file that other scenes own in the output folder: a writer takes such a name only
    # for the same bytes (see csm_assets.convert.output_folder.free_name)
    others: dict[str, Path] = field(default_factory=dict)
    # textures the writers name where they are instead of copying (csm_assets.convert.links.Links), or None
    links: Any = None
    # the folder the outputs are published in (writers write into a staging folder): a missing
    # file the scene names is named relative to it (csm_assets.convert.links.missing); None: where written
    published: Path | None = None

    def warn(self, code: str, text: str, about: str | None = None) -> None:
        """Record a warning of ``code`` (:data:`csm_assets.warning_codes.RULES`) about this scene,
        and the mesh or material ``about`` (when given); the same text of one code is said once,
        with a count (:func:`csm_assets.warning_codes.add`)."""
        add(self.warnings, Notice(code, str(self.path), text, (about,) if about else ()))

    def drop_undrawn(self, tried: list[tuple[Material, str]]) -> None:
        """Readers' last step: each material of ``tried`` (material, the uvs it needs), which
        had a mesh that could not carry the relief, and that no mesh in ``meshes`` carries,
        gets no CSM material (height None), with one warning; as OBJ does for faces without uvs."""
        keep = {id(m.material) for m in self.meshes}
        for mat, uvs in tried:
            if mat.height is not None and id(mat) not in keep:
                self.warn("CSM203", f"none of its meshes has triangles with positions and {uvs}, "
                          "so no CSM material (the relief needs texture coordinates)", f"material {mat.name!r}")
                mat.height = None


def resolve_reference(scene_path, base_dir, ref: str, *, allow_outside: bool = False, root=None) -> Path:
    """The file a scene's relative reference ``ref`` names, from ``base_dir``.

    Absolute paths, URLs and UNC paths (:mod:`csm_assets.references`' rule), and (unless
    ``allow_outside``) references that lead out of the project root ``root`` (default: the
    scene's own folder; ``../../etc/passwd``, or a link pointing away), raise FormatError
    naming the scene: a converted scene must not pull in arbitrary files.
    """
    references.check(scene_path, ref)
    full = Path(base_dir) / ref.replace("\\", "/")
    references.refuse_outside(scene_path, ref, full,
                              references.reach(scene_path, allow_outside=allow_outside, root=root))
    return full
