"""The step map as a value: packed pixels plus the settings they were made with.

``make_step_map(heightfield, settings)`` makes one, ``save_step_map`` writes it (the
settings as JSON ``{"csm": ...}`` in the image description), ``load_step_map`` reads it
back (one open of the file). ``convert``, ``verify``, ``trade``, ``bench`` and the scene
writers pass this value around, so the rules live here once: the defaults
(:data:`DEFAULTS`) and the minimum step that goes with a map (:attr:`StepMapSettings.min_step`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .cones.relaxed import CONE_KINDS
from .errors import FormatError
from .heightfield import Heightfield, tile_pair
from .packing import SAFE_MIN_STEP, step_maps

BITS = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16, np.dtype(np.float32): 32}


@dataclass(frozen=True)
class StepMapSettings:
    """How a step map was made; what the shader needs travels with it.

    max_ratio: the cone ratio that G = 1 stands for. tile: (tile_x, tile_y), the texture
    repeats along that axis. bits: 8, 16 (integers) or 32 (float). bilinear_safe: G holds
    each texel's 3x3 minimum (see :func:`csm_assets.step_map`), and ``_exact`` then steps
    at least 0.25 texel (:attr:`min_step`), else the paper's one texel. cone: "exact" (made
    here) or "external" (a map made elsewhere, read as a step map). cones: "conservative"
    (every variant), "relaxed" (the ``relaxed`` variant only) or "quadrant" (two images, the
    ``quadrant`` variant only: :class:`StepMap`'s ``second``). height_scale,
    height_offset: ``raw = offset + scale * R``. source: the height map's name.
    """

    max_ratio: float = 1.0
    tile: tuple[bool, bool] = (True, True)
    bits: int = 8
    bilinear_safe: bool = True
    cone: str = "exact"
    cones: str = "conservative"
    height_scale: float = 1.0
    height_offset: float = 0.0
    source: str = ""

    def __post_init__(self):
        object.__setattr__(self, "tile", tile_pair(self.tile))

    @property
    def min_step(self) -> float:
        """``_exact``'s minimum step in texels: 0.25 with bilinear-safe maps, else 1 (the paper's);
        half that for quadrant maps, whose variant measures it across the texture (longer along
        steep rays: a quarter texel skipped white-noise peaks at 10-20 degree views)."""
        step = SAFE_MIN_STEP if self.bilinear_safe else 1.0
        return step / 2 if self.cones == "quadrant" else step

    def replace(self, **changes) -> StepMapSettings:
        """A copy with ``changes``; None values leave a field as it is."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_meta(self) -> dict:
        """The JSON object stored in the map's image description."""
        return {"max_ratio": self.max_ratio, "tile": list(self.tile), "bits": self.bits,
                "bilinear_safe": self.bilinear_safe, "cones": self.cones, "height_scale": self.height_scale,
                "height_offset": self.height_offset, "source": self.source}

    @classmethod
    def from_meta(cls, meta: dict, bits: int) -> StepMapSettings:
        """Settings stored by :meth:`to_meta` (older maps lack some: bilinear_safe then False)."""
        return cls(max_ratio=float(meta.get("max_ratio", 1.0)), tile=tuple(meta.get("tile", (True, True))),
                   bits=bits, bilinear_safe=bool(meta.get("bilinear_safe", False)), cone="exact",
                   cones=str(meta.get("cones", "conservative")),
                   height_scale=float(meta.get("height_scale", 1.0)),
                   height_offset=float(meta.get("height_offset", 0.0)), source=str(meta.get("source", "")))


DEFAULTS = StepMapSettings()


@dataclass
class StepMap:
    """Packed pixels ``(H, W, 4)`` (uint8, uint16 or float32; see :func:`csm_assets.step_map`)
    and the :class:`StepMapSettings` they were made with.

    A map of quadrant cones (``settings.cones == "quadrant"``) is two images: ``pixels``
    (R height, G, B, A the cones of quadrants +u+v, -u+v, -u-v) and ``second`` (R height,
    G the cone of +u-v, B and A the slopes); see :func:`csm_assets.packing.pack_quadrant_maps`.
    Saved, the second image goes beside the first with :data:`SECOND_SUFFIX` before the
    extension (:func:`second_path`), and the first image's settings name it.
    """

    pixels: np.ndarray
    settings: StepMapSettings = field(default_factory=StepMapSettings)
    second: np.ndarray | None = None
    choice: object = field(default=None, repr=False, compare=False)  # why its bits (verify.bits.BitsChoice)

    @property
    def min_step(self) -> float:
        return self.settings.min_step

    @property
    def shape(self) -> tuple[int, int]:
        return self.pixels.shape[:2]


def make_step_map(heightfield, settings: StepMapSettings = DEFAULTS, *, progress=None, choose=None,
                  executor=None) -> StepMap:
    """The step map of ``heightfield`` with ``settings``.

    heightfield: a :class:`~csm_assets.Heightfield` (normalized first: raw altitudes and
    holes become unit heights, and its height scale and offset go into the settings) or
    unit heights as :func:`csm_assets.step_map` takes them. progress: ``progress(done, total)``.
    choose, executor: see :func:`make_step_maps`.
    """
    return make_step_maps(heightfield, settings, (settings.cones,), progress=progress,
                          choose=choose, executor=executor)[settings.cones]


def make_step_maps(heightfield, settings: StepMapSettings = DEFAULTS, cones=CONE_KINDS, *,
                   progress=None, choose=None, executor=None) -> dict[str, StepMap]:
    """:func:`make_step_map` for each cone kind in ``cones`` (``settings.cones`` set to it), by
    kind, from one read of the heights and one conservative cone pass
    (:func:`csm_assets.packing.step_maps`).

    choose: None (``settings.bits``), or ``choose(pack, settings) -> BitsChoice`` that picks the
    bits once the cones are made (``pack(bits)``: the map of the first kind in ``cones`` at those
    bits; see :func:`csm_assets.verify.bits.chooser`); the maps then carry it as ``choice``. Its
    attribute ``bits``, if any, names the bits it may ask for (quadrant cones keep those only).
    executor: a ``concurrent.futures`` executor (a Dask cluster's:
    :func:`csm_assets.dask_client.dask_executor`) that searches the cones in bands of rows, with
    the same bytes (:mod:`csm_assets.cones.remote`)."""
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
    return {kind: StepMap(p[..., :4], settings.replace(cones=kind), p[..., 4:] if p.shape[2] == 8 else None,
                          choice=chosen[0] if chosen else None)
            for kind, p in packed.items()}


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


SECOND_SUFFIX = "_q"  # a quadrant map's second image: OUT's stem + this + OUT's extension


def second_path(path) -> Path:
    """Where a quadrant map saved at ``path`` keeps its second image (``bricks.png`` ->
    ``bricks_q.png``)."""
    path = Path(path)
    return path.with_name(path.stem + SECOND_SUFFIX + path.suffix)


def save_step_map(sm: StepMap, path) -> None:
    """Write ``sm`` bit-exactly with its settings (PNG, TGA, TIFF, EXR), atomically."""
    from .formats import write_step_map

    meta = sm.settings.to_meta()
    if sm.settings.cones == "quadrant":
        if sm.second is None or sm.second.shape != sm.pixels.shape:
            raise ValueError("a quadrant step map needs its second image, of the first one's shape")
        write_step_map(sm.second, second_path(path), {**meta, "image": 2, "first": Path(path).name})
        meta["second"] = second_path(path).name
    write_step_map(sm.pixels, path, meta)


def load_step_map(path, *, external: StepMapSettings | None = None, optional: bool = False, image=None):
    """A step map file, read with one open: its pixels and the settings stored with them.

    A map without stored settings (made elsewhere) is refused (FormatError) unless
    ``external`` gives the settings to read it with (``cone`` becomes "external"); with
    ``optional`` such a file (or one that is no image) gives None instead, so the caller
    can read it as a height map. image: what ``formats.image.read_pixels(path, describe=True)``
    already read of the file (then it is not opened again).
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
    if meta.get("image") == 2:
        raise FormatError(path, f"is the second image of a quadrant step map; load {meta.get('first', 'the first')}")
    if meta.get("cones") == "quadrant":
        other = Path(path).with_name(str(meta.get("second", second_path(path).name)))
        if not other.is_file():
            raise FormatError(path, f"is a quadrant step map whose second image {other.name} is missing")
        second, _, _ = read_pixels(other, describe=True)
        second = second.astype(np.float32) if second.dtype == np.float16 else second
        if second.shape != pixels.shape or second.dtype != pixels.dtype:
            raise FormatError(other, f"expected the second image of {Path(path).name}: {pixels.shape} "
                                     f"{pixels.dtype}, got {second.shape} {second.dtype}")
        return StepMap(pixels, StepMapSettings.from_meta(meta, bits), second)
    if meta:
        return StepMap(pixels, StepMapSettings.from_meta(meta, bits))
    return StepMap(pixels, dataclasses.replace(external, bits=bits, cone="external"))
