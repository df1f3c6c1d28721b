"""The ``exact`` variant's cone march on the CPU, to foresee what ``verify`` will measure.

:func:`march_exact` is ``intersect_cone_exact`` of ``shaders/csm.glsl`` step for step (float64
instead of the GPU's float32; bilinear samples of R and G at texel centres, wrapped on tiled
axes, clamped to the edge texels on the others, as ``LINEAR`` filtering with ``REPEAT`` or
``CLAMP_TO_EDGE`` gives them; 8-bit maps filtered in 8-bit fixed point, as verify's renderer
does: :func:`filter_levels`). :func:`quad_error` marches the rays of verify's views of its
unit quad (its cameras' rays, through a coarser image than verify draws) and compares each hit with the exact tracer's on the same map's R
(:func:`~csm_assets.verify.trace.trace_heightfield`), as verify does pixel by pixel: the
p95 texel error it returns is the one verify's renders show, within the spread of its pixels
(tests hold the two side by side), its views on threads. It is what :mod:`csm_assets.verify.bits` chooses bits by.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..heightfield import tile_pair, unit_heights
from ..kernels import CACHE
from ..polling import run_chunks
from .trace import trace_unit
from .views import DEFAULT_VIEWS, view_camera

HIT, CAP, MISS = 0, 1, 2  # csm.glsl's CSM_HIT, CSM_CAP, CSM_MISS
RAYS = 64  # pixels per side of the image of each view whose rays are marched (verify draws 128)
LEVEL_MIN_STEP = 1.5  # csm.glsl's CSM_LEVEL_MIN_STEP: the least minimum step above level 0, in its texels
LEVEL_ACROSS = 0.75  # csm.glsl's CSM_LEVEL_ACROSS: the least a level's minimum step crosses, in its texels
LEVEL_MAX_STEP = 3.0  # csm.glsl's CSM_LEVEL_MAX_STEP: LEVEL_ACROSS's step along the ray at most, in its texels
BUDGET = 1 << 22  # per view: the exact tracer's cells and the march's steps, a few tenths of a second each


def scale_of(packed: np.ndarray) -> float:
    """What a stored value of ``packed`` is divided by as the GPU samples it: 255 or 65535 for
    normalized integers, 1 for floats."""
    return float(np.iinfo(packed.dtype).max) if packed.dtype in (np.uint8, np.uint16) else 1.0


@njit(cache=CACHE)
def _sample(rg, u, v, tx, ty, c, levels, scale):
    rows, cols = rg.shape[0], rg.shape[1]
    x = u * cols - 0.5
    y = v * rows - 0.5
    x0 = math.floor(x)
    y0 = math.floor(y)
    fx = x - x0
    fy = y - y0
    i0 = _wrap(x0, cols, tx)
    i1 = _wrap(x0 + 1, cols, tx)
    j0 = _wrap(y0, rows, ty)
    j1 = _wrap(y0 + 1, rows, ty)
    a, b = float(rg[j0, i0, c]) / scale, float(rg[j0, i1, c]) / scale  # sampled as stored: no float64 copy
    d, e = float(rg[j1, i0, c]) / scale, float(rg[j1, i1, c]) / scale
    if levels > 0:  # the renderer's 8-bit fixed point: weights in 1/256, each lerp rounded
        wx = math.floor(fx * 256.0 + 0.5)
        wy = math.floor(fy * 256.0 + 0.5)
        top = _lerp8(a * levels, b * levels, wx)
        bottom = _lerp8(d * levels, e * levels, wx)
        return _lerp8(top, bottom, wy) / levels
    top = a * (1.0 - fx) + b * fx
    return top * (1.0 - fy) + (d * (1.0 - fx) + e * fx) * fy


@njit(cache=CACHE)
def _wrap(i, n, wrap):
    return int(i % n) if wrap else int(min(max(i, 0), n - 1))


@njit(cache=CACHE)
def _lerp8(a, b, w):
    a, b = math.floor(a + 0.5), math.floor(b + 0.5)  # the stored integers
    return a + math.floor(((b - a) * w + 128.0) / 256.0)


@njit(cache=CACHE)
def _outside(u, v, tx, ty):
    return ((u < 0.0 or u > 1.0) and not tx) or ((v < 0.0 or v > 1.0) and not ty)


@njit(cache=CACHE, nogil=True)
def _march(rg, dp, ds, max_ratio, tx, ty, w, max_iterations, levels, scale, fetched):
    n = dp.shape[0]
    sc_out = np.zeros(n)
    status = np.zeros(n, np.int64)
    steps = np.zeros(n, np.int64)
    cap = fetched.shape[1]  # fetched[k, f]: the uv of ray k's fetch f (its first cap ones); cap 0: none kept
    for k in range(n):
        px, py = dp[k, 0], dp[k, 1]
        dx, dy, dz = ds[k, 0], ds[k, 1], ds[k, 2]
        iz = math.sqrt(max(0.0, 1.0 - dz * dz))
        sc = 0.0
        r = _sample(rg, px, py, tx, ty, 0, levels, scale)
        g = _sample(rg, px, py, tx, ty, 1, levels, scale)
        if cap > 0:
            fetched[k, 0, 0], fetched[k, 0, 1] = px, py
        i = 0
        while True:
            above = 1.0 - dz * sc - r
            if above <= 0.0:
                sc_out[k] = sc - w[k] if i > 0 else sc
                status[k] = HIT
                break
            if i >= max_iterations:
                sc_out[k] = sc
                status[k] = CAP
                break
            ratio = g * g * max_ratio
            sc += w[k] + above * ratio / max(dz * ratio + iz, 1e-30)
            i += 1
            u, v = px + dx * sc, py + dy * sc
            if i < cap:
                fetched[k, i, 0], fetched[k, i, 1] = u, v  # the step's fetch (or the side's, below)
            if _outside(u, v, tx, ty):
                edge = 3.0e38
                if not tx and dx != 0.0:
                    edge = min(edge, ((1.0 if dx > 0.0 else 0.0) - px) / dx)
                if not ty and dy != 0.0:
                    edge = min(edge, ((1.0 if dy > 0.0 else 0.0) - py) / dy)
                edge = max(edge, 0.0)
                if 1.0 - dz * edge <= _sample(rg, px + dx * edge, py + dy * edge, tx, ty, 0, levels, scale):
                    sc_out[k] = min(sc - w[k], edge)
                    status[k] = HIT
                else:
                    sc_out[k] = edge
                    status[k] = MISS
                break
            r = _sample(rg, u, v, tx, ty, 0, levels, scale)
            g = _sample(rg, u, v, tx, ty, 1, levels, scale)
        steps[k] = i
    return sc_out, status, steps


def filter_levels(packed) -> int:
    """The levels of a bilinear sample of ``packed`` on verify's renderer: Mesa llvmpipe filters 8-bit
    textures in 8-bit fixed point (255: weights rounded to 1/256, each lerp rounded to an integer; the
    march then takes the render's step count on every pixel); 16-bit and float ones in float (0)."""
    return 255 if np.asarray(packed).dtype == np.uint8 else 0


def march_exact(packed, dp, ds, *, max_ratio=1.0, tile=True, min_step=1.0, max_iterations=4096, steps=False,
                fetches=0):
    """``intersect_cone_exact`` of csm.glsl for rays starting at uv ``dp`` ``(N, 2)`` at height 1
    along unit ``ds`` ``(N, 3)`` (u, v, down) on step map ``packed`` ``(H, W, 4)`` (its level 0, which
    every march fetch reads). Returns (sc float64 ``(N,)``, status int ``(N,)``: :data:`HIT`,
    :data:`CAP` or :data:`MISS`); with ``steps``, also the iterations int ``(N,)`` (the render's
    count) and the uv of each ray's first ``fetches`` fetches float64 ``(N, fetches, 2)`` (NaN past
    its last: a ray fetches its iterations + 1 times). ``min_step``: texels, one for every ray or
    float ``(N,)``, one a ray."""
    rg = np.ascontiguousarray(packed)  # sampled as stored (no float64 copy of the map): R and G / scale
    tx, ty = tile_pair(tile)
    w = np.broadcast_to(np.asarray(min_step, np.float64) / max(rg.shape[:2]), (len(dp),)).copy()
    fetched = np.full((len(dp), int(fetches), 2), np.nan)
    sc, status, its = _march(rg, np.ascontiguousarray(dp, np.float64), np.ascontiguousarray(ds, np.float64),
                             float(max_ratio), tx, ty, w, int(max_iterations), filter_levels(packed),
                             scale_of(rg), fetched)
    return (sc, status, its, fetched) if steps else (sc, status)


def level_min_step(ds, min_step=1.0) -> np.ndarray:
    """float64 ``(N,)``: the minimum step, in texels of the marched level, of ``intersect_cone_exact``
    on a level above 0 for rays along unit ``ds`` ``(N, 3)``: ``min_step``, :data:`LEVEL_MIN_STEP` and
    a step that crosses :data:`LEVEL_ACROSS` texels of the texture (at most :data:`LEVEL_MAX_STEP`
    along the ray), whichever is the longest."""
    across = np.minimum(LEVEL_ACROSS / np.maximum(np.hypot(ds[:, 0], ds[:, 1]), 1e-6), LEVEL_MAX_STEP)
    return np.maximum(max(min_step, LEVEL_MIN_STEP), across)


def march_level(packed, levels, k, dp, ds, *, min_step=1.0, **kw):
    """:func:`march_exact` as ``intersect_cone_exact`` marches level ``k`` of a chain (csm_lod = k):
    level 0 ``packed`` with ``min_step``, level k >= 1 ``levels[k - 1]`` with :func:`level_min_step`.
    ``kw``: march_exact's."""
    if k == 0:
        return march_exact(packed, dp, ds, min_step=min_step, **kw)
    return march_exact(levels[k - 1], dp, ds, min_step=level_min_step(np.asarray(ds), min_step), **kw)


@njit(cache=CACHE)
def _heights(rg, uv, levels, scale):
    out = np.empty(uv.shape[0])
    for k in range(uv.shape[0]):
        out[k] = _sample(rg, uv[k, 0], uv[k, 1], True, True, 0, levels, scale)
    return out


def under_run(packed, dp, ds, t0, t1, step) -> np.ndarray:
    """float64 ``(N,)``: the longest stretch of ray parameter in ``[t0, t1]`` over which each ray
    (:func:`march_exact`'s) is under the surface the renderer samples from the R of ``packed``
    (tiled; 8-bit maps in fixed point: :func:`filter_levels`), sampled every ``step / 8`` at most."""
    n = int(min(np.max(t1 - t0, initial=0.0) / step * 8.0, 1 << 14)) + 2
    if len(t0) * n > 1 << 22:  # in parts
        return np.concatenate([under_run(packed, dp[k], ds[k], t0[k], t1[k], step)
                               for k in np.array_split(np.arange(len(t0)), 2)])
    rg = np.ascontiguousarray(packed)
    t = t0[:, None] + (t1 - t0)[:, None] * np.linspace(0.0, 1.0, n)
    uv = (dp[:, None, :] + ds[:, None, :2] * t[..., None]).reshape(-1, 2)
    under = _heights(rg, uv, filter_levels(rg), scale_of(rg)).reshape(t.shape) >= 1.0 - ds[:, 2:3] * t
    run = np.zeros(t.shape)
    for k in range(1, n):  # the stretch under the surface ending at sample k
        run[:, k] = np.where(under[:, k] & under[:, k - 1], run[:, k - 1] + t[:, k] - t[:, k - 1], 0.0)
    return run.max(axis=1, initial=0.0)


def view_rays(elevation: float, azimuth: float, depth: float, rays: int):
    """(dp ``(N, 2)``, unit ds ``(N, 3)``): the rays of verify's view of its unit quad
    (:func:`~csm_assets.verify.views.view_camera`) through a ``rays x rays`` image of it, in
    texture space as the shader makes them (relief ``depth`` uv units deep), front-facing
    pixels on the quad only."""
    from ..render.mesh import quad

    o, d = view_camera(0.5, elevation, azimuth).rays(rays, rays)
    t = -o[:, 2] / np.where(d[:, 2] < 0, d[:, 2], -1.0)
    p = o + d * t[:, None]
    corner = quad().positions[0]  # uv (0, 0); u follows +x, v follows -y
    dp = np.column_stack([p[:, 0] - corner[0], corner[1] - p[:, 1]])
    keep = (d[:, 2] < 0) & (dp >= 0).all(1) & (dp <= 1).all(1)
    s = np.column_stack([d[:, 0] * depth, -d[:, 1] * depth, -d[:, 2]])[keep]  # (u, v, -z / depth), scaled
    return dp[keep], s / np.linalg.norm(s, axis=1, keepdims=True)


def quad_error(packed, depth: float, *, views=DEFAULT_VIEWS, max_ratio=1.0, tile=True, min_step=1.0,
               max_iterations=4096, rays: int = RAYS, budget: int = BUDGET) -> float:
    """The worst p95 texel error over ``views`` of the exact variant on ``packed``, against the
    exact hits on its R (rays hitting on one side only count as infinitely far, shared misses
    are left out), as verify measures it on its quad. ``budget`` bounds the work per view: the
    exact tracer's cells (:func:`~csm_assets.verify.trace.trace_heightfield`) and the march's steps
    (``max_iterations`` a ray at most, fewer when the rays' share of ``budget`` is smaller); rays the
    tracer leaves unresolved, or that reach a march cap lowered so, are left out (deep relief only).
    The views run on ``numba.get_num_threads()`` threads (:func:`~csm_assets.polling.run_chunks`)
    against one float64 copy of R's heights (8 bytes a texel)."""
    rows, cols = packed.shape[:2]
    h = np.ascontiguousarray(unit_heights(np.asarray(packed)[..., 0]))  # the tracer's, for every view
    views = list(views)
    worst = np.zeros(len(views))

    def view(k, _):
        dp, ds = view_rays(*views[k], depth, rays)
        steps = min(int(max_iterations), max(int(budget) // max(len(dp), 1), 1))
        sc, status = march_exact(packed, dp, ds, max_ratio=max_ratio, tile=tile, min_step=min_step,
                                 max_iterations=steps)
        ref, t, ref_hit = trace_unit(h, np.column_stack([dp, np.ones(len(dp))]), ds * [1.0, 1.0, -1.0],
                                     *tile_pair(tile), budget=budget)
        known = ~np.isnan(t) & ((status != CAP) | (steps == int(max_iterations)))  # measured within the budget
        hit, ref_hit = (status != MISS)[known], ref_hit[known]
        got, ref = (dp + ds[:, :2] * sc[:, None])[known], ref[known]
        both = hit & ref_hit
        err = np.hypot((got - ref)[both, 0] * cols, (got - ref)[both, 1] * rows)
        err = np.concatenate([err, np.full(int((hit != ref_hit).sum()), np.inf)])
        if err.size:
            worst[k] = float(np.percentile(err, 95, method="higher"))

    run_chunks(view, len(views), np.zeros(len(views), np.uint8), None)
    return float(worst.max(initial=0.0))
