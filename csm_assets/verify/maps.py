"""Prove a step map renders right: GPU renders against the exact CPU tracer.

Every draw also writes, per pixel, the texture-space ray the shader starts its
intersection from (its interpolated uv at height 1 and its unit direction, made
from the tangent frame and the view direction: see
:class:`~csm_assets.render.renderer.RenderResult`). Those same rays are traced exactly on
the CPU (:func:`~csm_assets.verify.trace.trace_heightfield`) through the surface the
shader samples (the map's R channel, bilinear), and the shader's hit is compared
with the exact one in texels. Nothing is assumed of the mesh (planar or curved,
any uv layout): the reference is the exact answer to the question each pixel asks.

This module verifies one map on the unit quad (:func:`verify_step_map`,
:func:`verify_file`); :mod:`csm_assets.verify.scene` does whole converted scenes.
Reports are data; the CLI only prints them.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import positive
from ..depth import check_depth
from ..heightfield import check_max_ratio, tile_pair
from ..map_file import load_packed, load_step_maps  # noqa: F401  (load_packed re-exported: verify reads maps with it)
from ..render.gl_context import check_texture_size
from ..render.renderer import MAX_MIN_STEP, VARIANTS, Material, Renderer, quad
from .variants import map_variants
from .bits import chooser
from .stats import VIEW_COLUMNS, block_cost, finite_or_none, format_report, pixel_errors, pixel_stats, view_line
from .reports import VariantReport, VerifyReport, ViewStats  # noqa: F401  (re-exported)
from .trace import trace_heightfield
from .views import DEFAULT_VIEWS, view_camera  # noqa: F401  (re-exported: verify's views live there)

MAX_STEPS = 127
"""The most steps loop, fixed, pom and relief take (fixed unrolls them)."""
STEPS = 16  # their step count when none is given (verify, convert --variant, bench)
STEPPED = ("loop", "fixed", "pom", "relief")  # the variants that take a step count
RELAXED_DEFAULT_STEPS = 2
"""The relaxed variant's binary-search steps in a material when none is given."""
RENDER_SIZE = 128  # render side in pixels: verify, bench trade and convert's pick confirmation


def default_steps(variant: str) -> int:
    """The step count a material of ``variant`` gets when none is given.

    Args:
        variant: a shader variant's name.

    Returns:
        :data:`STEPS` (16) for loop, fixed, pom and relief, :data:`RELAXED_DEFAULT_STEPS` for
        relaxed, 0 for the variants that take none.
    """
    return RELAXED_DEFAULT_STEPS if variant == "relaxed" else STEPS if variant in STEPPED else 0


def map_steps(variant: str, steps: int | None = None) -> int:
    """The step count a map is drawn with in ``variant`` (verify, ``verify --shadows``).

    Args:
        variant: a shader variant's name.
        steps: the step count given, or None.

    Returns:
        ``steps`` when given, else :func:`default_steps` as convert writes it into a material
        (:data:`STEPS` for exact and parallax, which take none: it only labels their report).
    """
    return int(steps) if steps is not None else default_steps(variant) or STEPS


@dataclass
class ViewCase:
    """One view: a camera, the mesh and its model matrix, the heights the shader samples
    (float64 ``(H, W)``) and the tiling. The exact reference of the rays the last draw
    started from is kept, so variants drawn at the same view share it."""

    elevation: float
    azimuth: float
    camera: object
    mesh: object
    height: np.ndarray
    tile: tuple
    model: np.ndarray | None = None
    name: str = ""
    _rays: tuple | None = field(default=None, repr=False)
    _reference: tuple | None = field(default=None, repr=False)

    def reference(self, res) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ref_uv float64 ``(N, 2)``, ref_hit bool ``(N,)``, selected bool ``(N,)``) for the
        rays of ``res`` (N pixels, image order): the exact hits of the rays the shader started
        from. Selected: covered, front-facing (the ray goes down), along a non-tiled axis
        starting inside the map, and resolved by the exact tracer within its cell budget (a ray
        running nearly level through deep tiled relief may not be)."""
        uv0 = res.ray_uv.reshape(-1, 2)
        d = res.ray_dir.reshape(-1, 3)
        if self._rays is not None and np.array_equal(self._rays[0], uv0) and np.array_equal(self._rays[1], d):
            return self._reference
        sel = res.covered.ravel() & np.isfinite(uv0).all(1) & np.isfinite(d).all(1) & (d[:, 2] > 0)
        for axis, tiled in enumerate(self.tile):
            if not tiled:
                sel &= (uv0[:, axis] >= 0.0) & (uv0[:, axis] <= 1.0)
        ref_uv = np.full(uv0.shape, np.nan)
        ref_hit = np.zeros(len(uv0), bool)
        if sel.any():
            o = np.column_stack([uv0[sel], np.ones(int(sel.sum()))])
            dirs = d[sel] * [1.0, 1.0, -1.0]  # the shader's (u, v, down) as (u, v, height)
            ref_uv[sel], t, ref_hit[sel] = trace_heightfield(self.height, o, dirs, tile=self.tile)
            sel[np.flatnonzero(sel)[np.isnan(t)]] = False  # unresolved within the tracer's budget: not compared
        self._rays, self._reference = (uv0.copy(), d.copy()), (ref_uv, ref_hit, sel)
        return self._reference


def quad_view(height, elevation, azimuth, tile) -> ViewCase:
    """A view of :func:`csm_assets.render.renderer.quad` (``height``: float64 ``(H, W)`` in [0, 1])."""
    return ViewCase(float(elevation), float(azimuth), view_camera(0.5, float(elevation), float(azimuth)),
                    quad(), height, tile_pair(tile))


def measure_view(r: Renderer, mat: Material, case: ViewCase, variant, steps, max_iterations, draws=1):
    """Draw one variant at one view and compare with the exact reference of the same rays:
    (RenderResult, ViewStats, per-pixel error image (NaN where not compared), selected bool
    ``(N,)``). draws: see :meth:`Renderer.render`."""
    res = r.render(mat, case.camera, variant=variant, steps=steps, max_iterations=max_iterations,
                   mesh=case.mesh, model=case.model, draws=draws)
    ref_uv, ref_hit, sel = case.reference(res)
    err = pixel_errors(res, ref_uv, ref_hit, sel, case.height.shape)
    stats = pixel_stats(err[sel], res.status.ravel()[sel], res.iterations.ravel()[sel])
    total, blocks = block_cost(res.iterations, sel.reshape(res.status.shape))
    view = ViewStats(case.elevation, case.azimuth, **stats, camera=case.name, block_cost=total / max(blocks, 1),
                     blocks=blocks)
    return res, view, err.reshape(res.status.shape), sel


def verify_step_map(packed, *, max_ratio=1.0, tile=True, variants=("exact",), steps=None,
                    views=DEFAULT_VIEWS, size=RENDER_SIZE, depth=0.1, max_error=1.0, max_iterations=4096,
                    images=None, source="<array>", min_step=1.0, progress=None, second=None) -> VerifyReport:
    """Render a packed map on the unit quad with each variant at each view, against the exact
    tracer.

    Args:
        packed (numpy.ndarray): ``(H, W, 4)`` uint8, uint16 or float32.
        max_ratio (float): the ratio G = 1 stands for.
        tile (bool | tuple[bool, bool]): as the map was made.
        variants (tuple[str, ...]): shader variants to draw.
        steps (int | None): the step count of loop, fixed, pom and relief, the relaxed
            variant's search steps (None: each variant's :func:`map_steps`).
        views: ``(elevation, azimuth)`` degrees.
        size (int): render width and height in pixels.
        depth (float): world depth of the height range under the 1 x 1 quad (texture-space
            depth).
        max_error (float): the budget in texels (p95 at every view).
        max_iterations (int): the cap of the exact variant.
        images (str | os.PathLike | None): a folder for PNGs of every view and
            ``contact_sheet.png``.
        source (str): the map's name, for the report.
        min_step (float): the minimum step in texels (the paper's 1).
        progress: ``progress("drawing VARIANT", done, total)`` by view.
        second (numpy.ndarray | None): a quadrant map's second image, drawn by the quadrant
            variant only (see :func:`map_variants`).

    Returns:
        The VerifyReport.

    Raises:
        ValueError: an unknown variant, a bad step count, depth or max_ratio, or variants the
            map's cones cannot draw.
        GLUnavailable: no OpenGL context.
    """
    check_variants(variants, STEPS if steps is None else steps)
    if second is not None or "quadrant" in variants:
        map_variants("quadrant" if second is not None else "conservative", variants)
    p, height, mat = prepare(packed, max_ratio, tile, depth, min_step, second=second)
    with Renderer((size, size)) as r:
        for image in (p, second):  # refused before any upload
            if image is not None:
                check_texture_size(r.ctx, image.shape, source)
        report = VerifyReport(source=str(source), shape=tuple(p.shape[:2]), dtype=str(p.dtype), tile=mat.tile,
                              max_ratio=mat.max_ratio, depth=float(depth), size=int(size),
                              max_error=float(max_error), renderer=r.info.get("GL_RENDERER", "?"))
        cases = [quad_view(height, el, az, mat.tile) for el, az in views]
        sheet = []
        for variant in variants:
            n = map_steps(variant, steps)
            rep = VariantReport(variant, n if variant in STEPPED or variant == "relaxed" else 0)  # 0: takes none
            for done, case in enumerate(cases):
                if progress:
                    progress(f"drawing {variant}", done, len(cases))
                res, stats, err, _ = measure_view(r, mat, case, variant, n, max_iterations)
                rep.views.append(stats)
                if images is not None:
                    from .images import save_view_images

                    ref_uv, ref_hit, _ = case.reference(res)
                    save_view_images(Path(images), f"{variant}_el{case.elevation:g}_az{case.azimuth:g}", res,
                                     ref_uv.reshape(size, size, 2), ref_hit.reshape(size, size), err)
                    sheet.append((f"{variant}\n{case.elevation:g}/{case.azimuth:g}", res, err))
            report.variants.append(rep)
        if sheet:
            from .images import contact_sheet

            contact_sheet(Path(images) / "contact_sheet.png", sheet, max_error)
    return report


def check_variants(variants, steps) -> None:
    """ValueError for an unknown variant or a step count outside 1..:data:`MAX_STEPS`."""
    for v in variants:
        if v not in VARIANTS:
            raise ValueError(f"unknown variant {v!r}; known: {', '.join(VARIANTS)}")
    if not 1 <= int(steps) <= MAX_STEPS:
        raise ValueError(f"steps must be in 1..{MAX_STEPS} (loop, fixed, pom and relief), got {steps!r}")


def prepare(packed, max_ratio, tile, depth, min_step=1.0, uv_per_world=(1.0, 1.0), second=None, depth_name="depth"):
    """Check a step map and its settings: (packed array, the heights the shader samples
    (float64 ``(H, W)``), the :class:`~csm_assets.render.renderer.Material`); ``min_step`` in
    texels, > 0 and at most :data:`~csm_assets.render.renderer.MAX_MIN_STEP`. second: a
    quadrant map's second image (of the first one's shape and dtype), or None. On the unit
    quad (``uv_per_world`` (1, 1)) ``depth`` is texture-space and must be measurable on the map
    (:func:`csm_assets.depth.check_depth`, an OptionError naming ``depth_name``); scenes check
    their materials' depths themselves (:func:`csm_assets.verify.scene.primitives`)."""
    p = np.asarray(packed)
    if p.ndim != 3 or p.shape[2] != 4 or p.dtype not in (np.uint8, np.uint16, np.float32):
        raise ValueError(f"a packed step map is (H, W, 4) uint8, uint16 or float32, got {p.shape} {p.dtype}")
    if second is not None and (np.shape(second) != p.shape or np.asarray(second).dtype != p.dtype):
        raise ValueError(f"a quadrant map's second image must be {p.shape} {p.dtype} like its first")
    frame = np.asarray(uv_per_world, float)  # a pair, or a 2x2 (a scene's mesh_frame)
    if frame.tolist() == [1.0, 1.0]:
        check_depth(depth, p.shape, depth_name)
    mat = Material(p, max_ratio=check_max_ratio(max_ratio), depth=positive(depth, "depth"), tile=tile_pair(tile),
                   uv_per_world=tuple(frame) if frame.shape == (2,) else frame, min_step=checked_min_step(min_step),
                   step_map2=None if second is None else np.asarray(second))
    return p, sampled_heights(p), mat


def checked_min_step(min_step) -> float:
    """``min_step`` (texels) as a float in (0, MAX_MIN_STEP]; ValueError otherwise."""
    w = positive(min_step, "min_step")
    if w > MAX_MIN_STEP:
        raise ValueError(f"min_step must be at most {MAX_MIN_STEP:g} texels, got {min_step!r}")
    return w


def sampled_heights(p: np.ndarray) -> np.ndarray:
    """The R channel as the GPU samples it (normalized integers, or floats clipped to [0, 1])."""
    r = p[..., 0]
    if p.dtype != np.float32:
        return r.astype(np.float64) / np.iinfo(p.dtype).max
    if not np.isfinite(r).all():
        raise ValueError("the step map's R channel holds NaN or infinite values")
    return np.clip(r.astype(np.float64), 0.0, 1.0)


def verify_file(path, *, invert=False, as_step_map=None, bits=None, max_ratio=None, tile=None, channel=None,
                bilinear_safe=True, min_step=None, variants=None, **kwargs) -> VerifyReport:
    """:func:`verify_step_map` for a file: a step map written by csm-assets (its
    settings come from the file; arguments given here win) or a height map (the
    step map is made with ``bits`` (None: :func:`csm_assets.verify.bits.choose_bits` at the
    ``depth`` and ``views`` verified), ``max_ratio`` (1.0), ``tile`` (True) and, as
    ``convert`` makes them, ``bilinear_safe``). min_step: the exact variant's minimum
    step in texels; default 0.25 for bilinear-safe maps, else the paper's 1. variants: None
    for the map's own (:func:`map_variants`: relaxed for relaxed cones, quadrant for a quadrant
    map, whose second image is read beside it; else exact).

    Args:
        path (str | os.PathLike): a step map or a height map.
        invert (bool): a height map holds depths (white = deep).
        as_step_map (bool | None): True to read a foreign RGBA map as a step map, False to
            force a height map, None to decide by the settings csm-assets stores in its maps
            (an RGBA image without them is refused: see :func:`load_packed`).
        bits (int | None): a height map's step map bits (None: chosen).
        max_ratio (float | None): the cap (None: the file's, else 1.0).
        tile (bool | None): tiling (None: the file's, else True).
        channel (int | str | None): a height map's channel.
        bilinear_safe (bool): a height map's step map gets the safety pass.
        min_step (float | None): the minimum step in texels.
        variants (list[str] | None): the variants to draw (None: the map's own).
        **kwargs: :func:`verify_step_map`'s other arguments.

    Returns:
        The VerifyReport.

    Raises:
        FormatError: an unreadable file, or an RGBA map without settings.
        ValueError: bad arguments, as :func:`verify_step_map`.
    """
    if bits is None:
        defaults = inspect.signature(verify_step_map).parameters
        bits = chooser(kwargs.get("depth", defaults["depth"].default), views=kwargs.get("views", DEFAULT_VIEWS))
    (sm,) = load_step_maps(path, invert=invert, as_step_map=as_step_map, bits=bits, max_ratio=max_ratio,
                           tile=tile, channel=channel, bilinear_safe=bilinear_safe).values()
    s = sm.settings
    return verify_step_map(sm.pixels, max_ratio=s.max_ratio, tile=s.tile, source=Path(path).name,
                           min_step=float(s.min_step if min_step is None else min_step),
                           variants=map_variants(s.cones, variants), second=sm.second, **kwargs)