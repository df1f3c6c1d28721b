"""What a material's height texture really holds, and how the command line names one.

Every scene reader hands its height textures to :func:`screen` (called once, from
``convert``): a tangent-space normal map under a bump statement or a displacement
slot is skipped with a warning naming the material and the file, and a colour
photograph is converted from its luminance with a warning.

:func:`classify_pixels` decides by content, over at most ``SAMPLES``² texels:

- **normal**: three channels that decode (linearly, or as sRGB as CryEngine's ``_ddn``
  maps are often stored) to vectors of unit length (median |length - 1| < 0.1, and
  within 0.12 of 1 in 60% of texels: JPEG blurs the rest) pointing out of the surface
  (median z > 0.4) and centred in x and y (|mean| < 0.3); either green convention (DirectX or
  OpenGL) passes. Or two channels x, y (BC5-style: stored as RG, as grey+alpha, or as
  RGB with B constant) inside the unit disc, both varying, centred and distinct,
  with z = sqrt(1 - x² - y²) reconstructed (a flat two-channel map is grey, so only its
  name tells it). Float images holding signed vectors too.
  Or, for maps shortened by resizing or mip filtering (averaged unit vectors are
  shorter), vectors of median length 0.75 to 1.05 (10% above 0.6, 90% below 1.15),
  tightly centred (|mean x|, |mean y| < 0.1) and pointing out (median z > 0.6).
- **height**: grey values (R = G = B), one channel, or anything not a normal map nor
  colourful.
- **photo**: a colourful RGB image (Hasler and Süsstrunk's colourfulness above
  ``PHOTO_COLOURFULNESS`` on a 0-255 scale).

A name that reads like a normal map (``_n``, ``_nm``, ``_nrm``, ``_nor``, ``_norm``,
``_normal(s)``, ``_ddn``, ``normalmap``) decides only where the content leaves it open
(vectors pointing out, centred, of median length within 0.25 of 1: painted or
blurred maps such as nanosuit's ``glass_ddn``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .checks import positive
from .errors import FormatError, OptionError
from .scene import HeightInput, Material, Scene, Texture
from .udim import file_set, is_pattern

DEFAULT_DEPTH = 0.1
"""Texture-space depth (uv units per unit of height) when nothing states one."""
SAMPLES = 256        # texels per side looked at (a strided subsample of bigger images)
PHOTO_COLOURFULNESS = 12.0
NORMAL_NAME = re.compile(r"(normals?|normalmap|nrm|ddn|norm)$|[_\-. ](n|nm|nor)$", re.IGNORECASE)


@dataclass(frozen=True)
class HeightSpec:
    """A height texture named on the command line.

    Attributes:
        path (pathlib.Path): the image or heightfield file.
        depth_map (bool): it holds depths (white = deep; heights are ``1 - value``).
        channel (str | None): the one to read (index or name); None: grey, or the
            luminance of colour.
    """

    path: Path
    depth_map: bool = False
    channel: str | None = None

    def __str__(self) -> str:
        return (f"{self.path}{' (depth map)' if self.depth_map else ''}"
                f"{f' (channel {self.channel})' if self.channel is not None else ''}")


@dataclass
class Verdict:
    """What :func:`classify` found a texture holds: ``kind``, a ``reason`` for the warning,
    and the ``metrics`` measured."""

    kind: str          # "height", "normal" or "photo"
    reason: str        # a few words for the warning
    metrics: dict


EMPTY_NAME = '""'  # how the command line writes the empty material name (OBJ's bare ``newmtl``)


def material_name(text: str) -> str:
    """A MATERIAL as the command line writes it: ``""`` (two double quotes) or nothing at all
    stands for the empty name, which OBJ allows (``newmtl`` with no name)."""
    return "" if text == EMPTY_NAME else text


def height_option(flag: str, item: str) -> tuple[str, Path]:
    """``--height``/``--depth-map`` ``MATERIAL=PATH`` as the command line parses it.

    Args:
        flag: the option's name, for the message.
        item: ``MATERIAL=PATH``, split at the first ``=`` (a path may hold more); ``=PATH``
            or ``""=PATH`` names the material whose name is empty.

    Returns:
        ``(material name, path)``.

    Raises:
        OptionError: no ``=`` or no path (exit 2).
    """
    name, sep, path = item.partition("=")
    if not sep or not path:
        raise OptionError(f"{flag} takes MATERIAL=PATH, got {item!r}")
    return material_name(name), Path(path)


def depth_option(item: str) -> tuple[str | None, float]:
    """``--depth`` as the command line parses it.

    Args:
        item: ``D`` (every material) or ``MATERIAL=D`` (split at the last ``=``; ``=D`` or
            ``""=D`` names the material whose name is empty).

    Returns:
        ``(material name or None for every material, D)``.

    Raises:
        OptionError: D not a finite number > 0 (exit 2).
    """
    name, sep, value = item.rpartition("=")
    try:
        d = positive(value, "the depth")
    except ValueError as e:
        raise OptionError(f"--depth takes D or MATERIAL=D: {e}") from None
    return (material_name(name) if sep else None), d


def material_height(heights: dict, keys, scene: Scene, find) -> tuple[HeightInput | None, bool]:
    """A material's height and whether the command line gave it: ``heights`` (material name ->
    path, :class:`HeightSpec` or :class:`HeightInput`) looked up by the first of the material's
    names ``keys`` it holds (see :func:`override`), else the scene's own, ``find()``. The one
    place every scene reader takes ``--height`` from."""
    for key in keys:
        if isinstance(key, str) and key in heights:
            return override(heights[key], scene, find), True
    return find(), False


def override(value, scene: Scene, find) -> HeightInput:
    """The height a material gets from the command line (a path, :class:`HeightSpec` or
    :class:`HeightInput`), keeping what the scene itself states about it (``find()``, the
    reader's own lookup, run without its warnings: its displacement factor and offset,
    uv set, wrap modes): a command-line texture never silently replaces a factor the
    scene gives by the default depth."""
    if isinstance(value, HeightInput):
        return value
    kept = list(scene.warnings)
    found = find()
    scene.warnings[:] = kept
    spec = value if isinstance(value, HeightSpec) else HeightSpec(Path(value))
    texture, tile, udim = Texture(Path(spec.path).stem, path=Path(spec.path)), None, None
    if is_pattern(spec.path):  # a UDIM set: its tiles are separate uv squares, clamped (--tile says otherwise)
        udim = file_set(Path(spec.path), " (named as a height texture)")
        texture, tile = udim.first(), (False, False)
    if found is None:
        return HeightInput(texture, channel=spec.channel, invert=spec.depth_map, origin="command line",
                           tile=tile, depth=DEFAULT_DEPTH, udim=udim)
    return HeightInput(texture, found.tex_coord, spec.channel, spec.depth_map, found.scale, found.offset,
                       "command line", tile or found.tile, found.depth, udim)


def screen(scene: Scene, mat: Material, verdicts: dict | None = None) -> bool:
    """Whether ``mat``'s height texture holds heights. A normal map is skipped with a
    warning (False), or, named on the command line without a channel, refused (FormatError,
    exit 3); a colour photograph is kept, with a warning (its luminance, or the channel read).
    ``verdicts`` caches classifications by texture content across materials."""
    h = mat.height
    verdicts = {} if verdicts is None else verdicts
    try:
        key = h.texture.content_hash()
        if key not in verdicts:
            verdicts[key] = classify(h.texture)
        verdict = verdicts[key]
    except (FormatError, OSError):
        return True  # unreadable: the step-map maker reports it
    file = h.texture.path.name if h.texture.path is not None else f"embedded image {h.texture.name!r}"
    if verdict.kind == "normal" and h.origin == "command line":
        if h.channel is not None:  # the user said what to read
            return True
        raise FormatError(h.texture.path or file, f"is a tangent-space normal map ({verdict.reason}), not heights "
                                                  f"(named for material {mat.name!r}); name a --channel to read "
                                                  "one of its channels as heights anyway")
    if verdict.kind == "normal":
        scene.warn("CSM106", f"{h.origin} texture {file} is a tangent-space normal map ({verdict.reason}), not "
                   "heights; skipped, left without CSM", f"material {mat.name!r}")
        return False
    if verdict.kind == "photo":
        used = "its luminance is" if h.channel is None else f"its channel {h.channel} is"
        scene.warn("CSM107", f"{h.origin} texture {file} is a colour image ({verdict.reason}), not a grey height "
                   f"map; {used} used as heights", f"material {mat.name!r}")
    return True


def classify(texture: Texture) -> Verdict:
    """Whether a texture holds heights, normals, a photo, ... (:func:`classify_pixels`).

    Args:
        texture: a scene's texture; formats other than raster images hold heights by
            construction.

    Returns:
        The Verdict: ``kind`` ("height", "normal" or "photo"), ``reason``, ``metrics``.

    Raises:
        FormatError: the image cannot be read.
    """
    from .formats import image
    from .formats.registry import HEIGHTFIELDS

    if getattr(HEIGHTFIELDS.get(texture.suffix), "module", None) != "image":
        return Verdict("height", "a heightfield format", {})
    with texture.as_file() as file:
        pixels, _ = image.read_pixels(file)
    name = Path(texture.path).stem if texture.path is not None else texture.name
    return classify_stored(pixels, name)


def classify_stored(pixels: np.ndarray, name: str = "") -> Verdict:
    """:func:`classify_pixels` of an image as stored (uint8, uint16 or float ``(H, W, C)``):
    the texels it looks at are taken first, so a big image is never copied whole."""
    step = max(1, -(-max(pixels.shape[:2]) // SAMPLES))
    px = np.asarray(pixels)[::step, ::step]
    if np.issubdtype(px.dtype, np.integer):
        px = px / float(np.iinfo(px.dtype).max)
    return classify_pixels(px, name)


def classify_pixels(pixels: np.ndarray, name: str = "") -> Verdict:
    """Height, normal map or photo: ``pixels`` float ``(H, W, C)`` in [0, 1] (or signed
    floats), ``name`` the file's stem (a hint only)."""
    step = max(1, -(-max(pixels.shape[:2]) // SAMPLES))
    px = np.asarray(pixels, np.float64)[::step, ::step].reshape(-1, pixels.shape[2])
    named = bool(NORMAL_NAME.search(name))
    colours = px[:, :3] if px.shape[1] >= 3 else None
    if colours is not None and np.abs(colours - colours.mean(1, keepdims=True)).max(1).mean() < 0.01:
        return Verdict("height", "grey", {})
    decodings = _three_channel(colours) if colours is not None else []
    best = max(decodings, key=lambda m: m["unit"], default=None)
    pair = _two_channel(px, named)
    metrics = {"named": named, "three": best, "two": pair}
    if best is not None and best["off"] < 0.1 and best["unit"] >= 0.6 and best["z"] > 0.4 and best["centre"] < 0.3:
        enc = "sRGB-encoded" if best["srgb"] else "linear"
        return Verdict("normal", f"{enc} unit vectors in {best['unit']:.0%} of texels", metrics)
    if pair is not None:
        return Verdict("normal", f"two-channel x, y in the unit disc ({pair['disc']:.0%} of texels)", metrics)
    for m in decodings:  # resized or mip-filtered maps: averaged normals are shorter than 1
        if (m["centre"] < 0.1 and m["z"] > 0.6 and 0.75 <= m["median"] <= 1.05 and m["p10"] >= 0.6
                and m["p90"] <= 1.15):
            return Verdict("normal", f"{'sRGB-encoded' if m['srgb'] else 'linear'} vectors of median length "
                                     f"{m['median']:.2f} (filtered), centred, pointing out", metrics)
    for m in decodings:
        if named and m["off"] < 0.25 and m["z"] > 0.3 and m["centre"] < 0.4:
            return Verdict("normal", f"named like one, vectors out of the surface within {m['off']:.2f} of "
                                     f"unit length", metrics)
    if colours is not None:
        c = _colourfulness(colours)
        metrics["colourfulness"] = c
        if c > PHOTO_COLOURFULNESS:
            return Verdict("photo", f"colourfulness {c:.0f}", metrics)
    return Verdict("height", "no unit vectors", metrics)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in ``[0, 1]`` to linear ones (the standard's piecewise curve)."""
    return np.where(c <= 0.04045, c / 12.92, ((np.clip(c, 0, None) + 0.055) / 1.055) ** 2.4)


def _vectors(c: np.ndarray):
    """(decoded vectors, sRGB?) pairs: stored values read as 2c - 1 linearly and after
    sRGB decoding; signed floats as they are."""
    if c.min() < -0.01:
        return [(c, False)]
    return [(2 * c - 1, False), (2 * srgb_to_linear(c) - 1, True)]


def _three_channel(rgb: np.ndarray) -> list[dict]:
    """Unit-vector metrics of RGB read each way :func:`_vectors` decodes it."""
    out = []
    for v, srgb in _vectors(rgb):
        length = np.linalg.norm(v, axis=1)
        m = {"unit": float(np.mean(np.abs(length - 1) < 0.12)), "z": float(np.median(v[:, 2])),
             "off": float(np.median(np.abs(length - 1))),
             **dict(zip(("p10", "median", "p90"), map(float, np.percentile(length, [10, 50, 90])))),
             "centre": float(max(abs(v[:, 0].mean()), abs(v[:, 1].mean()))), "srgb": srgb}
        out.append(m)
    return out


def _two_channel(px: np.ndarray, named: bool) -> dict | None:
    """Metrics of a BC5-style map (x, y in channels 0 and 1, nothing or a constant after),
    or None when the pixels are not one. Both channels must vary and differ, unless the
    file is named like a normal map (a flat map: every texel near x = y = 0)."""
    if px.shape[1] < 2 or (px.shape[1] >= 3 and px[:, 2].std() > 0.01):
        return None
    for v, srgb in _vectors(px[:, :2]):
        x, y = v[:, 0], v[:, 1]
        r2 = x * x + y * y
        inside = np.mean(r2 <= 1.03) > 0.97 and max(abs(x.mean()), abs(y.mean())) < 0.25
        varied = min(x.std(), y.std()) > 0.005 and np.mean(np.abs(x - y)) > 0.005
        if inside and np.median(np.sqrt(r2)) < (0.7 if varied else 0.1 if named else -1):
            return {"disc": float(np.mean(r2 <= 1.03)), "srgb": srgb}
    return None


def _colourfulness(rgb: np.ndarray) -> float:
    """Hasler and Süsstrunk (2003) colourfulness on a 0-255 scale: ~0 grey, >~33 'quite colourful'."""
    c = rgb * 255.0
    rg = c[:, 0] - c[:, 1]
    yb = 0.5 * (c[:, 0] + c[:, 1]) - c[:, 2]
    return float(np.hypot(rg.std(), yb.std()) + 0.3 * np.hypot(rg.mean(), yb.mean()))
