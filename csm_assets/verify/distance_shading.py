"""The shading of ``verify --distance``'s level-chain march: the baked N·L fetched as the shader's
``textureGrad`` fetches a mipmapped map, trilinearly from its averaged chain at the level of the
pixel's visible footprint (:func:`footprint_image`, csm.glsl's ``csm_shading_grads``), far away
at four taps weighted by what the pixel sees of each (``csm_visible_taps``) and blended with its
2x2 pixel quad's neighbours (``csm_quad_share``)."""

from __future__ import annotations

import numpy as np

from ..step_levels import level_shapes, reduce_mean


def lit_chain(lit) -> list[np.ndarray]:
    """float64 ``[(H, W), ...]``: ``lit`` and its area-averaged levels, GL's mip sizes down to 1x1."""
    out = [np.asarray(lit, np.float64)]
    for _ in level_shapes(out[0].shape):
        out.append(reduce_mean(out[-1]))
    return out


def bilinear(field, uv) -> np.ndarray:
    """float64 ``(N,)``: ``field`` ``(H, W)`` sampled bilinearly (wrapped, texel centres at
    ``(i + 0.5) / size``) at uv ``(N, 2)``."""
    rows, cols = field.shape
    x, y = uv[:, 0] * cols - 0.5, uv[:, 1] * rows - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    i0, j0 = x0.astype(np.int64) % cols, y0.astype(np.int64) % rows
    i1, j1 = (i0 + 1) % cols, (j0 + 1) % rows
    top = field[j0, i0] * (1 - fx) + field[j0, i1] * fx
    bottom = field[j1, i0] * (1 - fx) + field[j1, i1] * fx
    return top * (1 - fy) + bottom * fy


def trilinear(chain, uv, duv_dx, duv_dy) -> np.ndarray:
    """float64 ``(N,)``: GL's trilinear ``textureGrad`` of ``chain`` (:func:`lit_chain`) at uv ``(N, 2)``
    with derivatives ``(N, 2)`` each (the level: log2 of the longer axis in level-0 texels)."""
    size = np.array(chain[0].shape[::-1], np.float64)
    rho = np.maximum(np.hypot(*(duv_dx * size).T), np.hypot(*(duv_dy * size).T))
    lod = np.clip(np.log2(np.maximum(rho, 1e-12)), 0.0, len(chain) - 1)
    lo = np.floor(lod).astype(int)
    hi = np.minimum(lo + 1, len(chain) - 1)
    out = np.zeros(len(uv))
    for k in range(len(chain)):
        for sel, w in ((lo == k, 1.0 - (lod - lo)), (hi == k, lod - lo)):
            if sel.any():
                out[sel] += w[sel] * bilinear(chain[k], uv[sel])
    return out


def diffs(a) -> tuple[np.ndarray, np.ndarray]:
    """Forward differences of ``a`` ``(h, w, 2)`` to the right and down (backward at the last), each
    ``(h * w, 2)``: a pixel's uv derivatives across and down the screen."""
    dx = np.concatenate([a[:, 1:] - a[:, :-1], a[:, -1:] - a[:, -2:-1]], axis=1)
    dy = np.concatenate([a[1:] - a[:-1], a[-1:] - a[-2:-1]], axis=0)
    return dx.reshape(-1, 2), dy.reshape(-1, 2)


def slope_chain(packed, levels) -> list[np.ndarray]:
    """float64 ``[(H, W, 2), ...]``: the stored slopes as dh/du, dh/dv per texel (B - 0.5, 0.5 - A)
    of ``packed`` and of its chain ``levels`` (levels 1..n), the mip levels the shader's sampler reads."""
    out = []
    for p in (packed, *levels):
        p = np.asarray(p)
        ba = p[..., 2:4].astype(np.float64) / (np.iinfo(p.dtype).max if p.dtype != np.float32 else 1.0)
        out.append(np.stack([ba[..., 0] - 0.5, 0.5 - ba[..., 1]], axis=-1))
    return out


def _texels(a, size):
    """float64 ``(N,)``: the lengths of uv vectors ``a`` ``(N, 2)`` in texels of a ``size`` (W, H) map."""
    return np.hypot(*(a * size).T)


def _shorter(a, b, size):
    return np.where((_texels(a, size) < _texels(b, size))[:, None], a, b)


FAR_SHARPEN = 0.5  # csm.glsl's CSM_FAR_SHARPEN: levels finer per octave beyond 8 texels a pixel


def _octaves(a, b, size):
    """float64 ``(N,)``: log2 of the shorter of the footprint axes ``a``, ``b`` ``(N, 2)`` in texels."""
    return np.log2(np.maximum(np.minimum(_texels(a, size), _texels(b, size)), 1e-30))


def shading_grad(slopes, uv, ds, duv_dx, duv_dy) -> np.ndarray:
    """float64 ``(N, 2)``: csm.glsl's ``csm_shading_grads``, the shorter axis of the visible footprint
    at hits uv ``(N, 2)`` of rays ds ``(N, 3)`` from the polygon's derivatives ``(N, 2)`` each, the
    surface's slope fetched from ``slopes`` (:func:`slope_chain`) at the polygon's shorter axis;
    beyond 8 texels a pixel along that axis :data:`FAR_SHARPEN` of a level finer per octave (at
    most two)."""
    size = np.array(slopes[0].shape[1::-1], np.float64)
    g = _shorter(duv_dx, duv_dy, size)
    slope = np.column_stack([trilinear([s[..., k] for s in slopes], uv, g, g) for k in (0, 1)]) * size
    below = np.maximum(ds[:, 2] + np.sum(slope * ds[:, :2], axis=1), np.maximum(0.1 * ds[:, 2], 1e-6))
    ax, ay = (d - ds[:, :2] * (np.sum(slope * d, axis=1) / below)[:, None] for d in (duv_dx, duv_dy))
    far = np.clip(np.log2(np.maximum(_texels(g, size), 1e-30)) - 3.0, 0.0, 2.0)  # g: the shorter axis
    return _shorter(ax, ay, size) * np.exp2(-FAR_SHARPEN * far)[:, None]


NORMAL_SHARPEN = 0.5  # csm.glsl's CSM_NORMAL_SHARPEN: near, levels finer than shading_grad the slopes are fetched
TAP_SPREAD = 0.25  # csm.glsl's CSM_TAP_SPREAD: the taps' distance from the hit along each footprint axis
TAP_SHRINK = 0.5  # csm.glsl's CSM_TAP_SHRINK: each tap's footprint, in the shading footprint's


def tap_spread(duv_dx, duv_dy, size) -> np.ndarray:
    """float64 ``(N,)``: csm.glsl's ``csm_tap_spread`` of the polygon's derivatives ``(N, 2)`` each
    on a map of ``size`` (W, H) texels: 0 at 2 texels a pixel or fewer, 1 at 4 or more."""
    return np.clip(_octaves(duv_dx, duv_dy, size) - 1.0, 0.0, 1.0)


def visible_taps(slopes, uv, ds, g, spread, weighted=True):
    """csm.glsl's ``csm_visible_taps`` at hits uv ``(N, 2)`` of rays ds ``(N, 3)`` in the shading
    footprint of gradient ``g`` ``(N, 2)`` (:func:`shading_grad`; the other axis ``g`` turned a right
    angle in texels), spread ``(N,)`` (:func:`tap_spread`): ``(taps, gt, slope)``, ``taps`` four
    ``(uv (N, 2), weight (N,))`` (weights sum to 1: each tap's projected area max(ds.z + grad h .
    ds.xy, 0) from its slopes, alike where none faces the eye, or with ``weighted`` False always:
    ``benchmarks/distance_taps.py``'s comparison), ``gt`` ``(N, 2)`` each tap's gradient, ``slope``
    ``(N, 2)`` the weighted stored slopes (B - 0.5, 0.5 - A)."""
    size = np.array(slopes[0].shape[1::-1], np.float64)
    across = np.column_stack([-g[:, 1] * size[1] / size[0], g[:, 0] * size[0] / size[1]])
    spread = np.asarray(spread, np.float64)[:, None]
    a, b = g * TAP_SPREAD * spread, across * TAP_SPREAD * spread
    gt = g * (1.0 + (TAP_SHRINK - 1.0) * spread)
    gs = g * (2.0 ** -NORMAL_SHARPEN + (TAP_SHRINK - 2.0 ** -NORMAL_SHARPEN) * spread)
    points = [uv - a - b, uv + a - b, uv - a + b, uv + a + b]
    fetched = [np.column_stack([trilinear([s[..., c] for s in slopes], p, gs, gs) for c in (0, 1)]) for p in points]
    w = np.column_stack([np.maximum(ds[:, 2] + np.sum(t * size * ds[:, :2], axis=1), 0.0) if weighted
                         else np.ones(len(uv)) for t in fetched])
    total = w.sum(axis=1, keepdims=True)
    w = np.where(total > 1e-12, w / np.where(total > 1e-12, total, 1.0), 0.25)
    slope = sum(w[:, [i]] * t for i, t in enumerate(fetched))
    return list(zip(points, w.T)), gt, slope


def tapped(chain, taps, gt) -> np.ndarray:
    """float64 ``(N,)``: csm.glsl's ``csm_tapped``, ``chain`` (:func:`lit_chain`) fetched at the taps
    of :func:`visible_taps` (``taps``, ``gt``)."""
    return sum(w * trilinear(chain, p, gt, gt) for p, w in taps)


QUAD_SHARE = 0.2  # csm.glsl's CSM_QUAD_SHARE: from 4 to 8 texels a pixel
QUAD_SHARE_FAR = 0.2  # csm.glsl's CSM_QUAD_SHARE_FAR: at 16 or more


def quad_weight(duv_dx, duv_dy, size, shares=None) -> np.ndarray:
    """float64 ``(N,)``: csm.glsl's ``csm_quad_weight`` of the polygon's derivatives ``(N, 2)`` each
    on a map of ``size`` (W, H) texels: 0 at 2 texels a pixel or fewer, :data:`QUAD_SHARE` from 4 to
    8, :data:`QUAD_SHARE_FAR` at 16 or more (linear in log2 of the texels between); ``shares``:
    another (near, far) pair than the shader's (the benchmarks' comparisons)."""
    near, far_share = (QUAD_SHARE, QUAD_SHARE_FAR) if shares is None else shares
    octaves = _octaves(duv_dx, duv_dy, size)
    far = np.clip(octaves - 3.0, 0.0, 1.0)
    return (near + (far_share - near) * far) * np.clip(octaves - 1.0, 0.0, 1.0)  # tap_spread's ramp


def quad_share(img, weight) -> np.ndarray:
    """float64 ``(h, w)``: csm.glsl's ``csm_quad_share`` of ``img`` ``(h, w)`` (h and w even) with
    per-pixel ``weight`` ``(h, w)``, derivatives per pixel: each pixel plus ``weight`` times the
    differences to its 2x2 quad's neighbours across and down (its own value where one is NaN)."""
    across, down = img[:, np.arange(img.shape[1]) ^ 1], img[np.arange(img.shape[0]) ^ 1]
    return img + weight * (np.where(np.isfinite(across), across, img) - img
                           + np.where(np.isfinite(down), down, img) - img)


def footprint_image(chain, res, ok, slopes) -> np.ndarray:
    """float64 ``(h, w)``: ``chain`` (:func:`lit_chain`) fetched at the hits of render ``res`` as the
    shader fetches it: at :func:`visible_taps` in :func:`shading_grad`'s footprint from the polygon's
    uv derivatives (from ``res.ray_uv``) and ``slopes`` (:func:`slope_chain`), then blended with its
    pixel quad's neighbours (:func:`quad_share`), over the pixels of ``ok`` (NaN elsewhere)."""
    dx, dy = diffs(res.ray_uv)
    flat = ok.ravel()
    uv, ds = res.hit_uv.reshape(-1, 2)[flat], res.ray_dir.reshape(-1, 3)[flat]
    size = np.array(slopes[0].shape[1::-1], np.float64)
    g = shading_grad(slopes, uv, ds, dx[flat], dy[flat])
    taps, gt, _ = visible_taps(slopes, uv, ds, g, tap_spread(dx[flat], dy[flat], size))
    img = np.full(flat.shape, np.nan)
    img[flat] = tapped(chain, taps, gt)
    weight = quad_weight(dx, dy, size)
    return quad_share(img.reshape(ok.shape), weight.reshape(ok.shape))
