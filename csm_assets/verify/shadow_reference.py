"""Exact self-shadows on the CPU: the reference the shader's ``csm_shadow`` is checked against.

Texture space is the shader's: ``(u, v, height)`` with uv and height in the same units
(a unit ray parameter is one uv unit, or the full height range); a light direction is a
unit vector ``(u, v, up)`` towards the light. The surface is the bilinear one of
:mod:`csm_assets.verify.trace`.

Hard shadow (:func:`hard_shadows`): the ray from the light comes down to the shaded
point P from where it enters the relief (its top, height 1, or a non-tiled side: nothing
lies outside a non-tiled map), and P is lit when that ray's first hit
(:func:`~csm_assets.verify.trace.trace_heightfield`, exact) is P itself: no hit, or a hit at most
``tolerance`` texels (``tolerance / max(H, W)`` along the ray) or ``height_tolerance``
of height (2/255: GPUs filter 8-bit maps to about 8 bits) before P, whichever is longer.
A light at or below the horizon (up <= 0) shadows everything.

Soft shadow (:func:`soft_shadows`): the visible share of the light's disc (angular
radius ``light_size`` radians, in world space) as the share of ``rays`` exact hard
tests over it, at the points of a sunflower (Vogel) spiral: every ray stands for an
equal area of the disc. A straight shadow edge across the disc is then estimated to
within about ``1.5 / sqrt(rays)`` (64 rays: under 0.2; the
measured error of the estimate is in the tests).
"""

from __future__ import annotations

import numpy as np

from ..heightfield import tile_pair, unit_heights
from .trace import trace_heightfield

TOLERANCE = 1.0  # texels; the shader's CSM_SHADOW_TOLERANCE
HEIGHT_TOLERANCE = 2.0 / 255.0  # the shader's CSM_SHADOW_HEIGHT_TOLERANCE
SOFT_RAYS = 64
BUDGET = 1 << 24  # cells the exact tracer visits per call (verify --shadows makes three per view and light)
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def sample_surface(height, uv, tile=True) -> np.ndarray:
    """Bilinear heights (float64 ``(N,)``) of ``height`` at ``uv`` (``(N, 2)``), as GL samples
    it: texel centres at ``(k + 0.5) / n``, REPEAT when tiled, CLAMP_TO_EDGE when not."""
    h = unit_heights(height)
    rows, cols = h.shape
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    x, y = uv[:, 0] * cols - 0.5, uv[:, 1] * rows - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    tx, ty = tile_pair(tile)

    def index(k, n, wrap):
        k = k.astype(np.int64)
        return k % n if wrap else np.clip(k, 0, n - 1)

    i0, i1 = index(x0, cols, tx), index(x0 + 1, cols, tx)
    j0, j1 = index(y0, rows, ty), index(y0 + 1, rows, ty)
    top = h[j0, i0] * (1 - fx) + h[j0, i1] * fx
    bottom = h[j1, i0] * (1 - fx) + h[j1, i1] * fx
    return top * (1 - fy) + bottom * fy


def entry_distance(points, light, tile) -> np.ndarray:
    """float64 ``(N,)``: how far from each point towards the light the ray enters the relief:
    at height 1, or earlier where it leaves uv in [0, 1] through a non-tiled side."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    d = np.asarray(light, np.float64).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        start = np.where(d[:, 2] > 0, np.maximum(1.0 - p[:, 2], 0.0) / d[:, 2], np.inf)
        for axis, tiled in enumerate(tile_pair(tile)):
            if tiled:
                continue
            c = d[:, axis]
            side = np.where(c > 0, 1.0, 0.0)
            e = np.where(c != 0, (side - p[:, axis]) / c, np.inf)
            start = np.minimum(start, np.maximum(e, 0.0))
    return start


def hard_shadows(height, points, light, *, tile=True, tolerance=TOLERANCE) -> np.ndarray:
    """The exact hard answer: is each point lit (see the module doc)?

    Args:
        height (numpy.ndarray): ``(H, W)`` unit heights, as :func:`~csm_assets.trace_heightfield`
            takes them.
        points (numpy.ndarray): ``(N, 3)`` shaded points ``(u, v, height)``.
        light (numpy.ndarray): ``(N, 3)`` or ``(3,)`` unit directions towards the light
            ``(u, v, up)``.
        tile (bool | tuple[bool, bool]): as the map was made.
        tolerance (float): texels a blocker may sit beyond the point (the shader's
            CSM_SHADOW_TOLERANCE).

    Returns:
        Bool ``(N,)``, True where lit. A ray the tracer leaves unresolved (a light grazing
        deep tiled relief) counts as lit.
    """
    return _hard(height, points, light, tile, tolerance)[0]


def _hard(height, points, light, tile, tolerance) -> tuple[np.ndarray, np.ndarray]:
    """(lit, unresolved) bool ``(N,)`` each: :func:`hard_shadows`, and where the exact tracer
    left the light's ray unresolved within its cell budget (lit there is a guess)."""
    h = unit_heights(height)
    p = np.asarray(points, np.float64).reshape(-1, 3)
    d = np.broadcast_to(np.asarray(light, np.float64).reshape(-1, 3), p.shape).copy()
    lit = np.zeros(len(p), bool)
    unknown = np.zeros(len(p), bool)
    up = d[:, 2] > 0
    if not up.any():
        return lit, unknown
    start = entry_distance(p[up], d[up], tile)
    origins = p[up] + d[up] * start[:, None]
    _, t, hit = trace_heightfield(h, origins, -d[up], tile=tile, budget=BUDGET)
    tol = np.maximum(float(tolerance) / max(h.shape), HEIGHT_TOLERANCE / d[up, 2])
    lit[up] = ~hit | (t >= start - tol)
    unknown[up] = np.isnan(t)
    return lit, unknown


def disc_directions(light, world_scale, light_size, rays=SOFT_RAYS) -> np.ndarray:
    """float64 ``(N, rays, 3)``: unit texture-space directions over the light's disc.

    light: ``(N, 3)`` unit texture-space directions to the disc's centre; world_scale:
    ``(3,)`` world length of a unit along u, v and height (the disc is round in world
    space); light_size: the disc's angular radius in radians."""
    s = np.asarray(world_scale, np.float64).reshape(3)
    c = np.asarray(light, np.float64).reshape(-1, 3) * s
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    helper = np.where(np.abs(c[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(c, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(c, e1)
    k = np.arange(int(rays))
    r = float(light_size) * np.sqrt((k + 0.5) / rays)
    phi = k * GOLDEN_ANGLE
    w = (np.cos(r)[None, :, None] * c[:, None, :]
         + (np.sin(r) * np.cos(phi))[None, :, None] * e1[:, None, :]
         + (np.sin(r) * np.sin(phi))[None, :, None] * e2[:, None, :])
    t = w / s
    return t / np.linalg.norm(t, axis=2, keepdims=True)


def soft_shadows(height, points, light, world_scale, light_size, *, tile=True, tolerance=TOLERANCE,
                 rays=SOFT_RAYS) -> np.ndarray:
    """The exact soft answer: the visible share of the light's disc at each point.

    Args:
        height (numpy.ndarray): as for :func:`hard_shadows`.
        points (numpy.ndarray): as for :func:`hard_shadows`.
        light (numpy.ndarray): unit directions to the disc's centre, as for :func:`hard_shadows`.
        world_scale: ``(3,)`` world length of a unit along u, v and height (the disc is round
            in world space).
        light_size (float): the disc's angular radius in radians (0: the hard answer).
        tile (bool | tuple[bool, bool]): as the map was made.
        tolerance (float): as for :func:`hard_shadows`.
        rays (int): rays over the disc per point.

    Returns:
        Float64 ``(N,)`` in ``[0, 1]``.
    """
    p = np.asarray(points, np.float64).reshape(-1, 3)
    d = np.broadcast_to(np.asarray(light, np.float64).reshape(-1, 3), p.shape)
    if not light_size > 0:
        return hard_shadows(height, p, d, tile=tile, tolerance=tolerance).astype(np.float64)
    dirs = disc_directions(d, world_scale, light_size, rays)
    n = dirs.shape[1]
    lit = hard_shadows(height, np.repeat(p, n, axis=0), dirs.reshape(-1, 3), tile=tile, tolerance=tolerance)
    return lit.reshape(-1, n).mean(axis=1)


def edge_band(height, points, light, *, tile=True, tolerance=TOLERANCE, band=1.0, height_band=1.0 / 255.0) -> tuple:
    """The hard answer at each point on the surface, and whether it changes within the edge band.

    A point is in the band when the answer is not the same at the eight points ``band``
    texels away in u, v and the diagonals (on the bilinear surface there), or at the point
    moved ``height_band`` up or down. The height moves catch the terminators where the light
    grazes the surface: there an 8-bit map's precision decides. A point where any of those
    rays is unresolved by the exact tracer (within its cell budget) is in the band too.

    Args:
        height (numpy.ndarray): as for :func:`hard_shadows`.
        points (numpy.ndarray): as for :func:`hard_shadows`.
        light (numpy.ndarray): as for :func:`hard_shadows`.
        tile (bool | tuple[bool, bool]): as the map was made.
        tolerance (float): as for :func:`hard_shadows`.
        band (float): texels.
        height_band (float): unit heights (default one 8-bit step).

    Returns:
        ``(lit, in_band)``: bool ``(N,)`` each.
    """
    h = unit_heights(height)
    rows, cols = h.shape
    p = np.asarray(points, np.float64).reshape(-1, 3)
    d = np.broadcast_to(np.asarray(light, np.float64).reshape(-1, 3), p.shape)
    lit, unknown = _hard(h, p, d, tile, tolerance)
    offsets = [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1) if a or b]
    uv = np.concatenate([p[:, :2] + [a * band / cols, b * band / rows] for a, b in offsets])
    tx, ty = tile_pair(tile)
    if not tx:
        uv[:, 0] = np.clip(uv[:, 0], 0.0, 1.0)
    if not ty:
        uv[:, 1] = np.clip(uv[:, 1], 0.0, 1.0)
    q = np.concatenate([np.column_stack([uv, sample_surface(h, uv, tile)]),
                        p + [0.0, 0.0, height_band], p - [0.0, 0.0, height_band]])
    k = len(offsets) + 2
    around, guessed = _hard(h, q, np.tile(d, (k, 1)), tile, tolerance)
    changes = (around.reshape(k, -1) != lit[None, :]).any(axis=0)
    return lit, changes | unknown | guessed.reshape(k, -1).any(axis=0)
