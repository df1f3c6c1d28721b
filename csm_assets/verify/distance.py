"""``verify --distance``: a step map seen far away, against a supersampled exact reference.

Each view draws the map repeated over a large quad (:func:`distance_view`) so that one pixel at
the image centre spans ``texels_per_pixel`` texels across the screen, with the shipped shader
(the ``exact`` variant: today's march, which reads level 0). The quantity compared is a
linearly filtered one, the N·L of the stored slopes baked per texel (:func:`baked_lighting`):
the shader's image shades it at each pixel's hit (one bilinear sample, as the shader's one
shading fetch of a map without mipmaps), the reference averages it over about one exact ray
per texel² of the pixel (:func:`reference_image`: ``ceil(texels_per_pixel)²`` rays through a
grid of points in the pixel, up to :data:`MAX_SUB`², each traced exactly by
:func:`~csm_assets.verify.trace.trace_heightfield`).

Per view (:class:`MarchStats`): image RMSE and p95 of the absolute difference; flicker, the RMS
change of the image under a half-pixel camera shift over the reference's change; fetches per
pixel (the march's iterations + its first fetch, from the render); cache tiles, the mean number
of 4x4-texel tiles the fetches of an 8x4-pixel block touch (from the CPU emulation of the march,
:func:`~csm_assets.verify.march.march_level` on the pixel's level, whose step count must match the render's:
``same_steps``); and ``through``, the share of pixels whose hit lies more than a texel beyond the
exact first hit of the same ray, past a stretch under the surface at least the minimum step long
(a hard failure for a level-0 march; a thinner tip may be stepped over, :func:`~.march.under_run`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..render.camera import Camera
from ..render.mesh import Mesh, quad
from ..render.renderer import STATUS_MISS, Material, Renderer
from ..step_levels import level_shapes
from .march import march_level, under_run
from .distance_report import DistanceRecord, DistanceReport, MarchStats
from .distance_seams import seam_contrast
from .distance_shading import bilinear, footprint_image, lit_chain, slope_chain
from .stats import BLOCK
from .trace import trace_heightfield
from .views import FOV_DEG, view_camera

TEXELS_PER_PIXEL = (1.0, 4.0, 8.0, 16.0)
ELEVATIONS = (90.0, 45.0, 20.0)
AZIMUTH = 30.0  # off the texture's axes
SIZE = 64  # render side in pixels
QUAD = 2.0  # world side of the quad: it fills the frame at 90 and 45 degrees
MAX_SUB = 16  # reference rays per pixel side at most (one per texel up to 16 texels per pixel)
TILE = 4  # texels per cache tile side
LIGHT = (45.0, 135.0)  # elevation, azimuth in texture space of the light of the baked N·L
FETCHES = 64  # fetches per ray kept for the tile count (rays at distance take 2 to 20)


def distance_views(texels=TEXELS_PER_PIXEL, elevations=ELEVATIONS, azimuth=AZIMUTH) -> list[tuple]:
    """The views ``verify --distance`` draws: every ``texels`` at every elevation.

    Args:
        texels: texels per pixel at the image centre (default 1, 4, 8, 16).
        elevations: degrees above the surface (default 90, 45, 20).
        azimuth: degrees around the surface's normal, one for all.

    Returns:
        ``[(texels_per_pixel, elevation, azimuth)]`` as floats.
    """
    return [(float(t), float(e), float(azimuth)) for e in elevations for t in texels]


@dataclass
class DistanceView:
    """One view of the repeated map: camera, mesh (uvs repeating ``uv_per_world`` per world unit),
    and the world depth of the height range (``depth`` uv units deep in texture space)."""

    texels_per_pixel: float
    elevation: float
    azimuth: float
    camera: Camera
    mesh: Mesh
    uv_per_world: float
    world_depth: float
    size: int
    pixel: float  # world size of a pixel at the camera's target


def distance_view(shape, texels_per_pixel, elevation, azimuth, depth, size=SIZE) -> DistanceView:
    """One view of the map repeated over a quad of side :data:`QUAD`, seen by verify's orbit camera.

    Args:
        shape: the map's ``(H, W, ...)``.
        texels_per_pixel: texels (along the map's longer side) one pixel spans at the image
            centre, across the screen; the uvs repeat the map as often as that takes.
        elevation: degrees above the surface (90: straight on).
        azimuth: degrees around its normal.
        depth: relief depth as a fraction of the texture's width (texture space).
        size: render side in pixels.

    Returns:
        The :class:`DistanceView`: camera, mesh, uv units per world unit, world depth.
    """
    cam = view_camera(0.5, float(elevation), float(azimuth))
    dist = float(np.linalg.norm(np.subtract(cam.eye, cam.target)))
    pixel = 2.0 * dist * math.tan(math.radians(FOV_DEG) / 2) / size
    k = float(texels_per_pixel) / (max(shape[:2]) * pixel)  # uv units per world unit
    m = quad(QUAD)
    mesh = Mesh(m.positions, m.normals, m.tangents, (m.uvs * (k * QUAD)).astype(np.float32), m.indices)
    return DistanceView(float(texels_per_pixel), float(elevation), float(azimuth), cam, mesh, k,
                        float(depth) / k, int(size), pixel)


def shifted(cam: Camera, by: float) -> Camera:
    """``cam`` moved ``by`` world units along its screen's right axis."""
    right = cam.view()[0, :3]
    return Camera(tuple(np.add(cam.eye, by * right)), tuple(np.add(cam.target, by * right)), cam.up, cam.fov_deg,
                  cam.near, cam.far)


def view_rays(view: DistanceView, cam: Camera, depth: float, sub: int):
    """(pixel index int ``(N,)``, dp ``(N, 2)``, unit ds ``(N, 3)``): the texture-space rays (as the
    shader makes them) through a ``sub x sub`` grid of points in each pixel that meet the quad
    from its front."""
    n = view.size * sub
    o, d = cam.rays(n, n)
    t = -o[:, 2] / np.where(d[:, 2] < 0, d[:, 2], -1.0)
    p = o + d * t[:, None]
    half = 0.5 * QUAD
    keep = (d[:, 2] < 0) & (np.abs(p[:, :2]) <= half).all(1)
    rows, cols = np.divmod(np.arange(n * n), n)
    pix = (rows // sub) * view.size + cols // sub
    dp = np.column_stack([p[:, 0] + half, half - p[:, 1]]) * view.uv_per_world
    s = np.column_stack([d[:, 0] * depth, -d[:, 1] * depth, -d[:, 2]])
    return pix[keep], dp[keep], (s / np.linalg.norm(s, axis=1, keepdims=True))[keep]


def baked_lighting(packed, depth: float, light=LIGHT) -> np.ndarray:
    """float64 ``(H, W)``: max(N·L, 0) per texel, N from the stored slopes B/A as surface_frag.glsl
    makes it on a flat polygon with the relief ``depth`` uv units deep, L from ``light``
    (elevation, azimuth in degrees, texture space: u, up the image, out of the surface)."""
    (slopes,) = slope_chain(packed, ())
    return slope_lighting(slopes[..., 0], slopes[..., 1], slopes.shape, depth, light)


def slope_lighting(su, sv, shape, depth: float, light=LIGHT) -> np.ndarray:
    """float64 of ``su``'s shape: :func:`baked_lighting`'s max(N·L, 0) of slopes ``su``, ``sv``
    (B - 0.5, 0.5 - A, stored or filtered) on a map of ``shape`` (H, W) texels."""
    rows, cols = shape[:2]
    gx, gy = np.asarray(su) * cols * depth, np.asarray(sv) * rows * depth
    e, a = np.radians(light[0]), np.radians(light[1])
    lx, ly, lz = np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)
    return np.maximum((-gx * lx - gy * ly + lz) / np.sqrt(gx * gx + gy * gy + 1.0), 0.0)


def reference_image(height, lit, view: DistanceView, cam: Camera, depth: float) -> np.ndarray:
    """float64 ``(size, size)``: per pixel the mean of ``lit`` at the exact hits of about one ray
    per texel² (NaN where no ray meets the quad or none is resolved)."""
    sub = min(max(int(math.ceil(view.texels_per_pixel)), 1), MAX_SUB)
    pix, dp, ds = view_rays(view, cam, depth, sub)
    uv, t, hit = trace_heightfield(height, np.column_stack([dp, np.ones(len(dp))]), ds * [1.0, 1.0, -1.0])
    pix, value = pix[hit], bilinear(lit, uv[hit])
    total = np.bincount(pix, value, view.size ** 2)
    count = np.bincount(pix, minlength=view.size ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / count).reshape(view.size, view.size)


def tiles_per_block(fetched, pix, size, shape, level=None) -> float:
    """Mean over the 8x4-pixel blocks holding a pixel of ``pix`` of the distinct 4x4-texel tiles
    their bilinear fetches (uv ``fetched`` ``(N, F, 2)``, NaN past a ray's last) touch; ``level``:
    int ``(N,)``, the mip level each ray fetched (its texels: GL's mip sizes of ``shape``), None: 0."""
    bw, bh = BLOCK
    uv = fetched.reshape(-1, 2)
    block = np.repeat((pix // size // bh) * size + (pix % size) // bw, fetched.shape[1])
    lev = np.repeat(np.zeros(len(pix), np.int64) if level is None else np.asarray(level, np.int64),
                    fetched.shape[1])
    ok = np.isfinite(uv).all(1)
    uv, block, lev = uv[ok], block[ok], lev[ok]
    shapes = [tuple(shape[:2]), *level_shapes(shape[:2])]
    most = -(-shapes[0][0] // TILE) * -(-shapes[0][1] // TILE)
    keys = []
    for k in np.unique(lev):
        rows, cols = shapes[k]
        sel = lev == k
        x0 = np.floor(uv[sel, 0] * cols - 0.5).astype(np.int64)
        y0 = np.floor(uv[sel, 1] * rows - 0.5).astype(np.int64)
        tx = -(-cols // TILE)
        keys += [(block[sel] * len(shapes) + k) * most + ((y0 + dy) % rows // TILE) * tx
                 + ((x0 + dx) % cols // TILE) for dy in (0, 1) for dx in (0, 1)]
    unique = np.unique(np.concatenate(keys)) if keys else []
    return float(len(unique) / max(len(np.unique(block)), 1))


def measure_today(r: Renderer, packed, height, lit, view: DistanceView, *, max_ratio, min_step, depth,
                  max_iterations=4096, levels=(), refs=None) -> MarchStats:
    """Today's march (``exact`` at level 0) at one view against the reference (see the module doc);
    with ``levels`` (levels 1..n of ``packed``) the chain's march, its image shaded from the
    baked N·L's chain over the pixel's visible footprint (:func:`~.distance_shading.footprint_image`).
    refs: the two reference images (view, shifted) when already made (they are filled in)."""
    mat = Material(packed, max_ratio=max_ratio, depth=view.world_depth, tile=True,
                   uv_per_world=(view.uv_per_world, view.uv_per_world), min_step=min_step, levels=tuple(levels))
    chain = lit_chain(lit) if len(levels) else None
    slopes = slope_chain(packed, levels) if len(levels) else None
    images, refs = [], [] if refs is None else refs
    for k, cam in enumerate((view.camera, shifted(view.camera, 0.5 * view.pixel))):
        res = r.render(mat, cam, variant="exact", mesh=view.mesh, max_iterations=max_iterations)
        ok = res.covered & (res.status != STATUS_MISS)
        if chain is not None:
            img = footprint_image(chain, res, ok, slopes)
        else:
            img = np.full(ok.shape, np.nan)
            img[ok] = bilinear(lit, res.hit_uv[ok])
        images.append(img)
        if len(refs) <= k:
            refs.append(reference_image(height, lit, view, cam, depth))
        if k == 0:
            first, mask = res, ok
    both = mask & np.isfinite(refs[0])
    diff = np.abs(images[0] - refs[0])[both]
    change = [np.nanmean((a[1] - a[0]) ** 2) for a in (images, refs)]
    seam, seam_pairs = seam_contrast(images[0], refs[0], first.lod, both)
    return _march_stats(first, mask, packed, height, view, max_ratio, min_step, max_iterations, levels, dict(
        seam=seam, seam_pairs=seam_pairs, rmse=float(np.sqrt(np.mean(diff ** 2))) if diff.size else 0.0,
        p95=float(np.percentile(diff, 95)) if diff.size else 0.0,
        flicker=float(math.sqrt(change[0] / change[1])) if change[1] > 0 else math.inf))


def _march_stats(res, mask, packed, height, view, max_ratio, min_step, max_iterations, levels,
                 image) -> MarchStats:
    """The counts of the march of ``res`` (the render), over the pixels of ``mask``; each pixel's
    march emulated on the level it marched (``res.lod``: level 0 ``packed``, level k ``levels[k-1]``)."""
    pix = np.flatnonzero(mask.ravel())
    dp, ds = res.ray_uv.reshape(-1, 2)[pix], res.ray_dir.reshape(-1, 3)[pix]
    lod = np.rint(res.lod.ravel()[pix]).astype(np.int64)
    steps, fetched = np.zeros(len(pix), np.int64), np.full((len(pix), FETCHES, 2), np.nan)
    for k in np.unique(lod):
        sel = lod == k
        _, _, steps[sel], fetched[sel] = march_level(
            packed, levels, k, dp[sel], ds[sel], max_ratio=max_ratio, min_step=min_step,
            max_iterations=max_iterations, steps=True, fetches=FETCHES)
    its = res.iterations.ravel()[pix]
    _, t, hit = trace_heightfield(height, np.column_stack([dp, np.ones(len(dp))]), ds * [1.0, 1.0, -1.0])
    rows, cols = height.shape
    ref = dp + ds[:, :2] * np.where(hit, t, 0.0)[:, None]
    off = np.hypot(*((res.hit_uv.reshape(-1, 2)[pix] - ref) * [cols, rows]).T)
    sc = res.ray_t.ravel()[pix]
    beyond = np.flatnonzero(hit & (sc > t) & (off > 1.0))
    through = np.zeros(len(pix), bool)
    step = min_step / max(rows, cols)  # a tip thinner than this may be stepped over
    through[beyond] = under_run(packed, dp[beyond], ds[beyond], t[beyond], sc[beyond], step) >= step
    return MarchStats(**image, fetches=float(np.mean(its + 1)) if its.size else 0.0,
                      tiles=tiles_per_block(fetched, pix, view.size, height.shape, lod),
                      through=float(through.mean()) if its.size else 0.0, pixels=int(its.size),
                      same_steps=float(np.mean(steps == its)) if its.size else 1.0)


def verify_distance(packed, *, max_ratio=1.0, min_step=0.25, depth=0.1, views=None, size=SIZE,
                    source="<array>", progress=None, levels=()) -> DistanceReport:
    """Today's march of a step map far away, and its level chain's, against a supersampled exact
    reference (module doc).

    Args:
        packed: ``(H, W, 4)`` uint8, uint16 or float32 conservative step map; drawn repeated,
            so it should tile.
        max_ratio: the cone ratio G = 1 stands for.
        min_step: the exact variant's minimum step in texels.
        depth: relief depth as a fraction of the texture's width.
        views: ``(texels_per_pixel, elevation, azimuth)`` each; None: :func:`distance_views`.
        size: render side in pixels.
        source: the map's name in the report.
        progress: ``progress("distance", done, total)`` by view, or None.
        levels: the map's chain, levels 1..n (:attr:`~csm_assets.stepmap.StepMap.levels`); when
            given, each record's ``levels`` measures its march (else None).

    Returns:
        A :class:`~csm_assets.verify.distance_report.DistanceReport`, a record per view.

    Raises:
        ValueError: a map that is no packed step map, or settings out of range.
        GLUnavailable: no headless OpenGL context.
    """
    from .maps import prepare

    p, height, _ = prepare(packed, max_ratio, True, depth, min_step)
    lit = baked_lighting(p, depth)
    views = distance_views() if views is None else list(views)
    with Renderer((size, size)) as r:
        report = DistanceReport(str(source), tuple(p.shape[:2]), float(depth), int(size),
                                r.info.get("GL_RENDERER", "?"))
        for done, (tpp, el, az) in enumerate(views):
            if progress:
                progress("distance", done, len(views))
            view = distance_view(p.shape, tpp, el, az, depth, size)
            refs = []
            today = measure_today(r, p, height, lit, view, max_ratio=max_ratio, min_step=min_step, depth=depth,
                                  refs=refs)
            chained = None if not len(levels) else measure_today(
                r, p, height, lit, view, max_ratio=max_ratio, min_step=min_step, depth=depth, levels=levels,
                refs=refs)
            report.views.append(DistanceRecord(view.texels_per_pixel, view.elevation, view.azimuth, today, chained))
    return report
