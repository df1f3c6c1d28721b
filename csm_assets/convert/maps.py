"""The step maps of a scene being converted: one per distinct height texture, named in
the staging folder, cached by content, each material's depth and shader pick set.

:func:`make_step_maps` is ``convert``'s step from heights to ``material.csm``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
from pathlib import Path

import numpy as np

from .. import height_source
from ..atomic import atomic_path
from ..errors import FormatError
from ..formats import load_heightfield
from ..scene import CsmSettings, HeightInput, Material, Scene
from ..stepmap import StepMap, StepMapSettings, load_step_map, make_step_map, save_step_map
from ..tangents.mesh_checks import triangle_areas
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


def make_step_maps(scene: Scene, out_dir: Path, opts) -> dict[str, Path]:
    """One packed map per distinct (texture content, channel, invert, tiling) into
    ``out_dir`` (the staging folder), named after the texture; sets ``material.csm``.
    Returns name -> path. opts: the :class:`~csm_assets.convert.pipeline.ConvertOptions`.
    The heights were screened first (:func:`screen_heights`).

    A map takes a name another scene owns in the output folder (``scene.others``) only when
    its bytes are the same (``_1``, ``_2``... otherwise), so two textures of one name never
    share a map."""
    made: dict[tuple, tuple[Path, StepMap]] = {}
    picks: dict[tuple, tuple[str, int]] = {}
    for mat in scene.materials:
        h = mat.height
        if h is None:
            continue
        tile = _tile(h, opts)
        key = (h.texture.content_hash(), str(h.channel), h.invert, tile)
        if key not in made:
            if h.texture.path is not None and h.texture.path not in scene.inputs:
                scene.inputs.append(h.texture.path)
            try:
                taken = {p.name for p, _ in made.values()} | scene.reserved
                path, sm = _write_step_map(h, tile, out_dir, taken, opts, key)
                made[key] = folder.settle(path, taken, scene.others), sm
            except FormatError as e:
                if h.origin == "command line":  # the user named this file: it must be readable
                    raise
                scene.warn(f"material {mat.name!r}: {e}; left without CSM")
                mat.height = None
                continue
        path, sm = made[key]
        depth = _depth(scene, mat, opts)
        if (key, depth) not in picks:
            picks[key, depth] = pick(sm, path.name, depth, opts)
        variant, steps = picks[key, depth]
        mat.csm = CsmSettings.of(path, sm, depth, variant, steps, self_shadow=opts.self_shadow,
                                 light_size=opts.light_size)
    return {p.stem: p for p, _ in made.values()}


def confirm_scene_picks(scene: Scene, stage: Path, opts, module) -> list[Path]:
    """Picks confirmed on the scene at verify's views (:mod:`csm_assets.convert.pick`); 8-bit maps
    that cannot meet the budget are made again at 16 bits. Returns the new step maps."""
    from .pick import confirm_picks, pick_configs

    def remake(mat, bits):
        h = mat.height
        key = (h.texture.content_hash(), str(h.channel), h.invert, tuple(mat.csm.tile), bits)
        taken = {p.name for p in stage.iterdir()}
        path, sm = _write_step_map(h, tuple(mat.csm.tile), stage, taken, dataclasses.replace(opts, bits=bits), key)
        mat.csm.use_map(folder.settle(path, taken, scene.others), sm)
        return mat.csm.step_map

    return confirm_picks(scene, opts, lambda mat: pick_configs(opts), remake if 16 in module.STEP_MAP_BITS else None,
                         generate_tangents=not module.STORES_TANGENTS)


def _tile(h: HeightInput, opts) -> tuple[bool, bool]:
    if opts.tile is not None:
        return opts.tile, opts.tile
    return h.tile if h.tile is not None else (True, True)


def _write_step_map(h: HeightInput, tile, out_dir: Path, taken: set[str], opts, key) -> tuple[Path, StepMap]:
    """The step map of ``h``, written into ``out_dir`` under a free name: (path, map)."""
    ext = ".exr" if opts.bits == 32 else ".png"
    path = out_dir / folder.free_name(f"{h.texture.name}_csm", ext, taken)
    settings = StepMapSettings(max_ratio=opts.max_ratio, tile=tile, bits=opts.bits,
                               bilinear_safe=opts.bilinear_safe, cones=opts.cones, source=h.texture.name)
    cached = None
    if opts.cache_dir is not None:  # keyed by the heights and every setting the map is made with
        digest = hashlib.sha256(repr((key, settings)).encode()).hexdigest()
        cached = Path(opts.cache_dir) / f"{digest}{ext}"
        if cached.is_file():
            shutil.copyfile(cached, path)
            return path, load_step_map(path)
    with h.texture.as_file() as file:
        sm = make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings)
    save_step_map(sm, path)
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(cached) as tmp:
            shutil.copyfile(path, tmp)
    return path, sm


def _depth(scene: Scene, mat: Material, opts) -> float:
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


