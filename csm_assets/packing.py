"""The packed RGBA step map of the paper, and its decoder.

Layout (DESIGN.md): R = height; G = sqrt(ratio / max_ratio); B = 0.5 + dh/dx and
A = 0.5 - dh/dy, slopes in height units per texel (x along columns, y along rows,
so A's sign is reversed for OpenGL's v axis). Integer maps round R, B and A to the
nearest step (B and A clipped to [0, 1]) and G down, keeping it at least one step.
"""

from __future__ import annotations

import numpy as np

from .cone_codes import DTYPES, ConeCodes
from .cones.exact import choose_method, exact_ratios
from .cones.pyramid import pyramid_heights
from .cones.quadrant import quadrant_exact
from .cones.relaxed import CONE_KINDS, relaxed_exact
from .cones.remote import remote_ratios
from .heightfield import Heightfield, check_max_ratio, height_levels, tile_pair, unit_heights
from .pack_bands import axis_slope, pack_bands, warn_narrow

MAP_CONES = (*CONE_KINDS, "quadrant")  # what a step map can hold (quadrant: two images)
SAFE_MIN_STEP = 0.25  # the exact variant's minimum step (texels) that goes with bilinear-safe maps


def slopes(h: np.ndarray, tile_x: bool, tile_y: bool) -> tuple[np.ndarray, np.ndarray]:
    """Height change per texel along columns (x) and rows (y) of float ``(H, W)`` ``h``.

    Central differences inside; one-sided at the edges of an axis that does not
    tile; wrapped when it tiles; zero along an axis one texel long.
    """
    return axis_slope(h, 1, tile_x), axis_slope(h, 0, tile_y)


def pack_step_map(h: np.ndarray, ratio: np.ndarray, max_ratio: float, tile_x: bool,
                  tile_y: bool, bits: int = 8, bilinear_safe: bool = False) -> np.ndarray:
    """Pack heights and their exact ratios (float64 ``(H, W)``) into ``(H, W, 4)``.

    h: unit heights (float ``(H, W)``), or the uint8/uint16 codes they stand for.
    bits: 8 (uint8), 16 (uint16) or 32 (float32, unrounded, B and A unclipped).
    bilinear_safe: see :func:`step_map`. Works a band of rows at a time, the bands on threads
    (:mod:`.pack_bands`): beside the output, the temporaries cost a band a thread.
    """
    return _pack(h, [ratio], max_ratio, tile_x, tile_y, bits, bilinear_safe)


def pack_quadrant_maps(h: np.ndarray, quad: np.ndarray, max_ratio: float, tile_x: bool,
                       tile_y: bool, bits: int = 8, bilinear_safe: bool = False) -> np.ndarray:
    """The two images of a quadrant step map, side by side in ``(H, W, 8)``.

    quad: float64 ``(4, H, W)`` quadrant ratios (:func:`csm_assets.quadrant_cone_ratios`'s
    order: +u+v, -u+v, -u-v, +u-v), or four :class:`~csm_assets.cone_codes.ConeCodes` of them. Channels 0..3 are the first image (R height, G, B, A the
    cones of quadrants 0, 1, 2), channels 4..7 the second (R height, G quadrant 3's cone,
    B and A the slopes as in :func:`step_map`). Each cone channel is encoded as G is (and
    gets the bilinear safety pass on its own). h: as for :func:`pack_step_map`.
    """
    return _pack(h, [quad[k] for k in range(4)], max_ratio, tile_x, tile_y, bits, bilinear_safe)


def _pack(h, ratios, max_ratio, tile_x, tile_y, bits, bilinear_safe) -> np.ndarray:
    """:func:`~csm_assets.pack_bands.pack_bands`' map, each cone channel that needs the one-step floor warning once."""
    out, narrow = pack_bands(h, ratios, max_ratio, tile_x, tile_y, bits, bilinear_safe)
    warn_narrow(narrow, bits, max_ratio, stacklevel=4)
    return out


def neighbourhood_min(g: np.ndarray, tile_x: bool, tile_y: bool) -> np.ndarray:
    """The minimum of each texel's 3x3 neighbourhood (wrapped on tiled axes, cut at the
    edges of the others): wherever the GPU samples G bilinearly, it then gets no more than
    the narrowest exact cone of the four texels around the sample."""
    out = g.copy()
    for axis, wrap in ((0, tile_y), (1, tile_x)):
        n = g.shape[axis]
        if n == 1:
            continue
        base = out.copy()
        for shift in (1, -1):
            moved = np.roll(base, shift, axis)
            if not wrap:  # the rolled-in edge line is no neighbour: keep the texel's own
                edge = [slice(None)] * 2
                edge[axis] = 0 if shift == 1 else n - 1
                moved[tuple(edge)] = base[tuple(edge)]
            out = np.minimum(out, moved)
    return out


def step_map(height, *, tile=True, max_ratio=1.0, bits=8, progress=None,
             bilinear_safe=False, cones="conservative") -> np.ndarray:
    """The packed CSM step map of ``height``.

    Args:
        height (numpy.ndarray | Heightfield): uint8, uint16 or float ``(H, W)`` in ``[0, 1]``
            (as for :func:`~csm_assets.cone_ratios`).
        tile (bool | tuple[bool, bool]): wrap distances and slopes around that axis.
        max_ratio (float): the cone ratio that G = 1 stands for (> 0); the shader needs it too.
        bits (int): 8 -> uint8, 16 -> uint16, 32 -> float32.
        progress (Callable | None): ``progress(done_rows, total_rows)``.
        bilinear_safe (bool): a safety pass for the GPU's bilinear sampling: G becomes the
            minimum over each texel's 3x3 neighbourhood, so a sample between texels never gets
            a cone wider than the narrowest exact cone of the four around it. Use it with a
            sub-texel minimum step in ``_exact`` (``min_step`` 0.25).
        cones (str): ``"conservative"`` (for every variant) or ``"relaxed"``
            (:func:`~csm_assets.relaxed_cone_ratios`, for the ``relaxed`` variant only).
            ``"quadrant"`` maps are two images: see :func:`step_maps`.

    Returns:
        ``(H, W, 4)`` of the ``bits``' dtype: R height, G sqrt(ratio/max_ratio) rounded down
        (at least one step), B = 0.5 + dh/dx, A = 0.5 - dh/dy (per texel). Cones are never
        wider than exact (except the one-step floor, which warns).

    Raises:
        ValueError: bad heights, ``max_ratio``, ``bits`` or ``cones``.
    """
    return step_maps(height, tile=tile, max_ratio=max_ratio, bits=bits, progress=progress,
                     bilinear_safe=bilinear_safe, cones=(cones,))[cones]


def step_maps(height, *, tile=True, max_ratio=1.0, bits=8, progress=None, bilinear_safe=False,
              cones=CONE_KINDS, choices=tuple(DTYPES), executor=None) -> dict[str, np.ndarray]:
    """:func:`step_map` of ``height`` for each cone kind in ``cones``, by kind, from one
    conservative cone pass: with both kinds, the relaxed kernel takes the conservative
    ratios as its floor instead of computing them again (the same values). progress:
    called by each pass in turn. Kind ``"quadrant"`` gives the two images of
    :func:`pack_quadrant_maps` as one ``(H, W, 8)`` array. bits: 8, 16, 32, or a function
    ``bits(pack) -> int`` that chooses them once the cones are known, ``pack(bits, kind)``
    giving the packed map of a kind in ``cones`` at those bits (see
    :func:`csm_assets.verify.bits.choose_bits`). choices: the bits such a function may ask for
    (quadrant cones keep their codes for those only: :class:`~csm_assets.cone_codes.ConeCodes`).
    executor: search the cones in bands on it (a Dask cluster's): see :func:`cone_ratio_maps`."""
    if not callable(bits) and bits not in DTYPES:  # before the cones: they take long
        raise ValueError(f"bits must be 8, 16 or 32, got {bits!r}")
    keep = tuple(choices) if callable(bits) else (bits,)
    h, ratios, cap, tx, ty = cone_ratio_maps(height, tile=tile, max_ratio=max_ratio, progress=progress, cones=cones,
                                             keep=keep, executor=executor)

    last = []  # (bits, kind, map, narrow) of a one-image map packed last: the chosen bits' map, not made twice

    def pack(b, kind):
        if last and last[0][:2] == (b, kind):
            p, narrow = last[0][2:]
        else:
            last.clear()  # first: one packed map alive at a time
            planes = [ratios[kind][k] for k in range(4)] if kind == "quadrant" else [ratios[kind]]
            p, narrow = pack_bands(h, planes, cap, tx, ty, b, bilinear_safe)
            if kind != "quadrant":  # the chooser's view of it is itself: kept at no cost
                last.append((b, kind, p, narrow))
        warn_narrow(narrow, b, cap, stacklevel=2)
        return p

    if callable(bits):
        bits = bits(pack)
    if bits not in DTYPES:
        raise ValueError(f"bits must be 8, 16 or 32, got {bits!r}")
    out = {}
    for kind in cones:
        out[kind] = pack(bits, kind)
        if kind not in cones[cones.index(kind) + 1:]:
            ratios.pop(kind, None)  # packed: its ratios (or codes) go
    return out


def _rows_into(a: np.ndarray):
    """A sink ``sink(r0, band)`` that puts bands of rows (along the last axis but one) into ``a``."""
    def sink(r0, band):
        a[..., r0:r0 + band.shape[-2], :] = band
    return sink


def cone_ratio_maps(height, *, tile=True, max_ratio=1.0, progress=None, cones=CONE_KINDS, keep=None,
                    executor=None):
    """(heights, {kind: exact cone ratios (quadrant: :func:`quadrant_exact`'s)}, max_ratio,
    tile_x, tile_y) of ``height`` for each kind in ``cones`` (see :func:`step_maps`); heights:
    the uint8/uint16 codes or float unit heights as given (:func:`~csm_assets.bands.unit_rows`
    reads either as float64). keep: bits (8, 16, 32) to keep the quadrant cones' codes for,
    four :class:`~csm_assets.cone_codes.ConeCodes` made as the search goes (2 or 4 bytes a texel
    each instead of 8); None: their float64 ratios. executor: a ``concurrent.futures`` executor (a
    Dask cluster's) that searches the conservative and quadrant cones in bands of rows
    (:mod:`csm_assets.cones.remote`: the same ratios). Memory: one max pyramid of float64 heights
    (4/3 of 8 bytes a texel) while the conservative and quadrant passes run, freed before the
    relaxed pass."""
    levels = height_levels(height)
    a = np.asarray(height.data if isinstance(height, Heightfield) else height)
    h = a if levels and a.ndim == 2 and a.size else unit_heights(height)  # codes: no float64 copy yet
    codes = a  # validated: the codes, or float heights (unit_rows reads them as unit_heights gives them)
    tx, ty = tile_pair(tile)
    cap = check_max_ratio(max_ratio)
    for kind in cones:
        if kind not in MAP_CONES:
            raise ValueError(f"cones must be one of {', '.join(MAP_CONES)}, got {kind!r}")
    ratios, cons = {}, None
    h, pyramid = pyramid_heights(h)
    if "conservative" in cones or "relaxed" in cones:  # the relaxed pass's floor (progress: its own)
        tell = progress if "conservative" in cones else None
        method = "auto" if executor is None else choose_method(h, tx, ty, cap, pyramid)
        if method in ("auto", "levels"):  # levels: few heights, quick; not banded
            cons = exact_ratios(h, tx, ty, cap, tell, method=method, pyramid=pyramid)
        else:
            cons = np.empty(h.shape)
            remote_ratios(executor, codes, "conservative", _rows_into(cons), tile=(tx, ty), max_ratio=cap,
                          method=method, progress=tell)
    if "quadrant" in cones:
        if keep is None:
            planes = np.empty((4,) + h.shape)
            sink = _rows_into(planes)
        else:
            planes = [ConeCodes(h.shape, cap, keep) for _ in range(4)]

            def sink(r0, q):
                for plane, r in zip(planes, q):
                    plane.add(r0, r)
        if executor is None:
            quadrant_exact(h, tx, ty, cap, progress, pyramid=pyramid, sink=sink)
        else:
            remote_ratios(executor, codes, "quadrant", sink, tile=(tx, ty), max_ratio=cap, progress=progress)
        ratios["quadrant"] = planes
    h = pyramid = None
    if "relaxed" in cones:
        ratios["relaxed"] = relaxed_exact(codes, tx, ty, cap, progress, conservative=cons, levels=levels)
    if "conservative" in cones:
        ratios["conservative"] = cons
    cons = None
    return codes, ratios, cap, tx, ty


def unpack_step_map(packed: np.ndarray, *, max_ratio=1.0) -> dict[str, np.ndarray]:
    """Decode a packed map as the paper's shader does.

    Args:
        packed (numpy.ndarray): ``(H, W, 4)`` uint8 (/255), uint16 (/65535) or float.
        max_ratio (float): the ratio G = 1 stands for (> 0).

    Returns:
        Float64 ``(H, W)`` arrays by name: ``height``, ``ratio`` (= G^2 * max_ratio), ``dhdx``
        and ``dhdy`` (height change per texel along columns and rows).

    Raises:
        ValueError: not ``(H, W, 4)``, or ``max_ratio`` not > 0.
    """
    p = np.asarray(packed)
    if p.ndim != 3 or p.shape[2] != 4:
        raise ValueError(f"a packed step map has shape (H, W, 4), got {p.shape}")
    if p.dtype in (np.uint8, np.uint16):
        p = p.astype(np.float64) / np.iinfo(p.dtype).max
    else:
        p = p.astype(np.float64)
    return {
        "height": p[..., 0],
        "ratio": p[..., 1] ** 2 * check_max_ratio(max_ratio),
        "dhdx": p[..., 2] - 0.5,
        "dhdy": -(p[..., 3] - 0.5),
    }
