"""UDIM height sets in a conversion: one step map per tile, written as a UDIM set.

A material whose height texture is a UDIM set (:class:`~csm_assets.scene.UdimSet`, from a USD
``name.<UDIM>.ext`` or ``--height MATERIAL=name.<UDIM>.png``) gets one step map per tile present,
each made from that tile alone: tiles are separate uv squares, so its cones are exact within the
tile and clamped at its borders (``--tile`` makes every tile repeat instead). The maps are written
as ``<name>_csm.<tile>.png`` beside the scene; the material names the pattern
``<name>_csm.<UDIM>.png`` (``CsmSettings.step_map``; each tile's file in ``CsmSettings.tiles``).
All tiles of a set share one bit depth (the most any tile's choice needs) and one height range (float
tiles of other ranges are made over the range spanning them all).

A UDIM set's maps carry no level chain, whatever ``opts.levels`` says: the readers of a converted
scene (:func:`csm_assets.formats.csm_material.usd_materials`, ``verify``) keep one levels image per material,
not one per tile, and no engine side here draws a UDIM set's levels; level 0's march is correct alone.

Only USD holds UDIM textures: a set named on the command line (or in a configuration) for a glTF
or OBJ scene is refused (:func:`refuse_sets`). ``--max-error`` picks on one map, so it is refused
for UDIM sets too; pick a ``--variant`` (and ``--steps``).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import OptionError
from ..scene import CsmSettings, HeightInput, Scene
from ..stepmap import StepMap, save_step_map, second_path
from ..udim import TOKEN, face_tiles, is_pattern, spans
from ..verify.bits import chooser
from . import output_folder as folder
from .maps import check_material_depth, made_or_dropped, material_depth, resolve_tile, step_map_settings
from .pick import pick
from .udim_tiles import common_range, tile_maps


def refuse_sets(in_path: Path, opts, module) -> None:
    """OptionError (exit 2) when ``opts.heights`` names a UDIM set for a scene whose format holds
    no UDIM textures (glTF and MTL name one image per material): the request cannot be met."""
    if getattr(module, "UDIM_SETS", False):
        return
    for name, value in opts.heights.items():
        path = getattr(value, "path", value)
        udim = getattr(value, "udim", None) is not None or (isinstance(path, (str, Path)) and is_pattern(path))
        if udim:
            key = "depth-map" if getattr(value, "depth_map", False) else "height"
            where = f"{key}.{name} ({opts.named_by[name]})" if name in opts.named_by else f"--{key} {name}={path}"
            raise OptionError(f"{in_path}: {where} names a UDIM set as the height texture of material {name!r}, but "
                              f"{in_path.suffix} scenes have no UDIM textures (a material names one image): name "
                              "one tile, or convert a USD scene")


def make_udim_maps(scene: Scene, out_dir: Path, opts, allowed_bits=(8, 16), progress=None,
                   executor=None) -> dict[str, Path]:
    """The step maps of every material whose height is a UDIM set, into ``out_dir`` (the staging
    folder); sets ``material.csm`` (``tiles``: tile -> map file) and adds the files' names to
    ``scene.reserved``. Returns name -> path of every tile's map (as
    :func:`csm_assets.convert.maps.make_step_maps`, which leaves these materials alone).
    Materials sharing one set (same tiles, channel, inversion, tiling) share its maps. ``executor``
    (a ``concurrent.futures`` executor, a Dask cluster's): each tile's map is a task on it."""
    todo = []
    for mat in scene.materials:
        h = mat.height
        if h is None or h.udim is None:
            continue
        if opts.max_error is not None:
            raise OptionError(f"material {mat.name!r}: --max-error picks the shader on one step map; its height is "
                              "a UDIM set (a map per tile): give --variant (and --steps) instead")
        key = (tuple((t, x.content_hash()) for t, x in h.udim.tiles.items()), str(h.channel), h.invert,
               resolve_tile(h.tile, opts))
        todo.append((mat, key, material_depth(scene, mat, opts)))
    deepest: dict[tuple, float] = {}
    for _, key, depth in todo:
        deepest[key] = max(depth, deepest.get(key, 0.0))
    made: dict[tuple, tuple] = {}
    for mat, key, depth in todo:
        h = mat.height
        if key not in made:
            scene.inputs.extend(f for f in h.files() if f not in scene.inputs)
            found = made_or_dropped(scene, mat, lambda: _make_set(scene, h, key[3], out_dir, opts, deepest[key],
                                                                  allowed_bits, progress, executor))
            if found is None:
                continue
            made[key] = found
        files, shapes, sm = made[key]
        for shape in shapes.values():
            check_material_depth(scene, mat, opts, depth, shape)
        pattern = _pattern(files)
        variant, steps, min_step = pick(sm, pattern.name, depth, opts)
        mat.csm = CsmSettings.of(pattern, sm, depth, variant, steps, self_shadow=opts.self_shadow,
                                 light_size=opts.light_size, picked_min_step=min_step)
        mat.csm.tiles = dict(files)
        warn_uncovered(scene, mat, set(files))
    return {p.stem: p for files, _, _ in made.values() for p in files.values()}


def _pattern(tiles: dict[int, Path]) -> Path:
    """The pattern of the tile files ``tiles`` (``h_csm.1001.png`` -> ``h_csm.<UDIM>.png``)."""
    t = min(tiles)
    stem, suffix = tiles[t].name.rsplit(f".{t}", 1)
    return tiles[t].with_name(f"{stem}.{TOKEN}{suffix}")


def _make_set(scene: Scene, h: HeightInput, tile, out_dir: Path, opts, depth: float, allowed_bits,
              progress, executor=None) -> tuple[dict[int, Path], dict[int, tuple], StepMap]:
    """Each tile's step map of the set ``h.udim``, written into ``out_dir``: (tile -> file, tile -> shape,
    the lowest tile's map). Each tile is made alone first; then, so that the material's one bit depth
    and one height range hold for all, a tile is made again at the most bits any tile's choice needs
    (:func:`~csm_assets.verify.bits.chooser`; ``opts.bits`` when given), and over the set's common range
    where the tiles' ranges differ (float heights leaving [0, 1] are rescaled per tile alone).
    ``executor``: each tile a task on it (:func:`~csm_assets.convert.udim_tiles.tile_maps`), the same files."""
    settings = step_map_settings(opts, tile, h.texture.name).replace(levels="none")  # no levels: module doc
    choose = chooser(depth, allowed=tuple(allowed_bits), given=opts.bits)
    suffix = ".exr" if opts.bits == 32 else ".png"
    tiles = sorted(h.udim.tiles)

    def names(stem: str) -> list[str]:
        firsts = [Path(f"{stem}.{t}{suffix}") for t in tiles]
        return [n for p in firsts for n in (p.name, *([second_path(p).name] if opts.cones == "quadrant" else []))]

    stem = folder.free_name(f"{h.texture.name}_csm", "", lambda s: any(n in scene.reserved or n in scene.others
                                                                      for n in names(s)))
    scene.reserved.update(names(stem))
    files = {t: out_dir / f"{stem}.{t}{suffix}" for t in tiles}
    rows = (lambda done, total: progress("step maps", done, total)) if progress else None
    made: dict[int, StepMap] = {}  # tile -> its map (the pixels of the first tile only)
    shapes: dict[int, tuple] = {}

    def make(todo, bits=None, common=None):
        for t, sm in tile_maps(h, todo, settings.replace(bits=bits), choose=choose if bits is None else None,
                               common=common, executor=executor, progress=rows):
            save_step_map(sm, files[t])
            shapes[t] = sm.pixels.shape[:2]
            made[t] = sm if t == tiles[0] else StepMap(sm.pixels[:0, :0], sm.settings, None, sm.choice)

    make(tiles)
    ranges = {t: (m.settings.height_scale, m.settings.height_offset) for t, m in made.items()}
    common = None if len(set(ranges.values())) == 1 else common_range(ranges.values())
    bits = max(m.settings.bits for m in made.values())
    deciding = next(made[t].choice for t in tiles if made[t].settings.bits == bits)
    make([t for t in tiles if made[t].settings.bits != bits or (common is not None and ranges[t] != common)],
         bits, common)
    first = made[tiles[0]]
    return files, {t: shapes[t] for t in tiles}, StepMap(first.pixels, first.settings, first.second, deciding)


def warn_uncovered(scene: Scene, mat, tiles: set[int]) -> None:
    """CSM108 for each mesh of ``mat`` with triangles in a tile the set lacks (no relief there) or
    reaching across their tile's border (cut off at it)."""
    for mesh in scene.meshes:
        if mesh.material is not mat or mesh.uvs is None:
            continue
        where = face_tiles(mesh)
        lacking = sorted(set(where.tolist()) - tiles)
        missing = int(sum((where == t).sum() for t in lacking))
        across = spans(mesh, where)
        named = ", ".join(str(t) if t else "outside 1001-1999" for t in lacking)
        said = [f"{missing} of {len(where)} triangle(s) lie in UDIM tile(s) the set lacks ({named}): no relief "
                "there"] * bool(missing)
        said += [f"{across} triangle(s) reach across their tile's border: the relief is cut off at it"] * bool(across)
        if said:
            scene.warn("CSM108", "; ".join(said), f"mesh {mesh.name} (material {mat.name!r})")
