"""The step map as a value: packed pixels plus the settings they were made with.

``make_step_map(heightfield, settings)`` makes one, ``save_step_map`` writes it (the
settings as JSON ``{"csm": ...}`` in the image description), ``load_step_map`` reads it
back (one open of the file). ``convert``, ``verify``, ``trade``, ``bench`` and the scene
writers pass this value around. Its settings, the defaults (:data:`DEFAULTS`) and the minimum
step that goes with a map live in :mod:`csm_assets.step_settings` (re-exported here).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .cones.relaxed import CONE_KINDS
from .errors import FormatError
from .heightfield import Heightfield
from .packing import step_maps
from .step_files import LEVELS_SUFFIX, SECOND_SUFFIX, levels_path, save_step_map, second_path  # noqa: F401 (re-exported)
from .step_levels import atlas_shape, level_chain, level_shapes, split_atlas
from .step_settings import BITS, DEFAULTS, StepMapSettings  # noqa: F401 (re-exported: csm_assets.stepmap.DEFAULTS)


@dataclass
class StepMap:
    """Packed pixels and the :class:`StepMapSettings` they were made with.

    A map of quadrant cones (``settings.cones == "quadrant"``) is two images: ``pixels``
    (R height, G, B, A the cones of quadrants +u+v, -u+v, -u-v) and ``second`` (R height,
    G the cone of +u-v, B and A the slopes); see :func:`csm_assets.packing.pack_quadrant_maps`.
    Saved, the second image goes beside the first with :data:`SECOND_SUFFIX` before the
    extension (:func:`second_path`), and the first image's settings name it.

    Attributes:
        pixels (numpy.ndarray): ``(H, W, 4)`` uint8, uint16 or float32 (see
            :func:`csm_assets.step_map`).
        settings (StepMapSettings): how they were made.
        second (numpy.ndarray | None): a quadrant map's second image, else None.
        choice (object): why its bits, when they were chosen (``verify.bits.BitsChoice``).
        levels (list[numpy.ndarray]): levels 1..n below ``pixels`` (``settings.levels`` not
            "none"; see :mod:`csm_assets.step_levels`), each ``(h, w, 4)`` of ``pixels``' dtype,
            GL's mip sizes. Saved as one more image each (:func:`levels_path`, the layout of
            :func:`csm_assets.step_levels.atlas`).
        second_levels (list[numpy.ndarray]): likewise below ``second``.
    """

    pixels: np.ndarray
    settings: StepMapSettings = field(default_factory=StepMapSettings)
    second: np.ndarray | None = None
    choice: object = field(default=None, repr=False, compare=False)  # why its bits (verify.bits.BitsChoice)
    levels: tuple = ()
    second_levels: tuple = ()

    @property
    def min_step(self) -> float:
        """``settings.min_step``."""
        return self.settings.min_step

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the pixels."""
        return self.pixels.shape[:2]


def make_step_map(heightfield, settings: StepMapSettings = DEFAULTS, *, progress=None, choose=None,
                  executor=None, level0=None) -> StepMap:
    """The step map of ``heightfield`` with ``settings``.

    Args:
        heightfield (Heightfield | numpy.ndarray): a :class:`~csm_assets.Heightfield`
            (normalized first: raw altitudes and holes become unit heights, and its height
            scale and offset go into the settings) or unit heights as
            :func:`csm_assets.step_map` takes them.
        settings: how to make it; ``settings.cones`` picks the kind.
        progress (Callable | None): ``progress(done, total)`` (rows of each cone pass,
            then the levels of the chain).
        choose (Callable | None): picks the bits once the cones are made; see
            :func:`make_step_maps`.
        executor (concurrent.futures.Executor | None): see :func:`make_step_maps`.
        level0 (Callable | None): ``level0(sm)`` with the map before its levels are made (see
            :func:`make_step_maps`).

    Returns:
        The StepMap.

    Raises:
        ValueError: bad heights or settings (as :func:`csm_assets.step_map`).
    """
    return make_step_maps(heightfield, settings, (settings.cones,), progress=progress, choose=choose, executor=executor,
                          level0=level0 and (lambda maps: level0(maps[settings.cones])))[settings.cones]


def make_step_maps(heightfield, settings: StepMapSettings = DEFAULTS, cones=CONE_KINDS, *,
                   progress=None, choose=None, executor=None, level0=None) -> dict[str, StepMap]:
    """:func:`make_step_map` for each cone kind in ``cones`` (``settings.cones`` set to it), by
    kind, from one read of the heights and one conservative cone pass
    (:func:`csm_assets.packing.step_maps`).

    Args:
        heightfield (Heightfield | numpy.ndarray): as for :func:`make_step_map`.
        settings: how to make them.
        cones (tuple[str, ...]): the kinds (``"conservative"``, ``"relaxed"``, ``"quadrant"``).
        progress (Callable | None): ``progress(done, total)``, called by each pass in turn.
        choose (Callable | None): None (``settings.bits``), or ``choose(pack, settings) ->
            BitsChoice`` that picks the bits once the cones are made (``pack(bits)``: the map
            of the first kind in ``cones`` at those bits; see
            :func:`csm_assets.verify.bits.chooser`); the maps then carry it as ``choice``. Its
            attribute ``bits``, if any, names the bits it may ask for (quadrant cones keep
            those only).
        executor (concurrent.futures.Executor | None): an executor (a Dask cluster's:
            :func:`csm_assets.dask_client.dask_executor`) that searches the cones in bands of
            rows, with the same bytes (:mod:`csm_assets.cones.remote`).
        level0 (Callable | None): ``level0({kind: StepMap})`` with the maps (final settings, no
            levels yet) before their level chain is made: a :class:`~csm_assets.step_files.StepMapSaver`
            starts writing them then.

    Returns:
        ``{kind: StepMap}`` for each kind in ``cones``.

    Raises:
        ValueError: bad heights or settings (as :func:`csm_assets.step_map`).
    """
    heights, settings = step_map_heights(heightfield, settings)
    chosen = []

    def bits(pack):
        chosen.append(choose(lambda b: conservative_view(pack(b, cones[0])), settings.replace(cones=cones[0])))
        return chosen[0].bits

    packed = step_maps(heights, tile=settings.tile, max_ratio=settings.max_ratio,
                       bits=settings.bits if choose is None else bits, progress=progress,
                       bilinear_safe=settings.bilinear_safe, cones=tuple(cones),
                       choices=getattr(choose, "bits", (8, 16, 32)), executor=executor)
    if chosen:
        settings = settings.replace(bits=chosen[0].bits)
    if not level_shapes(packed[cones[0]].shape[:2]):  # 1x1: no level below it
        settings = settings.replace(levels="none")
    maps = {kind: StepMap(p[..., :4], settings.replace(cones=kind), p[..., 4:] if p.shape[2] == 8 else None,
                          choice=chosen[0] if chosen else None) for kind, p in packed.items()}
    if level0 is not None:
        level0(maps)
    if settings.levels != "none":
        chain = level_chain(packed[cones[0]], tuple(cones), mode=settings.levels,
                            tile=settings.tile, max_ratio=settings.max_ratio, bilinear_safe=settings.bilinear_safe,
                            progress=progress)
        for kind, sm in maps.items():
            sm.levels = tuple(lv[..., :4] for lv in chain[kind])
            sm.second_levels = tuple(lv[..., 4:] for lv in chain[kind] if lv.shape[2] == 8)
    return maps


def step_map_heights(heightfield, settings: StepMapSettings = DEFAULTS):
    """(heights, settings) that :func:`make_step_maps` makes the maps of: a
    :class:`~csm_assets.Heightfield` normalized, as its exact uint8/uint16 codes where it has
    them (:meth:`~csm_assets.Heightfield.exact_heights`), its height scale and offset put in the
    settings; unit heights as they are. A caller done with the field can drop it then (its float32
    data: 4 bytes a texel while the cones are made)."""
    if not isinstance(heightfield, Heightfield):
        return heightfield, settings
    hf = heightfield.normalized()
    settings = settings.replace(height_scale=float(hf.meta["height_scale"]),
                                height_offset=float(hf.meta["height_offset"]))
    return hf.exact_heights(), settings


def conservative_view(p: np.ndarray) -> np.ndarray:
    """A packed map as one ``(H, W, 4)`` image a cone march can draw: itself, or for a
    quadrant map (``(H, W, 8)``) R, the narrowest of its four quadrant cones (the whole cone:
    conservative), B and A."""
    if p.shape[2] == 4:
        return p
    out = np.empty(p.shape[:2] + (4,), p.dtype)
    out[..., 0], out[..., 2], out[..., 3] = p[..., 0], p[..., 6], p[..., 7]
    g = np.minimum(p[..., 1], p[..., 2], out=out[..., 1])
    np.minimum(g, p[..., 3], out=g)
    np.minimum(g, p[..., 5], out=g)
    return out


def load_step_map(path, *, external: StepMapSettings | None = None, optional: bool = False, image=None):
    """A step map file, read with one open: its pixels and the settings stored with them.

    A map without stored settings (made elsewhere) is refused (FormatError) unless
    ``external`` gives the settings to read it with (``cone`` becomes "external"); with
    ``optional`` such a file (or one that is no image) gives None instead, so the caller
    can read it as a height map.

    Args:
        path (str | os.PathLike): the step map image.
        external: settings for a map made elsewhere (``max_ratio``, ``tile``).
        optional: give None instead of refusing a file that is no csm-assets step map.
        image (tuple | None): what ``formats.image.read_pixels(path, describe=True)`` already
            read of the file (then it is not opened again).

    Returns:
        The map (``settings.bits`` from the file's type), or None as ``optional`` says.

    Raises:
        FormatError: not an image, unreadable, not RGBA, no settings and no ``external``, or
            a quadrant map's second image missing or not matching.
    """
    from .formats import FORMATS, step_map_meta
    from .formats.image import read_pixels

    if FORMATS.get(Path(path).suffix.lower()) != "image":
        if optional:
            return None
        raise FormatError(path, "step maps are images (PNG, TGA, TIFF, EXR)")
    pixels, _, text = image or read_pixels(path, describe=True)
    meta = step_map_meta(text)
    if not meta and external is None:
        if optional:
            return None
        raise FormatError(path, "has no csm-assets step map settings; a map made elsewhere needs its "
                                "settings given (max_ratio, tile)")
    if pixels.shape[2] != 4:
        raise FormatError(path, f"expected an RGBA step map (4 channels), got {pixels.shape[2]}")
    if pixels.dtype == np.float16:
        pixels = pixels.astype(np.float32)
    bits = BITS.get(pixels.dtype, 32)
    if meta.get("image") in (2, "levels"):
        what = "the second image of a quadrant step map" if meta["image"] == 2 else "the levels of a step map"
        raise FormatError(path, f"is {what}; load {meta.get('first', 'the first')}")
    if not meta:
        return StepMap(pixels, dataclasses.replace(external, bits=bits, cone="external", levels="none"))
    settings, second = StepMapSettings.from_meta(meta, bits), None
    if meta.get("cones") == "quadrant":
        second, second_meta = _beside(path, meta.get("second", second_path(path).name), "second image",
                                      pixels.shape, pixels.dtype)
    levels = _levels(path, meta, pixels)
    second_levels = _levels(second_path(path), second_meta, second) if second is not None else ()
    return StepMap(pixels, settings, second, levels=levels, second_levels=second_levels)


def _beside(path, name, what: str, shape, dtype):
    """(pixels, stored settings) of the image ``name`` beside ``path`` (its ``what``), which must
    exist with ``shape`` and ``dtype``; FormatError naming the file otherwise."""
    from .formats import step_map_meta
    from .formats.image import read_pixels

    if not isinstance(name, str) or name in ("", ".", "..") or Path(name).name != name:
        raise FormatError(path, f"names its {what} {name!r}: expected the name of a file beside it")
    other = Path(path).with_name(name)
    if not other.is_file():
        raise FormatError(path, f"is a step map whose {what} {other.name} is missing")
    pixels, _, text = read_pixels(other, describe=True)
    pixels = pixels.astype(np.float32) if pixels.dtype == np.float16 else pixels
    if pixels.shape != tuple(shape) or pixels.dtype != dtype:
        raise FormatError(other, f"expected the {what} of {Path(path).name}: {tuple(shape)} {np.dtype(dtype)}, "
                                 f"got {pixels.shape} {pixels.dtype}")
    return pixels, step_map_meta(text)


def _levels(path, meta: dict, pixels: np.ndarray) -> tuple:
    """The levels 1..n of the image ``pixels`` at ``path`` from the atlas its ``meta`` names
    (``levels_image``; () when it names none)."""
    if "levels_image" not in meta:
        return ()
    h, w = atlas_shape(pixels.shape[:2])
    image, _ = _beside(path, meta["levels_image"], "levels image", (h, w, 4), pixels.dtype)
    return tuple(np.ascontiguousarray(lv) for lv in split_atlas(image, pixels.shape[:2]))
