"""Scene conversion: a chain of small steps over the scene model.

read -> step maps (one per distinct height texture) -> tangents (only meshes whose
material got a step map) -> write. A material without a height texture costs nothing.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import height_source, manifest
from . import output_folder as folder
from .atomic import atomic_path
from .errors import FormatError, OptionError, OutputError, StrictError
from .formats import load_heightfield
from .pick_scene import pick
from .scene import CsmSettings, HeightInput, Material, Scene
from .stepmap import DEFAULTS, StepMap, StepMapSettings, load_step_map, make_step_map, save_step_map

# extension -> scene format module in csm_assets.formats
SCENE_FORMATS = {".gltf": "gltf", ".glb": "gltf", ".obj": "obj", ".usda": "usd", ".usdc": "usd",
                 ".usdz": "usd", ".usd": "usd"}
DEFAULT_DEPTH = height_source.DEFAULT_DEPTH  # texture-space depth when nothing states a factor


@dataclass
class ConvertOptions:
    """Settings of one conversion (the CLI's flags).

    heights: material name -> height texture (a path or a
        :class:`~csm_assets.height_source.HeightSpec`, which can say it is a depth map).
    depth: texture-space depth (uv units per unit of height) for every material,
        instead of the one derived from the file's displacement factor.
    depths: material name -> texture-space depth of that material (before ``depth``).
    bits: 8 or 16 (PNG step maps), or 32 (float EXR, for OBJ and USD scenes).
    variant, steps: the shader variant and its step count written into each material.
    max_error: a budget in texels (p95 at every view): each material gets the cheapest
        (variant, steps) of :data:`csm_assets.trade.DEFAULT_CONFIGS` that meets it on its
        own step map and depth, measured by :func:`csm_assets.trade.pick_settings`. Then
        ``variant`` "auto" (or None) picks among all variants, another name only among
        its step counts, and ``steps`` > 0 only among that step count; a variant and
        steps both given are taken as they are.
    """

    heights: dict = field(default_factory=dict)
    depths: dict = field(default_factory=dict)
    max_ratio: float = DEFAULTS.max_ratio
    bits: int = DEFAULTS.bits
    tile: bool | None = None
    depth: float | None = None
    regenerate_tangents: bool = False
    variant: str = "exact"
    steps: int = 0
    max_error: float | None = None
    allow_outside: bool = False
    bilinear_safe: bool = DEFAULTS.bilinear_safe  # G = 3x3 minimum, and _exact's minimum step 0.25 texel
    force: bool = False              # convert even when the manifest says the outputs are fresh
    cache_dir: Path | None = None    # step maps shared by content hash across conversions
    strict: bool = False             # warnings are errors: StrictError, nothing published

    def settings(self) -> dict:
        """What decides the outputs (for the manifest): every field but force, cache_dir, strict."""
        d = dataclasses.asdict(self)
        for k in ("force", "cache_dir", "strict"):
            d.pop(k)
        d["heights"] = {k: str(v) for k, v in sorted(self.heights.items())}
        return json.loads(json.dumps(d))


@dataclass
class ConvertReport:
    """What a conversion did: files written, step maps made, warnings, seconds."""

    input: Path
    skipped: str | None = None  # why nothing was done (outputs fresh), else None
    written: list[Path] = field(default_factory=list)
    step_maps: dict[str, Path] = field(default_factory=dict)
    tangent_meshes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    picks: dict = field(default_factory=dict)  # material -> {"variant", "steps"} written
    seconds: float = 0.0

    @property
    def unchanged(self) -> bool:
        """Converted, but no material had a height texture: the scene was copied as it was."""
        return self.skipped is None and not self.step_maps


def scene_module(path):
    ext = Path(path).suffix.lower()
    if ext not in SCENE_FORMATS:
        raise FormatError(path, f"unknown scene format {ext or '(no extension)'!r}; known: "
                                f"{' '.join(sorted(SCENE_FORMATS))}")
    return importlib.import_module(f".formats.{SCENE_FORMATS[ext]}", __package__)


def convert(in_path, out_dir, options: ConvertOptions | None = None, **kwargs) -> ConvertReport:
    """Convert the scene at ``in_path`` into ``out_dir`` (created if missing).

    Options come as a :class:`ConvertOptions` or as its fields by keyword. Outputs whose
    manifest shows them fresh are left alone (``report.skipped`` says why) unless
    ``force``. Everything is made in a staging folder inside ``out_dir`` and moved into
    place only when all of it succeeded, manifest last: a failure leaves no partial
    outputs, an interruption leaves each file old and intact or new and complete.
    Several scenes may be converted into one folder: each takes names no other scene's
    entry in the manifest holds (see :mod:`csm_assets.output_folder`).
    Raises FormatError for an unreadable scene (:class:`~csm_assets.errors.StrictError`
    for warnings under ``strict``) and OutputError when an output would overwrite an
    input or another scene's output, or cannot be written.
    """
    opts = options or ConvertOptions(**kwargs)
    start = time.perf_counter()
    in_path, out_dir = Path(in_path), Path(out_dir)
    module = scene_module(in_path)
    if out_dir.resolve() == in_path.parent.resolve():
        raise OutputError(out_dir, "is the input's folder: the converted scene would overwrite "
                                   f"{in_path.name}; choose another output folder")
    if opts.bits not in module.STEP_MAP_BITS:
        raise OptionError(f"{in_path}: {in_path.suffix} scenes take {' or '.join(map(str, module.STEP_MAP_BITS))}"
                         f"-bit step maps, not {opts.bits}-bit (glTF images are PNG)")
    report = ConvertReport(in_path)
    with folder.locked(out_dir):
        folder.clean_dead_stages(out_dir)
        known = manifest.load(out_dir)
        mine = known["scenes"].get(in_path.name)
        if mine is not None and mine.get("source", manifest.source_key(in_path, out_dir)) != \
                manifest.source_key(in_path, out_dir):
            raise OutputError(out_dir / in_path.name, f"is the output of another scene ({mine['source']}); "
                                                      "convert this one into another folder")
        if not opts.force and in_path.is_file():
            if manifest.staleness(in_path, out_dir, opts.settings(), known) is None:
                report.skipped = "outputs are fresh"
                report.warnings = list(mine.get("warnings", []))
                report.picks = dict(mine.get("picks", {}))
                if opts.strict and report.warnings:
                    raise StrictError(in_path, report.warnings)
                report.seconds = time.perf_counter() - start
                return report
        scene = module.read(in_path, heights=opts.heights, allow_outside=opts.allow_outside)
        height_source.check_names(scene, [*opts.heights, *opts.depths])
        others = manifest.owned_by_others(known, in_path.name)
        scene.reserved = {manifest.NAME, in_path.name}
        with folder.staging(out_dir) as stage:
            report.step_maps = make_step_maps(scene, stage, opts, out_dir, others)
            if module.STORES_TANGENTS:
                report.tangent_meshes = make_tangents(scene, opts)
            if opts.max_error is not None:
                report.step_maps.update({p.stem: p for p in _confirm_picks(scene, stage, opts, module)})
            embedded = getattr(module, "embeds_step_maps", lambda _: False)(scene)  # a GLB holds its own
            scene_files = module.write(scene, stage)
            staged = [*([] if embedded else report.step_maps.values()), *scene_files]
            if opts.strict and scene.warnings:
                raise StrictError(in_path, scene.warnings)
            names = [p.name for p in staged]
            inputs = [in_path, *scene.inputs]
            folder.check_names(stage, names, out_dir, inputs, others)
            report.picks = {m.name: {"variant": m.csm.variant, "steps": m.csm.steps, "bits": m.csm.bits}
                            for m in scene.materials if m.csm is not None}
            known["scenes"][in_path.name] = manifest.entry(in_path, out_dir, scene.inputs, staged,
                                                           opts.settings(), report.picks, scene.warnings)
            with atomic_path(stage / manifest.NAME) as tmp:
                manifest.write(tmp, known)
            report.written = folder.publish(stage, names + [manifest.NAME], out_dir)
        folder.remove_orphans(out_dir, set(mine["outputs"]) if mine else set(), set(names), set(others), inputs)
    report.step_maps = {k: out_dir / (scene_files[0] if embedded else v).name for k, v in report.step_maps.items()}
    report.warnings = list(scene.warnings)
    report.seconds = time.perf_counter() - start
    return report


def make_step_maps(scene: Scene, out_dir: Path, opts: ConvertOptions, published: Path | None = None,
                   others: dict | None = None) -> dict[str, Path]:
    """One packed map per distinct (texture content, channel, invert, tiling) into
    ``out_dir``, named after the texture; sets ``material.csm``. Returns name -> path.

    published, others: the folder the maps will be moved to and the names other scenes
    own there; a map takes such a name only when its bytes are the same (``_1``, ``_2``...
    otherwise), so two textures of one name never share a map."""
    made: dict[tuple, tuple[Path, StepMap]] = {}
    picks: dict[tuple, tuple[str, int]] = {}
    verdicts: dict = {}
    for mat in scene.materials:
        h = mat.height
        if h is None:
            continue
        if not height_source.screen(scene, mat, verdicts):
            mat.height = None
            continue
        tile = _tile(h, opts)
        key = (h.texture.content_hash(), str(h.channel), h.invert, tile)
        if key not in made:
            if h.texture.path is not None and h.texture.path not in scene.inputs:
                scene.inputs.append(h.texture.path)
            try:
                taken = {p.name for p, _ in made.values()} | scene.reserved
                path, sm = _write_step_map(h, tile, out_dir, taken, opts, key)
                made[key] = _settle(path, taken, others or {}, published), sm
            except FormatError as e:
                scene.warn(f"material {mat.name!r}: {e}; left without CSM")
                mat.height = None
                continue
        path, sm = made[key]
        depth = _depth(scene, mat, opts)
        if (key, depth) not in picks:
            picks[key, depth] = pick(sm, path.name, depth, opts)
        variant, steps = picks[key, depth]
        mat.csm = CsmSettings.of(path, sm, depth, variant, steps)
    return {p.stem: p for p, _ in made.values()}


def _confirm_picks(scene: Scene, stage: Path, opts: ConvertOptions, module) -> list[Path]:
    """Picks confirmed on the scene at verify's views (:mod:`csm_assets.pick_scene`); 8-bit maps
    that cannot meet the budget are made again at 16 bits. Returns the new step maps."""
    from .pick_scene import confirm_picks, pick_configs

    def remake(mat, bits):
        h = mat.height
        key = (h.texture.content_hash(), str(h.channel), h.invert, tuple(mat.csm.tile), bits)
        taken = {p.name for p in stage.iterdir()}
        path, mat.csm.map = _write_step_map(h, tuple(mat.csm.tile), stage, taken,
                                            dataclasses.replace(opts, bits=bits), key)
        return path

    return confirm_picks(scene, opts, lambda mat: pick_configs(opts), remake if 16 in module.STEP_MAP_BITS else None,
                         generate_tangents=not module.STORES_TANGENTS)


def _tile(h: HeightInput, opts: ConvertOptions) -> tuple[bool, bool]:
    if opts.tile is not None:
        return opts.tile, opts.tile
    return h.tile if h.tile is not None else (True, True)


def _settle(path: Path, taken: set[str], others: dict, published: Path | None) -> Path:
    """``path`` renamed, if need be, so that it takes no name of ``taken`` and no file another
    scene owns in ``published`` unless that file has the same bytes."""
    from .manifest import file_hash

    def clash(name: str) -> bool:
        if name in taken:
            return True
        theirs = published / name if published is not None else None
        return name in others and theirs is not None and theirs.is_file() and \
            file_hash(theirs) != file_hash(path)

    name, n = path.name, 1
    while clash(name):
        name, n = f"{path.stem}_{n}{path.suffix}", n + 1
    if name != path.name:
        path = path.rename(path.with_name(name))
    return path


def _write_step_map(h: HeightInput, tile, out_dir: Path, taken: set[str], opts, key) -> tuple[Path, StepMap]:
    """The step map of ``h``, written into ``out_dir`` under a free name: (path, map)."""
    ext = ".exr" if opts.bits == 32 else ".png"
    stem, n = f"{h.texture.name}_csm", 1
    while f"{stem}{ext}" in taken:
        stem, n = f"{h.texture.name}_csm_{n}", n + 1
    path = out_dir / f"{stem}{ext}"
    cached = None
    if opts.cache_dir is not None:
        digest = hashlib.sha256(repr((key, opts.max_ratio, opts.bits)).encode()).hexdigest()
        cached = Path(opts.cache_dir) / f"{digest}{ext}"
        if cached.is_file():
            shutil.copyfile(cached, path)
            return path, load_step_map(path)
    settings = StepMapSettings(max_ratio=opts.max_ratio, tile=tile, bits=opts.bits,
                               bilinear_safe=opts.bilinear_safe, source=h.texture.name)
    with h.texture.as_file() as file:
        sm = make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings)
    save_step_map(sm, path)
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(cached) as tmp:
            shutil.copyfile(path, tmp)
    return path, sm


def _depth(scene: Scene, mat: Material, opts: ConvertOptions) -> float:
    """Texture-space depth: the displacement factor over the world size of one uv unit
    (the square root of world area over uv area of the material's triangles)."""
    for key in (mat.name, mat.ref):
        if isinstance(key, str) and key in opts.depths:
            return float(opts.depths[key])
    if opts.depth is not None:
        return opts.depth
    if mat.height.depth is not None:
        return mat.height.depth
    world = uv = 0.0
    for mesh in scene.meshes:
        if mesh.material is mat:
            w, u = triangle_areas(mesh)
            world += w.sum()
            uv += u.sum()
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
        for problem in mesh_problems(mesh):
            scene.warn(f"mesh {mesh.name} (material {mesh.material.name!r}): {problem}")
        mesh.corner_tangents = mikktspace_tangents(mesh.positions, mesh.normals, mesh.uvs, mesh.faces,
                                                   flip_v=mesh.uv_origin == "top-left")
        done.append(mesh.name)
    return done


def mesh_problems(mesh) -> list[str]:
    """What in a mesh makes tangents doubtful: degenerate triangles (no area, or no uv
    area: MikkTSpace borrows their frames) and edges shared by more than two triangles."""
    area, uv_area = triangle_areas(mesh)
    problems = []
    if (area == 0).any() or (uv_area == 0).any():
        problems.append(f"{int((area == 0).sum())} triangle(s) without area and {int((uv_area == 0).sum())} "
                        "without uv area; their tangents are borrowed from neighbours")
    edges = np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if (counts > 2).any():
        problems.append(f"{int((counts > 2).sum())} non-manifold edge(s) (shared by more than two triangles)")
    return problems


def triangle_areas(mesh) -> tuple[np.ndarray, np.ndarray]:
    """World and uv areas of a mesh's triangles, float64 ``(F,)`` each."""
    p, t = mesh.positions[mesh.faces], mesh.uvs[mesh.faces]
    world = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) / 2
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return world, np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2
