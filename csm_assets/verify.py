"""Prove a step map renders right: GPU renders against the exact CPU tracer.

For each view (straight down to grazing) and each shader variant, the quad is
rendered with the step map, the same pixels' rays are traced exactly
(:func:`~csm_assets.trace.trace_heightfield_world`) through the surface the
shader samples (the map's R channel, bilinear), and the hit points are compared
in texels. Reports are data (:class:`VerifyReport`); the CLI only prints them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .heightfield import check_max_ratio, tile_pair
from .packing import SAFE_MIN_STEP
from .render import (
    STATUS_CAP,
    STATUS_MISS,
    VARIANTS,
    Material,
    Renderer,
    orbit_camera,
    quad_field_to_world,
)
from .trace import rays_to_field, trace_heightfield_world

# (elevation, azimuth) in degrees: 90 looks straight down, 10 grazes
DEFAULT_VIEWS = ((90.0, 0.0), (70.0, 30.0), (50.0, 120.0), (35.0, 200.0), (20.0, 290.0), (10.0, 45.0))


@dataclass
class ViewStats:
    """One variant at one view. Errors are texture-space distances in texels between
    the render's hit and the reference's, over pixels where either hits (inf where
    only one of them hits; a shared miss counts as agreement, not as an error)."""

    elevation: float
    azimuth: float
    pixels: int               # pixels compared (polygon covered, ray enters the map)
    mean_error: float         # over pixels where both hit
    p95_error: float
    max_error: float
    wrong_share: float        # more than one texel away, or hit/miss disagree
    nonconverged_share: float  # stopped by the iteration cap / still moving
    mean_iterations: float
    max_iterations: int


@dataclass
class VariantReport:
    variant: str
    steps: int
    views: list = field(default_factory=list)

    @property
    def worst_p95(self) -> float:
        return max((v.p95_error for v in self.views), default=0.0)


@dataclass
class VerifyReport:
    """The outcome of :func:`verify_step_map`: passed when every view's p95 error of
    every variant is at most ``max_error`` texels."""

    source: str
    shape: tuple
    dtype: str
    tile: tuple
    max_ratio: float
    depth: float
    size: int
    max_error: float
    renderer: str
    variants: list = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(v.worst_p95 <= self.max_error for v in self.variants)

    def to_dict(self) -> dict:
        """Plain data for JSON: infinite errors (a pixel hit where the other missed) become null."""
        d = asdict(self)
        d["passed"] = self.passed
        for v, rep in zip(d["variants"], self.variants):
            v["worst_p95"] = rep.worst_p95
        return _finite_or_none(d)


@dataclass
class Surface:
    """A planar mesh to verify on: ``mesh`` in a frame where it lies in z = 0 facing +z,
    centred on the origin; ``field_to_world`` maps texture space (u, v, height) there;
    ``uv_box`` (u0, v0, u1, v1) is the uv domain it covers; ``radius`` its size."""

    mesh: object
    field_to_world: np.ndarray
    uv_box: tuple
    uv_per_world: tuple
    radius: float


def quad_surface(depth: float) -> Surface:
    """The 1 x 1 quad of :func:`csm_assets.render.quad`, uv [0, 1]²."""
    from .render import quad

    return Surface(quad(), quad_field_to_world(1.0, depth), (0.0, 0.0, 1.0, 1.0), (1.0, 1.0), 0.5)


def verify_step_map(packed, *, max_ratio=1.0, tile=True, variants=("exact",), steps=16,
                    views=DEFAULT_VIEWS, size=96, depth=0.1, max_error=1.0, max_iterations=4096,
                    images=None, source="<array>", surface: Surface | None = None,
                    min_step=1.0) -> VerifyReport:
    """Render ``packed`` (``(H, W, 4)`` uint8, uint16 or float32) with each variant at each view.

    depth: world depth of the height range (under a 1 x 1 quad unless ``surface``).
    size: render width and height in pixels. steps: the step count of loop,
    fixed, pom and relief. images: a directory to write PNGs into (see
    :func:`csm_assets.verify_images.save_view_images`), or None. surface: the
    planar mesh to draw (default the unit quad; see :func:`verify_scene`). min_step:
    the exact variant's minimum step in texels (the paper's 1).
    """
    for v in variants:
        if v not in VARIANTS:
            raise ValueError(f"unknown variant {v!r}; known: {', '.join(VARIANTS)}")
    p, height, mat, surface = prepare(packed, max_ratio, tile, depth, surface, min_step)
    tx, ty = mat.tile
    with Renderer((size, size)) as r:
        report = VerifyReport(source=str(source), shape=tuple(p.shape[:2]), dtype=str(p.dtype), tile=(tx, ty),
                              max_ratio=mat.max_ratio, depth=float(depth), size=int(size),
                              max_error=float(max_error), renderer=r.info.get("GL_RENDERER", "?"))
        cases = [reference_view(height, surface, el, az, size, (tx, ty)) for el, az in views]
        for variant in variants:
            rep = VariantReport(variant, int(steps))
            for case in cases:
                res, stats, err = measure_view(r, mat, case, variant, steps, max_iterations)
                rep.views.append(stats)
                if images is not None:
                    from .verify_images import save_view_images

                    save_view_images(Path(images), f"{variant}_el{case.elevation:g}_az{case.azimuth:g}", res,
                                     case.ref_uv.reshape(size, size, 2), case.ref_hit.reshape(size, size), err)
            report.variants.append(rep)
    return report


@dataclass
class ViewCase:
    """One view of a surface with its exact reference, shared by every variant drawn there.

    ref_uv: float64 ``(N, 2)`` reference hits (N = size², image order); ref_hit, enters:
    bool ``(N,)`` (the reference hits; the ray crosses the polygon inside the uv box)."""

    elevation: float
    azimuth: float
    camera: object
    surface: Surface
    ref_uv: np.ndarray
    ref_hit: np.ndarray
    enters: np.ndarray
    shape: tuple  # the height map's (rows, cols)


def view_camera(surface: Surface, elevation: float, azimuth: float):
    """The camera of a view: orbiting the surface, near enough at grazing views to fill the frame."""
    return orbit_camera(elevation, azimuth, 2 * surface.radius * _distance(elevation), fov_deg=40.0)


def reference_view(height, surface: Surface, elevation, azimuth, size, tile) -> ViewCase:
    """Trace the exact reference of one view (``height``: float64 ``(H, W)`` in [0, 1], the surface
    the shader samples; ``tile``: pair of bools)."""
    cam = view_camera(surface, float(elevation), float(azimuth))
    o, d = cam.rays(size, size)
    ref_uv, _, ref_hit = trace_heightfield_world(height, o, d, surface.field_to_world, tile=tile)
    enters = _enters_map(o, d, surface.field_to_world, surface.uv_box)
    return ViewCase(float(elevation), float(azimuth), cam, surface, ref_uv, ref_hit, enters, height.shape)


def measure_view(r: Renderer, mat: Material, case: ViewCase, variant, steps, max_iterations, draws=1):
    """Draw one variant at one view and compare with the reference: (RenderResult, ViewStats,
    per-pixel error image (NaN where not compared)). draws: see :meth:`Renderer.render`."""
    res = r.render(mat, case.camera, variant=variant, steps=steps, max_iterations=max_iterations,
                   mesh=case.surface.mesh, draws=draws)
    err, sel = _pixel_errors(res, case)
    stats = pixel_stats(err[sel], res.status.ravel()[sel], res.iterations.ravel()[sel])
    return res, ViewStats(case.elevation, case.azimuth, **stats), err.reshape(res.status.shape)


def prepare(packed, max_ratio, tile, depth, surface: Surface | None = None, min_step=1.0):
    """Check a step map and its settings: (packed array, the heights the shader samples
    (float64 ``(H, W)``), the :class:`~csm_assets.render.Material`, the surface)."""
    p = np.asarray(packed)
    if p.ndim != 3 or p.shape[2] != 4 or p.dtype not in (np.uint8, np.uint16, np.float32):
        raise ValueError(f"a packed step map is (H, W, 4) uint8, uint16 or float32, got {p.shape} {p.dtype}")
    if not (depth > 0 and math.isfinite(depth)):
        raise ValueError(f"depth must be a finite number > 0, got {depth!r}")
    surface = surface or quad_surface(float(depth))
    mat = Material(p, max_ratio=check_max_ratio(max_ratio), depth=float(depth), tile=tile_pair(tile),
                   uv_per_world=surface.uv_per_world, min_step=float(min_step))
    return p, _heights(p), mat, surface


def _heights(p: np.ndarray) -> np.ndarray:
    """The R channel as the GPU samples it (normalized integers, or floats clipped to [0, 1])."""
    r = p[..., 0]
    if p.dtype != np.float32:
        return r.astype(np.float64) / np.iinfo(p.dtype).max
    if not np.isfinite(r).all():
        raise ValueError("the step map's R channel holds NaN or infinite values")
    return np.clip(r.astype(np.float64), 0.0, 1.0)


def _distance(elevation: float) -> float:
    """Camera distance: near enough at grazing views that the quad fills some of the frame."""
    return 1.0 + 0.8 * math.sin(math.radians(elevation))


def _enters_map(o, d, field_to_world, uv_box=(0.0, 0.0, 1.0, 1.0)) -> np.ndarray:
    """bool (N,): the ray crosses the polygon (height 1) inside the uv box (u0, v0, u1, v1)."""
    fo, fd = rays_to_field(o, d, field_to_world)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (1.0 - fo[:, 2]) / fd[:, 2]
    uv = fo[:, :2] + t[:, None] * fd[:, :2]
    lo, hi = np.asarray(uv_box[:2]), np.asarray(uv_box[2:])
    return (t > 0) & np.all((uv >= lo) & (uv <= hi), axis=1)


def _pixel_errors(res, case: ViewCase):
    """(err float (N,), sel bool (N,)): texel distance of the render's hit from the reference's
    (inf where only one hits, NaN where not compared or both miss); sel: the compared pixels
    (polygon covered, ray enters the map)."""
    rows, cols = case.shape
    status = res.status.ravel()
    sel = res.covered.ravel() & case.enters
    gpu_hit = sel & (status != STATUS_MISS)
    both = gpu_hit & case.ref_hit
    one = sel & (gpu_hit != case.ref_hit)
    err = np.full(status.shape, np.nan)
    diff = (res.hit_uv.reshape(-1, 2)[both] - case.ref_uv[both]) * [cols, rows]
    err[both] = np.hypot(diff[:, 0], diff[:, 1])
    err[one] = np.inf
    return err, sel


def pixel_stats(err, status, iterations) -> dict:
    """The :class:`ViewStats` numbers over compared pixels (one view, or several pooled).

    err: float ``(N,)`` texels (inf: only one side hit; NaN: both missed, an agreement);
    status: int ``(N,)`` render status; iterations: int ``(N,)``."""
    err = np.asarray(err, np.float64)
    e = err[~np.isnan(err)]
    finite = err[np.isfinite(err)]
    n = int(err.size)
    return dict(
        pixels=n,
        mean_error=float(finite.mean()) if finite.size else 0.0,
        p95_error=float(np.percentile(e, 95, method="higher")) if e.size else 0.0,
        max_error=float(e.max()) if e.size else 0.0,
        wrong_share=float((e > 1.0).sum() / n) if n else 0.0,
        nonconverged_share=float((np.asarray(status) == STATUS_CAP).mean()) if n else 0.0,
        mean_iterations=float(np.mean(iterations)) if n else 0.0,
        max_iterations=int(np.max(iterations)) if n else 0,
    )


def _finite_or_none(x):
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_or_none(v) for v in x]
    return x


def format_report(report: VerifyReport) -> str:
    """The report as a text table."""
    ty, tx = report.shape
    lines = [f"verify {report.source}: {tx}x{ty} {report.dtype}, tile {list(report.tile)}, max_ratio "
             f"{report.max_ratio:g}, depth {report.depth:g}, {report.size}x{report.size} px on "
             f"{report.renderer}",
             f"{'variant':8} {'steps':>5} {'elev':>5} {'azim':>5} {'pixels':>6} {'mean':>7} {'p95':>7} "
             f"{'max':>7} {'wrong':>6} {'nonconv':>7} {'iters':>6} {'max_it':>6}"]
    for v in report.variants:
        for s in v.views:
            lines.append(f"{v.variant:8} {v.steps:5d} {s.elevation:5g} {s.azimuth:5g} {s.pixels:6d} "
                         f"{s.mean_error:7.3f} {s.p95_error:7.3f} {s.max_error:7.2f} "
                         f"{100 * s.wrong_share:5.1f}% {100 * s.nonconverged_share:6.1f}% "
                         f"{s.mean_iterations:6.1f} {s.max_iterations:6d}")
    verdict = "PASS" if report.passed else "FAIL"
    lines.append(f"{verdict}: worst p95 error " + ", ".join(
        f"{v.variant} {v.worst_p95:.3f}" for v in report.variants) + f" texels (budget {report.max_error:g})")
    return "\n".join(lines)


def verify_file(path, *, invert=False, as_step_map=None, bits=8, max_ratio=None, tile=None, channel=None,
                bilinear_safe=True, min_step=None, **kwargs) -> VerifyReport:
    """:func:`verify_step_map` for a file: a step map written by csm-assets (its
    settings come from the file; arguments given here win) or a height map (the
    step map is made with ``bits``, ``max_ratio`` (1.0), ``tile`` (True) and, as
    ``convert`` makes them, ``bilinear_safe``). min_step: the exact variant's minimum
    step in texels; default 0.25 for bilinear-safe maps, else the paper's 1.

    as_step_map: True to read a foreign RGBA map as a step map, False to force a
    height map, None to decide by the settings csm-assets stores in its maps.
    """
    packed, mr, tl, min_step = load_packed(path, invert=invert, as_step_map=as_step_map, bits=bits,
                                           max_ratio=max_ratio, tile=tile, channel=channel,
                                           bilinear_safe=bilinear_safe, min_step=min_step)
    return verify_step_map(packed, max_ratio=mr, tile=tl, source=Path(path).name, min_step=min_step, **kwargs)


def load_packed(path, *, invert=False, as_step_map=None, bits=8, max_ratio=None, tile=None, channel=None,
                bilinear_safe=True, min_step=None):
    """(packed map, max_ratio, tile, exact's min_step) of a file, as :func:`verify_file` reads it."""
    from .formats import load_heightfield, read_step_map, read_step_map_meta
    from .packing import step_map

    meta = {} if as_step_map is False else read_step_map_meta(path)
    if as_step_map or meta:
        packed = read_step_map(path)
        mr = max_ratio if max_ratio is not None else float(meta.get("max_ratio", 1.0))
        tl = tile if tile is not None else tuple(meta.get("tile", (True, True)))
        safe = bool(meta.get("bilinear_safe", False))
    else:
        hf = load_heightfield(path, channel=channel, invert=invert).normalized()
        mr = 1.0 if max_ratio is None else max_ratio
        tl = True if tile is None else tile
        safe = bilinear_safe
        packed = step_map(hf.exact_heights(), tile=tl, max_ratio=mr, bits=bits, bilinear_safe=safe)
    if min_step is None:
        min_step = SAFE_MIN_STEP if safe else 1.0
    return packed, mr, tl, float(min_step)


def verify_scene(path, **kwargs) -> list[VerifyReport]:
    """Verify a converted glTF/GLB scene: each primitive carrying the CSM extension is
    drawn as it is in the file (its positions, normals, TANGENT and uvs) with its step
    map, depth and tiling, and compared with the exact tracer. Primitives must be planar
    with an affine uv map (walls, floors, decals), where the heightfield is exact; others
    raise ValueError. Options as for :func:`verify_step_map`."""
    from .formats import gltf
    from .formats import gltf_container as gc

    doc = gc.load(path)
    reports = []
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            m = prim.get("material")
            ext = doc.json["materials"][m].get("extensions", {}).get(gltf.EXTENSION) if m is not None else None
            if ext is None:
                continue
            image = doc.json["images"][doc.json["textures"][ext["stepMapTexture"]["index"]]["source"]]
            packed = _step_map_of(doc, image)
            surface, world_depth = _planar_surface(doc, prim, ext, f"{path}: mesh {mi} primitive {pi}")
            kwargs.setdefault("min_step", ext.get("minStep", 1.0))
            reports.append(verify_step_map(packed, max_ratio=ext.get("maxRatio", 1.0), tile=tuple(ext["tile"]),
                                           depth=world_depth, surface=surface,
                                           source=f"{Path(path).name} mesh {mi} primitive {pi}", **kwargs))
    if not reports:
        raise ValueError(f"{path}: no primitive carries {gltf.EXTENSION}; convert the scene first")
    return reports


def _step_map_of(doc, image) -> np.ndarray:
    """The packed map a glTF image holds: a file beside the scene or bytes in the GLB."""
    from .formats import gltf_container as gc
    from .formats import read_step_map
    from .scene import Texture

    if "uri" in image:
        texture = Texture("step_map", path=Path(doc.path).parent / image["uri"])
    else:
        texture = Texture("step_map", data=gc.view_bytes(doc, image["bufferView"]), mime=image.get("mimeType"))
    with texture.as_file() as file:
        return read_step_map(file)


def _planar_surface(doc, prim, ext, name) -> tuple[Surface, float]:
    """The primitive moved to z = 0 facing +z, and the world depth of its relief."""
    from .formats import gltf_container as gc
    from .render import Mesh

    attrs = prim["attributes"]
    tc = ext["stepMapTexture"].get("texCoord", 0)
    pos = gc.read_accessor(doc, attrs["POSITION"]).astype(np.float64)
    nrm = gc.read_accessor(doc, attrs["NORMAL"]).astype(np.float64)
    tan = gc.read_accessor(doc, attrs["TANGENT"]).astype(np.float64)
    uv = gc.read_accessor(doc, attrs[f"TEXCOORD_{tc}"]).astype(np.float64)
    idx = (gc.read_accessor(doc, prim["indices"])[:, 0] if "indices" in prim else np.arange(len(pos)))
    # world = origin + U u + V v must hold at every vertex (affine uvs on a plane)
    a = np.column_stack([np.ones(len(uv)), uv])
    coef, *_ = np.linalg.lstsq(a, pos, rcond=None)
    origin, U, V = coef
    n = np.cross(U, V)
    extent = np.ptp(pos, axis=0).max()
    if np.abs(a @ coef - pos).max() > 1e-4 * max(extent, 1e-9) or np.linalg.norm(n) == 0:
        raise ValueError(f"{name}: not planar with an affine uv map; verify needs such primitives")
    n /= np.linalg.norm(n)
    if np.mean(nrm @ n) < 0:  # the side the normals face
        n = -n
    world_depth = ext["depthScale"] * float(np.sqrt(np.linalg.norm(np.cross(U, V))))
    centre = pos.mean(axis=0)
    x = U / np.linalg.norm(U)
    frame = np.stack([x, np.cross(n, x), n])  # rows: the local axes, z = the normal
    local = (pos - centre) @ frame.T
    f2w = np.eye(4)
    f2w[:3, 0], f2w[:3, 1] = frame @ U, frame @ V
    f2w[:3, 2] = [0.0, 0.0, world_depth]
    f2w[:3, 3] = frame @ (origin - centre) - np.array([0.0, 0.0, world_depth])
    mesh = Mesh(local.astype(np.float32), (nrm @ frame.T).astype(np.float32),
                np.column_stack([tan[:, :3] @ frame.T, tan[:, 3]]).astype(np.float32),
                uv.astype(np.float32), idx.reshape(-1, 3).astype(np.uint32))
    box = (*uv.min(axis=0), *uv.max(axis=0))
    surface = Surface(mesh, f2w, box, (1 / np.linalg.norm(U), 1 / np.linalg.norm(V)),
                      float(np.linalg.norm(local, axis=1).max()))
    return surface, world_depth
