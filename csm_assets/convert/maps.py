"""The step maps of a scene being converted: one per distinct height texture, named in
the staging folder, cached by content, each material's depth and shader pick set.

:func:`make_step_maps` is ``convert``'s step from heights to ``material.csm``.
"""

from __future__ import annotations

import dataclasses
import filecmp
import hashlib
import json
import math
import shutil
from pathlib import Path

from .. import height_source
from ..atomic import atomic_path
from ..depth import check_depth, texture_depth
from ..errors import FormatError, OptionError
from ..formats import load_heightfield
from ..scene import CsmSettings, HeightInput, Material, Scene
from ..stepmap import (DEFAULTS, StepMap, StepMapSettings, levels_path, load_step_map, make_step_map,
                       save_step_map, second_path)
from ..verify.bits import BitsChoice, chooser
from ..warning_codes import python_warnings
from . import output_folder as folder
from .pick import pick


def screen_heights(scene: Scene) -> bool:
    """Drop the height textures that hold no heights (normal maps, with a warning each:
    :func:`csm_assets.height_source.screen`); whether any material still has relief."""
    verdicts: dict = {}
    for mat in scene.materials:
        if mat.height is not None and not height_source.screen(scene, mat, verdicts):
            mat.height = None
    return any(mat.height is not None for mat in scene.materials)


def make_step_maps(scene: Scene, out_dir: Path, opts, allowed_bits=(8, 16), progress=None,
                   executor=None) -> dict[str, Path]:
    """One packed map per distinct (texture content, channel, invert, tiling) into
    ``out_dir`` (the staging folder), named after the texture; sets ``material.csm``.
    Returns name -> path. opts: the :class:`~csm_assets.convert.pipeline.ConvertOptions`.
    allowed_bits: the step map bits the scene's format holds, among which ``opts.bits`` None
    chooses (:func:`csm_assets.verify.bits.choose_bits` at the deepest depth of the materials
    sharing the map and verify's views). ``progress(stage, done, total)``: "step maps" by rows,
    then "pick" by material (with ``max_error``). ``executor`` (a Dask cluster's): each map's cones
    are searched there in bands of rows (:mod:`csm_assets.cones.remote`), the same bytes.
    The heights were screened first (:func:`screen_heights`).

    A map takes a name another scene owns in the output folder (``scene.others``) only when
    its bytes are the same (``_1``, ``_2``... otherwise; a map with levels or quadrant cones only
    when every one of its files is), so two textures of one name never share a map."""
    made: dict[tuple, tuple[Path, StepMap]] = {}
    picks: dict[tuple, tuple[str, int]] = {}
    todo = []
    for mat in scene.materials:
        h = mat.height
        if h is None or h.udim is not None:  # a UDIM set: csm_assets.convert.udim makes its maps
            continue
        tile = resolve_tile(h.tile, opts)
        todo.append((mat, (h.texture.content_hash(), str(h.channel), h.invert, tile), material_depth(scene, mat, opts)))
    deepest: dict[tuple, float] = {}
    for _, key, depth in todo:
        deepest[key] = max(depth, deepest.get(key, 0.0))
    for mat, key, depth in todo:
        h = mat.height
        if key not in made:
            if h.texture.path is not None and h.texture.path not in scene.inputs:
                scene.inputs.append(h.texture.path)
            taken = {n for p, _ in made.values() for n in map_names(p, opts)} | scene.reserved
            rows = (lambda done, total: progress("step maps", done, total)) if progress else None
            found = made_or_dropped(scene, mat, lambda: _write_step_map(
                h, key[3], out_dir, taken, opts, key, rows, bits_for=(deepest[key], tuple(allowed_bits)),
                others=scene.others, executor=executor))
            if found is None:
                continue
            made[key] = _settle(found[0], taken, scene.others, opts), found[1]
        path, sm = made[key]
        check_material_depth(scene, mat, opts, depth, sm.pixels.shape)  # before anything is traced or drawn
        if (key, depth) not in picks:
            if progress and opts.max_error is not None:
                progress("pick", len(picks), len(scene.materials))
            picks[key, depth] = pick(sm, path.name, depth, opts)
        variant, steps, min_step = picks[key, depth]
        mat.csm = CsmSettings.of(path, sm, depth, variant, steps, self_shadow=opts.self_shadow,
                                 light_size=opts.light_size, picked_min_step=min_step)
    return {p.stem: p for p, _ in made.values()}


def made_or_dropped(scene: Scene, mat: Material, make):
    """``make()``, which returns ``(..., StepMap)``, with Python's warnings as the scene's (cones
    narrower than one stored step: CSM301) and the map's bits warning said (CSM304); None, with a
    CSM102 warning and the material left without height, when its texture cannot be read. A texture
    the command line named must be readable: its FormatError is raised."""
    try:
        with python_warnings(scene):
            found = make()
    except FormatError as e:
        if mat.height.origin == "command line":
            raise
        scene.warn("CSM102", f"{e}; left without CSM", f"material {mat.name!r}")
        mat.height = None
        return None
    if found[-1].choice is not None and found[-1].choice.warning:
        scene.warn("CSM304", found[-1].choice.warning, f"material {mat.name!r}")
    return found


def confirm_scene_picks(scene: Scene, stage: Path, opts, module, progress=None) -> list[Path]:
    """Picks confirmed on the scene at verify's views (:mod:`csm_assets.convert.pick`); 8-bit maps
    that cannot meet the budget are made again at 16 bits. Returns the new step maps.
    ``progress("confirm", done, total)`` by material."""
    from .pick import confirm_picks, pick_configs

    def remake(mat, bits):
        h = mat.height
        key = (h.texture.content_hash(), str(h.channel), h.invert, tuple(mat.csm.tile), bits)
        taken = {p.name for p in stage.iterdir()}
        with python_warnings(scene):
            path, sm = _write_step_map(h, tuple(mat.csm.tile), stage, taken, dataclasses.replace(opts, bits=bits),
                                       key, others=scene.others)
        mat.csm.use_map(_settle(path, taken, scene.others, opts), sm)
        return mat.csm.step_map

    return confirm_picks(scene, opts, lambda mat: pick_configs(opts), remake if 16 in module.STEP_MAP_BITS else None,
                         generate_tangents=not module.STORES_TANGENTS, progress=progress)


def resolve_tile(texture_tile, opts) -> tuple[bool, bool]:
    """Whether the cones wrap along (u, v): ``opts.tile`` (``--tile``/``--no-tile``) when set,
    else the texture's own wrap modes ``texture_tile`` (None: both repeat)."""
    if opts.tile is not None:
        return opts.tile, opts.tile
    return tuple(texture_tile) if texture_tile is not None else (True, True)


def step_map_settings(opts, tile, source: str) -> StepMapSettings:
    """The :class:`~csm_assets.stepmap.StepMapSettings` convert makes a map with: ``opts``'
    max ratio, bits (the default when ``opts.bits`` is None: convert then chooses them), bilinear
    safety and cones, the resolved ``tile``, the texture's name."""
    return StepMapSettings(max_ratio=opts.max_ratio, tile=tile, bits=opts.bits or DEFAULTS.bits,
                           bilinear_safe=opts.bilinear_safe, cones=opts.cones, source=source, levels=opts.levels)


def map_names(path: Path, opts, folder: Path | None = None) -> list[str]:
    """The file names a step map written at ``path`` takes: its own, with quadrant cones
    (``opts.cones``) its second image's (:func:`~csm_assets.stepmap.second_path`), and with
    ``opts.levels`` each image's levels (:func:`~csm_assets.stepmap.levels_path`; with ``folder``
    only those in it: a 1x1 map has none)."""
    images = [path, *([second_path(path)] if opts.cones == "quadrant" else [])]
    levels = [levels_path(p) for p in images] if opts.levels != "none" else []
    return [p.name for p in images] + [p.name for p in levels if folder is None or (folder / p.name).is_file()]


def _names_inside(opts) -> bool:
    """Whether a map names other files inside it (a quadrant map its second image, a map with
    levels its levels images): such a map is never renamed once written."""
    return opts.cones == "quadrant" or opts.levels != "none"


def _place(sm: StepMap, out_dir: Path, stem: str, suffix: str, taken: set[str], opts, others, copy=None) -> Path:
    """Write ``sm`` into ``out_dir`` (the staging folder) under the first free name ``stem + suffix``,
    ``stem_1 + suffix``... (``copy``: a file of its bytes, copied instead of saved). A plain map's
    name is free of ``taken``; :func:`_settle` renames it afterwards off another scene's file
    (``others``) of other bytes. A map that names its other files (:func:`_names_inside`: a
    quadrant map's second image, levels images) is never renamed once written, so all its files'
    names must be free of ``taken``, and where another scene owns one of them, it is written there
    and kept only when every such file holds the same bytes (scenes share identical maps, as they
    share plain ones), else removed and the next name tried."""
    if not _names_inside(opts):
        path = out_dir / folder.free_name(stem, suffix, taken)
        shutil.copyfile(copy, path) if copy is not None else save_step_map(sm, path)
        return path
    written = []

    def clash(name: str) -> bool:
        files = _files(out_dir / name, sm)
        if any(f.name in taken for f in files):
            return True
        theirs = {f: Path(others[f.name]) for f in files if f.name in (others or {}) and Path(others[f.name]).is_file()}
        if not theirs:
            return False
        save_step_map(sm, out_dir / name)
        if all(filecmp.cmp(f, t, shallow=False) for f, t in theirs.items()):
            written.append(name)
            return False
        for f in files:
            f.unlink(missing_ok=True)
        return True

    path = out_dir / folder.free_name(stem, suffix, clash)
    if not written:
        save_step_map(sm, path)
    return path


def _files(path: Path, sm: StepMap) -> list[Path]:
    """The files ``save_step_map(sm, path)`` writes: the image, a quadrant map's second, their levels."""
    images = [path, *([second_path(path)] if sm.second is not None else [])]
    return images + ([levels_path(p) for p in images] if sm.levels else [])


def _settle(path: Path, taken: set[str], others, opts) -> Path:
    """:func:`~csm_assets.convert.output_folder.settle` for a step map; a map that names its other
    files (:func:`_names_inside`) is left where it is (:func:`_place` chose its name)."""
    return path if _names_inside(opts) else folder.settle(path, taken, others)


def _write_step_map(h: HeightInput, tile, out_dir: Path, taken: set[str], opts, key,
                    rows=None, bits_for=None, others=None, executor=None) -> tuple[Path, StepMap]:
    """The step map of ``h``, written into ``out_dir`` under a free name: (path, map);
    ``rows(done, total)`` hears the cone search's progress.
    bits_for: (depth, allowed bits) to choose its bits by (:func:`csm_assets.verify.bits.chooser`,
    ``opts.bits`` then kept as given), else ``opts.bits`` as they are. others: the files other
    scenes own in the output folder (see :func:`_place`). executor: where the cones are searched
    in bands (None: here)."""
    settings = step_map_settings(opts, tile, h.texture.name)
    choose = None if bits_for is None else chooser(bits_for[0], allowed=bits_for[1], given=opts.bits)
    cached = None
    if opts.cache_dir is not None:  # keyed by the heights and every setting the map is made with
        digest = hashlib.sha256(repr((key, settings, opts.bits, bits_for)).encode()).hexdigest()
        cached = Path(opts.cache_dir) / digest
        found = [p for p in (cached.with_suffix(".png"), cached.with_suffix(".exr")) if p.is_file()
                 and all((p.parent / n).is_file() for n in map_names(p, opts)[1:])]
        if found and cached.with_suffix(".json").is_file():
            sm = load_step_map(found[0])  # a map naming its other files is written again (it names them)
            path = _place(sm, out_dir, f"{h.texture.name}_csm", found[0].suffix, taken, opts, others,
                          copy=None if _names_inside(opts) else found[0])
            why = json.loads(cached.with_suffix(".json").read_text())
            sm.choice = BitsChoice(**why) if why else None
            return path, sm
    with h.texture.as_file() as file:
        sm = make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings, progress=rows, choose=choose,
                           executor=executor)
    path = _place(sm, out_dir, f"{h.texture.name}_csm", ".exr" if sm.settings.bits == 32 else ".png", taken, opts,
                  others)
    if cached is not None and h.texture.content_hash() == key[0]:  # a texture replaced meanwhile: not cached
        cached.parent.mkdir(parents=True, exist_ok=True)
        if _names_inside(opts):  # every image, the first last (it names the others)
            save_step_map(sm, cached.with_suffix(path.suffix))
        else:
            with atomic_path(cached.with_suffix(path.suffix)) as tmp:
                shutil.copyfile(path, tmp)
        with atomic_path(cached.with_suffix(".json")) as tmp:  # the choice: the report says it again
            tmp.write_text(json.dumps(dataclasses.asdict(sm.choice) if sm.choice else {}))
    return path, sm


def material_depth(scene: Scene, mat: Material, opts) -> float:
    """Texture-space depth: the displacement factor over the world size of one uv unit
    (the square root of world area over uv area of the material's triangles). FormatError
    naming the scene and material when that is not a finite number (a huge factor on a tiny
    mesh): no Infinity is ever written."""
    depth = _raw_depth(scene, mat, opts)
    if not math.isfinite(depth):
        raise FormatError(scene.path, f"material {mat.name!r}: its displacement scale {mat.height.scale:g} gives a "
                                      f"texture-space depth of {depth} (the scale over the mesh's size per uv "
                                      "unit), which no material can hold; scale it down or give --depth")
    return depth


def check_material_depth(scene: Scene, mat: Material, opts, depth: float, shape) -> None:
    """Refuse a depth nothing can be measured at on a step map of ``shape``
    (:func:`csm_assets.depth.check_depth`): OptionError (exit 2) naming the option or
    configuration key that gave it, or FormatError naming the scene and the material when its
    displacement factor did (a fix: ``--depth``)."""
    name = _depth_setting(mat, opts)
    if name is not None:
        check_depth(depth, shape, name)
        return
    try:
        check_depth(depth, shape, "its texture-space depth")
    except OptionError as e:
        why = "as the scene states it" if mat.height.depth is not None else \
            f"from its displacement scale {mat.height.scale:g} over the mesh's size per uv unit"
        raise FormatError(scene.path, f"material {mat.name!r}: {e} ({why}); give --depth") from None


def _depth_setting(mat: Material, opts) -> str | None:
    """How a message names the setting ``_raw_depth`` takes ``mat``'s depth from, None for the scene."""
    for key in (mat.name, mat.ref):
        if isinstance(key, str) and key in opts.depths:
            return opts.depth_names.get(key, f"the depth of material {key!r}")
    return opts.depth_names.get("depth", "the depth") if opts.depth is not None else None


def _raw_depth(scene: Scene, mat: Material, opts) -> float:
    for key in (mat.name, mat.ref):
        if isinstance(key, str) and key in opts.depths:
            return float(opts.depths[key])
    if opts.depth is not None:
        return opts.depth
    if mat.height.depth is not None:
        return mat.height.depth
    return texture_depth(mat.height.scale, ((m.positions, m.uvs, m.faces) for m in scene.meshes if m.material is mat))


