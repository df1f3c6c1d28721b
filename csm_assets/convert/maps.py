"""The step maps of a scene being converted: one per distinct height texture, named in
the staging folder, cached by content, each material's depth and shader pick set.

:func:`make_step_maps` is ``convert``'s step from heights to ``material.csm``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from .. import height_source
from ..atomic import atomic_path
from ..errors import FormatError
from ..formats import load_heightfield
from ..scene import CsmSettings, HeightInput, Material, Scene
from ..stepmap import DEFAULTS, StepMap, StepMapSettings, load_step_map, make_step_map, save_step_map
from ..verify.bits import BitsChoice, chooser
from ..tangents.mesh_checks import triangle_areas
from . import output_folder as folder
from .pick import pick


def make_step_maps(scene: Scene, out_dir: Path, opts, allowed_bits=(8, 16)) -> dict[str, Path]:
    """One packed map per distinct (texture content, channel, invert, tiling) into
    ``out_dir`` (the staging folder), named after the texture; sets ``material.csm``.
    Returns name -> path. opts: the :class:`~csm_assets.convert.pipeline.ConvertOptions`.
    allowed_bits: the step map bits the scene's format holds, among which ``opts.bits`` None
    chooses (:func:`csm_assets.verify.bits.choose_bits` at the deepest depth of the materials
    sharing the map and verify's views).

    A map takes a name another scene owns in the output folder (``scene.others``) only when
    its bytes are the same (``_1``, ``_2``... otherwise), so two textures of one name never
    share a map."""
    made: dict[tuple, tuple[Path, StepMap]] = {}
    picks: dict[tuple, tuple[str, int]] = {}
    verdicts: dict = {}
    todo = []
    for mat in scene.materials:
        h = mat.height
        if h is None:
            continue
        if not height_source.screen(scene, mat, verdicts):
            mat.height = None
            continue
        tile = _tile(h, opts)
        todo.append((mat, (h.texture.content_hash(), str(h.channel), h.invert, tile), _depth(scene, mat, opts)))
    deepest: dict[tuple, float] = {}
    for _, key, depth in todo:
        deepest[key] = max(depth, deepest.get(key, 0.0))
    for mat, key, depth in todo:
        h = mat.height
        if key not in made:
            if h.texture.path is not None and h.texture.path not in scene.inputs:
                scene.inputs.append(h.texture.path)
            try:
                taken = {p.name for p, _ in made.values()} | scene.reserved
                path, sm = _write_step_map(h, key[3], out_dir, taken, opts, key,
                                           bits_for=(deepest[key], tuple(allowed_bits)))
                made[key] = folder.settle(path, taken, scene.others), sm
            except FormatError as e:
                if h.origin == "command line":  # the user named this file: it must be readable
                    raise
                scene.warn(f"material {mat.name!r}: {e}; left without CSM")
                mat.height = None
                continue
            if sm.choice is not None and sm.choice.warning:
                scene.warn(f"material {mat.name!r}: {sm.choice.warning}")
        path, sm = made[key]
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


def _write_step_map(h: HeightInput, tile, out_dir: Path, taken: set[str], opts, key,
                    bits_for=None) -> tuple[Path, StepMap]:
    """The step map of ``h``, written into ``out_dir`` under a free name: (path, map).
    bits_for: (depth, allowed bits) to choose its bits by (:func:`csm_assets.verify.bits.chooser`,
    ``opts.bits`` then kept as given), else ``opts.bits`` as they are."""
    settings = StepMapSettings(max_ratio=opts.max_ratio, tile=tile, bits=opts.bits or DEFAULTS.bits,
                               bilinear_safe=opts.bilinear_safe, cones=opts.cones, source=h.texture.name)
    choose = None if bits_for is None else chooser(bits_for[0], allowed=bits_for[1], given=opts.bits)
    cached = None
    if opts.cache_dir is not None:  # keyed by the heights and every setting the map is made with
        digest = hashlib.sha256(repr((key, settings, opts.bits, bits_for)).encode()).hexdigest()
        cached = Path(opts.cache_dir) / digest
        found = [p for p in (cached.with_suffix(".png"), cached.with_suffix(".exr")) if p.is_file()]
        if found and cached.with_suffix(".json").is_file():
            path = out_dir / folder.free_name(f"{h.texture.name}_csm", found[0].suffix, taken)
            shutil.copyfile(found[0], path)
            sm = load_step_map(path)
            why = json.loads(cached.with_suffix(".json").read_text())
            sm.choice = BitsChoice(**why) if why else None
            return path, sm
    with h.texture.as_file() as file:
        sm = make_step_map(load_heightfield(file, channel=h.channel, invert=h.invert), settings, choose=choose)
    path = out_dir / folder.free_name(f"{h.texture.name}_csm", ".exr" if sm.settings.bits == 32 else ".png", taken)
    save_step_map(sm, path)
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(cached.with_suffix(path.suffix)) as tmp:
            shutil.copyfile(path, tmp)
        with atomic_path(cached.with_suffix(".json")) as tmp:  # the choice: the report says it again
            tmp.write_text(json.dumps(dataclasses.asdict(sm.choice) if sm.choice else {}))
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


