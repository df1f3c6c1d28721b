"""The renderer's textures: step maps and colour maps uploaded to a moderngl context."""

from __future__ import annotations

import numpy as np

from .gl_context import check_texture_size

TEXTURE_DTYPES = {np.dtype(np.uint8): "f1", np.dtype(np.uint16): "nu2", np.dtype(np.float32): "f4"}


def upload(ctx, img, tx: bool, ty: bool, mipmaps: bool = False):
    """A texture of ``img`` (``(H, W, 4)`` uint8, uint16 or float32) in ``ctx``: LINEAR, REPEAT along
    u (``tx``) and v (``ty``) where true, else CLAMP_TO_EDGE. mipmaps: with box-averaged mipmaps and
    LINEAR_MIPMAP_LINEAR, as engines make them (csm.glsl's march still reads level 0). ValueError
    for another shape or dtype; FormatError for a map larger than ``ctx`` samples."""
    import moderngl

    a = np.ascontiguousarray(img)
    if a.ndim != 3 or a.shape[2] != 4 or a.dtype not in TEXTURE_DTYPES:
        raise ValueError(f"a texture must be (H, W, 4) uint8, uint16 or float32, got "
                         f"{a.shape} {a.dtype}")
    check_texture_size(ctx, a.shape, "texture")
    tex = ctx.texture((a.shape[1], a.shape[0]), 4, a.tobytes(), dtype=TEXTURE_DTYPES[a.dtype])
    if mipmaps:
        tex.build_mipmaps()
    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR if mipmaps else moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x, tex.repeat_y = bool(tx), bool(ty)  # False: CLAMP_TO_EDGE
    return tex


def rgba8(img) -> np.ndarray:
    """``img`` (``(H, W, 3 or 4)`` uint8, a colour map) as RGBA (opaque alpha added); ValueError otherwise."""
    a = np.asarray(img)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"color_map must be (H, W, 3 or 4) uint8, got {a.shape} {a.dtype}")
    if a.shape[2] == 3:
        a = np.concatenate([a, np.full(a.shape[:2] + (1,), 255, np.uint8)], axis=2)
    return a
