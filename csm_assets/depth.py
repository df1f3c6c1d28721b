"""A relief's depth in texture space, from a displacement factor and the surface it lies on.

The CSM material's ``depthScale`` is texture-space: uv units per unit of height. A scene
states a displacement factor in model (or world) units instead, so the factor is divided by
the world size of one uv unit on the material's triangles: the square root of their world
area over their uv area (one number per material, as a texture's texels are one size).
``convert`` and exporters calling the library (the Blender add-on) share these functions, and
an importer goes back with :func:`world_per_uv` (factor = depthScale * world_per_uv).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


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

    parts: ``(positions, uvs, faces)`` triples as :func:`triangle_areas` takes them (one per
    mesh using the material; positions in the space the factor is stated in). None when the
    triangles have no world or no uv area (nothing to measure the factor against).
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

    factor: model units per unit of the height texture's value (a glTF displacement factor,
    Blender's Displacement Scale or Bump Distance); its sign is dropped (a negative factor
    is an inverted height, which the step map's heights already hold). height_scale: the
    step map's ``heightScale`` (its heights' span in texture values; 1 for 8 and 16-bit
    images), so the depth spans the relief of the step map's 0..1. Triangles without area
    leave the factor as it is (one uv unit taken as one model unit).
    """
    scale = world_per_uv(parts)
    depth = abs(float(factor) * float(height_scale))
    return depth if scale is None else depth / scale
