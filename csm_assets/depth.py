"""A relief's depth in texture space, from a displacement factor and the surface it lies on.

The CSM material's ``depthScale`` is texture-space: uv units per unit of height. A scene
states a displacement factor in model (or world) units instead, so the factor is divided by
the world size of one uv unit on the material's triangles: the square root of their world
area over their uv area (one number per material, as a texture's texels are one size).
``convert`` and exporters calling the library (the Blender add-on) share these functions, and
an importer goes back with :func:`world_per_uv` (factor = depthScale * world_per_uv).

What can be measured (:func:`check_depth`): a relief ``depth`` uv units deep on a ``W x H``
texture is ``depth * max(W, H)`` texels deep. Between :data:`MIN_DEPTH_TEXELS` and
:data:`MAX_DEPTH_TEXELS` (2^-24 to 2^24 texels: float32's 24-bit significand, the precision the
shaders and verify's renderer compute in) the relief moves a hit by a measurable amount and
a float32 step of height spans at most a texel of it. Shallower, no hit moves by one float32
step of a texel; deeper, one float32 step of height is more than a texel of relief, so no hit
under the top can be placed to a texel, and a ray seen at a slant runs ``depth * W * cot(elevation)``
texels through the relief before it can reach the bottom. Such depths are refused, naming where
they came from, before anything is traced.
"""

from __future__ import annotations

from collections.abc import Iterable

import math

import numpy as np

from .errors import OptionError

MIN_DEPTH_TEXELS = 2.0 ** -24  # texels: shallower, no hit moves by a float32 step of a texel
MAX_DEPTH_TEXELS = 2.0 ** 24   # texels: deeper, a float32 step of height spans more than a texel


def triangle_areas(positions, uvs, faces) -> tuple[np.ndarray, np.ndarray]:
    """World and uv areas of triangles, float64 ``(F,)`` each.

    positions: ``(V, 3)``; uvs: ``(V, 2)``; faces: integer ``(F, 3)`` indices into both.
    """
    p = np.asarray(positions, np.float64)[faces]
    t = np.asarray(uvs, np.float64)[faces]
    world = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) / 2
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return world, np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2


def world_per_uv(parts: Iterable[tuple]) -> float | None:
    """World units per uv unit over all triangles of ``parts``: ``sqrt(world area / uv area)``.

    Args:
        parts: ``(positions, uvs, faces)`` triples, one per mesh using the material: positions
            ``(V, 3)`` in the space the factor is stated in, uvs ``(V, 2)``, faces integer
            ``(F, 3)`` indices into both.

    Returns:
        The scale, or None when the triangles have no world or no uv area (nothing to measure
        a factor against).
    """
    world = uv = 0.0
    for positions, uvs, faces in parts:
        if len(faces) == 0:
            continue
        w, u = triangle_areas(positions, uvs, faces)
        world += float(w.sum())
        uv += float(u.sum())
    if not (world > 0 and uv > 0) or not np.isfinite(world / uv):
        return None
    return float(np.sqrt(world / uv))


def texture_depth(factor: float, parts: Iterable[tuple], *, height_scale: float = 1.0) -> float:
    """Texture-space depth (uv units per unit of height) of a displacement ``factor``.

    Args:
        factor: model units per unit of the height texture's value (a glTF displacement
            factor, Blender's Displacement Scale or Bump Distance). Its sign is dropped: a
            negative factor is an inverted height, which the step map's heights already hold.
        parts: ``(positions, uvs, faces)`` triples as :func:`world_per_uv` takes them.
        height_scale: the step map's ``heightScale`` (its heights' span in texture values; 1
            for 8 and 16-bit images), so the depth spans the relief of the step map's 0..1.

    Returns:
        ``|factor * height_scale| / world_per_uv(parts)``, in uv units. Triangles without area
        leave the factor as it is (one uv unit taken as one model unit).
    """
    scale = world_per_uv(parts)
    depth = abs(float(factor) * float(height_scale))
    return depth if scale is None else depth / scale


def depth_texels(depth: float, shape) -> float:
    """How many texels deep a relief ``depth`` uv units deep is on a texture of ``shape``
    ``(H, W, ...)``: ``depth * max(H, W)`` (1/W uv is a texel along u, 1/H along v)."""
    return float(depth) * max(int(shape[0]), int(shape[1]), 1)


def depth_range(shape) -> tuple[float, float]:
    """The depths (uv units per unit of height) :func:`check_depth` accepts on a texture of
    ``shape`` ``(H, W, ...)``: ``(MIN_DEPTH_TEXELS, MAX_DEPTH_TEXELS) / max(H, W)``."""
    side = max(int(shape[0]), int(shape[1]), 1)
    return MIN_DEPTH_TEXELS / side, MAX_DEPTH_TEXELS / side


def measurable(depth: float, shape) -> bool:
    """Whether a relief ``depth`` deep on a texture of ``shape`` is within :func:`depth_range`."""
    lo, hi = depth_range(shape)
    return math.isfinite(depth) and lo <= depth <= hi


def check_depth(depth, shape, what: str = "the depth") -> float:
    """``depth`` (texture-space: uv units per unit of height) as a float when it is finite, > 0
    and measurable on a texture of ``shape`` ``(H, W, ...)`` (:func:`depth_range`, see the module
    doc); else OptionError (exit 2) naming ``what`` (the option or configuration key it came
    from: ``--depth``, ``depth (csm-assets.toml:3)``...), the texture's size and the range."""
    try:
        d = float(depth)
    except (TypeError, ValueError, OverflowError):
        raise OptionError(f"{what} must be a finite number > 0, got {depth!r}") from None
    if not (math.isfinite(d) and d > 0):
        raise OptionError(f"{what} must be a finite number > 0, got {depth!r}")
    if measurable(d, shape):
        return d
    lo, hi = depth_range(shape)
    side = max(int(shape[0]), int(shape[1]), 1)
    why = ("no hit moves by a float32 step of a texel" if d < lo else
           "a float32 step of height spans more than a texel, and slanted rays run that far through the relief")
    raise OptionError(f"{what} {d:g} is {depth_texels(d, shape):.3g} texels deep on a {shape[1]}x{shape[0]} texture "
                      f"(depth x {side}): nothing can be measured there ({why}); this texture takes depths "
                      f"{lo:.3g} to {hi:.3g} (2^-24 to 2^24 texels)")


def too_deep(depth: float, shape) -> str:
    """Why a relief ``depth`` deep is too deep to measure on a texture of ``shape`` (a stored
    material's depthScale, which verify reports instead of drawing), or '' when it is not."""
    texels = depth_texels(depth, shape)
    if texels <= MAX_DEPTH_TEXELS:
        return ""
    return f"{float(depth):g} is {texels:.3g} texels deep on its {shape[1]}x{shape[0]} map: nothing can be measured " \
           "(over 2^24 texels)"
