"""The shading of ``verify --distance``'s level-chain march: the baked N·L fetched as the shader's
``textureGrad`` fetches a mipmapped map, trilinearly from its averaged chain at the level the
polygon's uv footprint gives (:func:`footprint_image`)."""

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


def footprint_image(chain, res, ok) -> np.ndarray:
    """float64 ``(h, w)``: ``chain`` (:func:`lit_chain`) fetched at the hits of render ``res`` with
    the polygon's uv derivatives (from ``res.ray_uv``), over the pixels of ``ok`` (NaN elsewhere)."""
    dx, dy = diffs(res.ray_uv)
    flat = ok.ravel()
    img = np.full(flat.shape, np.nan)
    img[flat] = trilinear(chain, res.hit_uv.reshape(-1, 2)[flat], dx[flat], dy[flat])
    return img.reshape(ok.shape)
