"""Scene conversion: a chain of small steps over the scene model.

read -> step maps (one per distinct height texture) -> tangents (only meshes whose
material got a step map) -> write. A material without a height texture costs nothing.
"""

from __future__ import annotations

import importlib
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import FormatError, OutputError
from .formats import load_heightfield, write_step_map
from .packing import step_map
from .scene import CsmSettings, HeightInput, Material, Scene

# extension -> scene format module in csm_assets.formats
SCENE_FORMATS = {".gltf": "gltf", ".glb": "gltf", ".obj": "obj", ".usda": "usd", ".usdc": "usd",
                 ".usdz": "usd", ".usd": "usd"}
DEFAULT_DEPTH = 0.1  # texture-space depth when the file gives no displacement factor


@dataclass
class ConvertOptions:
    """Settings of one conversion (the CLI's flags).

    depth: texture-space depth (uv units per unit of height) for every material,
        instead of the one derived from the file's displacement factor.
    bits: 8 or 16 (PNG step maps).
    """

    heights: dict = field(default_factory=dict)
    max_ratio: float = 1.0
    bits: int = 8
    tile: bool | None = None
    depth: float | None = None
    regenerate_tangents: bool = False
    variant: str = "exact"
    steps: int = 0


@dataclass
class ConvertReport:
    """What a conversion did: files written, step maps made, warnings, seconds."""

    input: Path
    written: list[Path] = field(default_factory=list)
    step_maps: dict[str, Path] = field(default_factory=dict)
    tangent_meshes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0


def scene_module(path):
    ext = Path(path).suffix.lower()
    if ext not in SCENE_FORMATS:
        raise FormatError(path, f"unknown scene format {ext or '(no extension)'!r}; known: "
                                f"{' '.join(sorted(SCENE_FORMATS))}")
    return importlib.import_module(f".formats.{SCENE_FORMATS[ext]}", __package__)


def convert(in_path, out_dir, options: ConvertOptions | None = None, **kwargs) -> ConvertReport:
    """Convert the scene at ``in_path`` into ``out_dir`` (created if missing).

    Options come as a :class:`ConvertOptions` or as its fields by keyword. Raises
    FormatError for an unreadable scene and OutputError when ``out_dir`` is the input's
    folder (the input would be overwritten) or cannot be written.
    """
    opts = options or ConvertOptions(**kwargs)
    start = time.perf_counter()
    in_path, out_dir = Path(in_path), Path(out_dir)
    module = scene_module(in_path)
    if out_dir.resolve() == in_path.parent.resolve():
        raise OutputError(out_dir, "is the input's folder: the converted scene would overwrite "
                                   f"{in_path.name}; choose another output folder")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(out_dir, f"cannot create the output folder: {e.strerror or e}") from e
    scene = module.read(in_path, heights=opts.heights)
    report = ConvertReport(in_path)
    report.step_maps = make_step_maps(scene, out_dir, opts)
    if module.STORES_TANGENTS:
        report.tangent_meshes = make_tangents(scene, opts)
    report.written = [*report.step_maps.values(), *module.write(scene, out_dir)]
    report.warnings = list(scene.warnings)
    report.seconds = time.perf_counter() - start
    return report


def make_step_maps(scene: Scene, out_dir: Path, opts: ConvertOptions) -> dict[str, Path]:
    """One packed map per distinct (texture content, channel, invert, tiling) into
    ``out_dir``, named after the texture; sets ``material.csm``. Returns name -> path."""
    made: dict[tuple, Path] = {}
    for mat in scene.materials:
        h = mat.height
        if h is None:
            continue
        tile = _tile(h, opts)
        key = (h.texture.content_hash(), str(h.channel), h.invert, tile)
        if key not in made:
            try:
                made[key] = _write_step_map(h, tile, out_dir, set(p.name for p in made.values()), opts)
            except FormatError as e:
                scene.warn(f"material {mat.name!r}: {e}; left without CSM")
                mat.height = None
                continue
        mat.csm = CsmSettings(made[key], depth_scale=_depth(scene, mat, opts), max_ratio=opts.max_ratio,
                              tile=tile, variant=opts.variant, steps=opts.steps, bits=opts.bits)
    return {p.stem: p for p in made.values()}


def _tile(h: HeightInput, opts: ConvertOptions) -> tuple[bool, bool]:
    if opts.tile is not None:
        return opts.tile, opts.tile
    return h.tile if h.tile is not None else (True, True)


def _write_step_map(h: HeightInput, tile, out_dir: Path, taken: set[str], opts) -> Path:
    if h.texture.path is not None:
        hf = load_heightfield(h.texture.path, channel=h.channel, invert=h.invert)
    else:  # embedded image: the readers want a file
        with tempfile.TemporaryDirectory() as tmp:
            file = Path(tmp) / f"{h.texture.name}{h.texture.suffix}"
            file.write_bytes(h.texture.data)
            hf = load_heightfield(file, channel=h.channel, invert=h.invert)
    stem, n = f"{h.texture.name}_csm", 1
    while f"{stem}.png" in taken:
        stem, n = f"{h.texture.name}_csm_{n}", n + 1
    path = out_dir / f"{stem}.png"
    packed = step_map(hf.exact_heights(), tile=tile, max_ratio=opts.max_ratio, bits=opts.bits)
    write_step_map(packed, path, {"max_ratio": opts.max_ratio, "tile": list(tile), "bits": opts.bits,
                                  "source": h.texture.name})
    return path


def _depth(scene: Scene, mat: Material, opts: ConvertOptions) -> float:
    """Texture-space depth: the displacement factor over the world size of one uv unit
    (the square root of world area over uv area of the material's triangles)."""
    if opts.depth is not None:
        return opts.depth
    if mat.height.origin == "command line":
        return DEFAULT_DEPTH
    world = uv = 0.0
    for mesh in scene.meshes:
        if mesh.material is mat:
            p, t = mesh.positions[mesh.faces], mesh.uvs[mesh.faces]
            world += np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum() / 2
            e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
            uv += np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2
    if world <= 0 or uv <= 0:
        return abs(mat.height.scale)
    return abs(mat.height.scale) / float(np.sqrt(world / uv))


def make_tangents(scene: Scene, opts: ConvertOptions) -> list[str]:
    """MikkTSpace tangents for meshes whose material got a step map and that have none
    (or all, with ``regenerate_tangents``). Returns the names of the meshes done."""
    from .tangents import mikktspace_tangents

    done = []
    for mesh in scene.meshes:
        if mesh.material is None or mesh.material.csm is None:
            continue
        if mesh.tangents is not None and not opts.regenerate_tangents:
            continue
        if mesh.normals is None:
            scene.warn(f"mesh {mesh.name}: no normals, so no tangents (viewers ignore tangents "
                       f"without normals); add normals to it")
            continue
        mesh.corner_tangents = mikktspace_tangents(mesh.positions, mesh.normals, mesh.uvs, mesh.faces,
                                                   flip_v=mesh.uv_origin == "top-left")
        done.append(mesh.name)
    return done
