"""``verify --shadows``: the shader's self-shadows against exact shadows, per view and light.

Each view is drawn with self-shadowing on (``CSM_SELF_SHADOW``) and a directional light
at each (elevation, azimuth) of ``lights``; per pixel the shader writes its hard answer
(lit or not), its soft share and its shadow steps. The exact answer
(:mod:`csm_assets.verify.shadow_reference`) is taken at the exact hit of the pixel's view ray
(the same reference :mod:`csm_assets.verify.maps` compares hits with), towards the light's
direction in texture space, computed here from the quad's frame (maps) or, on scenes'
curved meshes, read from the shader with the view ray (a test checks the two on the quad).

Relief pixels: the shader and the exact view ray both hit. Those whose exact answer
changes within one texel (:func:`~csm_assets.verify.shadow_reference.edge_band`) form the edge
band; ``disagreement`` is the share of relief pixels that lie outside the band and whose
hard answer differs (all relief pixels count: on a rough map the band covers nearly all of
them, and a share of the few left would weigh a view ray's miss by hundreds). The soft
term's error is ``|shader soft - exact soft|`` over up to ``soft_pixels`` relief pixels
(a fixed random sample), with the exact soft share from ``soft_rays`` exact rays over the
light's disc. Fetches: texture steps per relief pixel, view and shadow together
(``mean_fetches``) and the shadow's alone.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..checks import non_negative
from ..render.renderer import STATUS_MISS, Renderer
from .maps import (DEFAULT_VIEWS, RENDER_SIZE, STEPS, check_variants, finite_or_none, map_steps, prepare,
                   quad_view)
from .shadow_reference import SOFT_RAYS, TOLERANCE, edge_band, sample_surface, soft_shadows
from .variants import map_variants

LIGHT_ELEVATIONS = (10.0, 30.0, 50.0, 80.0)
LIGHT_AZIMUTHS = (0.0, 120.0, 240.0)
DEFAULT_LIGHTS = tuple((el, az) for el in LIGHT_ELEVATIONS for az in LIGHT_AZIMUTHS)
LIGHT_SIZE = 0.05  # radians: the soft term's default disc (the sun is 0.0047)
MAX_DISAGREEMENT = 0.01
SOFT_PIXELS = 512
PICK_LIGHT = (45.0, 30.0)  # bench trade --shadows' light, and the pick's for self-shadowed materials


@dataclass
class ShadowStats:
    """One view and one light direction (degrees; the light's elevation above the surface)."""

    elevation: float
    azimuth: float
    light_elevation: float
    light_azimuth: float
    pixels: int              # relief pixels
    band_share: float        # of relief pixels, in the one-texel band at exact shadow edges
    lit_share: float         # of relief pixels, lit in the exact answer
    disagreement: float      # of relief pixels: outside the band and the hard answer differs from the exact one
    soft_mean_error: float
    soft_p95_error: float
    soft_pixels: int
    mean_fetches: float      # texture steps per relief pixel: view ray and shadow ray
    mean_shadow_fetches: float
    capped_share: float      # shadow marches stopped by the iteration cap
    camera: str = ""


@dataclass
class ShadowReport:
    """The outcome of :func:`verify_shadows` (and of a scene's).

    Attributes:
        source (str): the map's or scene's name.
        variant (str): the shader variant drawn.
        steps (int): its step count.
        size (int): render side in pixels.
        light_size (float): the light's angular radius in radians (0: hard shadows).
        tolerance (float): the exact answer's height tolerance.
        max_disagreement (float): the budget: share of relief pixels (outside the one-texel
            band at shadow edges) where the shader's hard answer differs from the exact one.
        renderer (str): GL_RENDERER.
        views (list[ShadowStats]): one per view and light.
        problems (list): scenes: primitives that could not be drawn.
        light_source (str): scenes: "" (given), or how the materials' own light sizes were used.
    """

    source: str
    variant: str
    steps: int
    size: int
    light_size: float
    tolerance: float
    max_disagreement: float
    renderer: str
    views: list = field(default_factory=list)
    problems: list = field(default_factory=list)  # scenes: primitives that could not be drawn
    light_source: str = ""  # scenes: "" (given), or how the materials' own light sizes were used

    @property
    def worst(self) -> float:
        """The largest disagreement over views and lights."""
        return max((v.disagreement for v in self.views), default=0.0)

    @property
    def passed(self) -> bool:
        """Something was drawn, nothing failed, and every view and light disagrees on at most
        ``max_disagreement``."""
        return bool(self.views) and not self.problems and self.worst <= self.max_disagreement

    def to_dict(self) -> dict:
        """Plain data for JSON (``--json``), with ``passed`` and ``worst_disagreement``."""
        d = asdict(self)
        d["passed"], d["worst_disagreement"] = self.passed, self.worst
        return finite_or_none(d)


def light_vector(elevation: float, azimuth: float, axis=None) -> np.ndarray:
    """Unit world direction towards a light ``elevation`` degrees above the plane perpendicular
    to ``axis`` at ``azimuth`` around it (as :func:`csm_assets.render.camera.frame_camera` places
    cameras); None: the quad's +z, azimuth 0 along +x (+u), as :func:`orbit_camera` turns."""
    from ..render.camera import frame_camera

    if axis is None:
        e, a = math.radians(elevation), math.radians(azimuth)
        return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    eye = np.asarray(frame_camera((0.0, 0.0, 0.0), axis, elevation, azimuth, 1.0).eye, float)
    return eye / np.linalg.norm(eye)


def quad_light(light_world, depth: float, uv_per_world=(1.0, 1.0)) -> np.ndarray:
    """The texture-space unit direction ``(u, v, up)`` of a world light on
    :func:`csm_assets.render.renderer.quad` (u along +x, v along -y, up +z; heights ``depth`` deep)."""
    lw = np.asarray(light_world, float)
    t = np.array([lw[0] * uv_per_world[0], -lw[1] * uv_per_world[1], lw[2] / depth])
    return t / np.linalg.norm(t)


def measure_shadows(r, mat, case, light_el, light_az, *, variant="exact", steps=STEPS, max_iterations=4096,
                    world_scale, light_tex=None, soft_pixels=SOFT_PIXELS, soft_rays=SOFT_RAYS,
                    tolerance=TOLERANCE, axis=None, pixels=None):
    """Draw ``case`` lit from (light_el, light_az) with self-shadowing and compare with the exact
    shadows: (RenderResult, ShadowStats). light_tex: the texture-space light direction ``(3,)``
    (None: the shader's, per pixel); world_scale: world length of a unit along u, v, height.
    pixels: a dict to receive int8 images (image order) ``exact`` (1 lit, 0 shadowed, -1 not
    relief), ``band`` and ``disagree`` (bool)."""
    from dataclasses import replace

    m = replace(mat, self_shadow=True, light_direction=tuple(light_vector(light_el, light_az, axis)))
    res = r.render(m, case.camera, variant=variant, steps=steps, max_iterations=max_iterations,
                   mesh=case.mesh, model=case.model)
    ref_uv, ref_hit, sel = case.reference(res)
    relief = sel & ref_hit & (res.status.ravel() != STATUS_MISS)
    idx = np.flatnonzero(relief)
    stats = dict(elevation=case.elevation, azimuth=case.azimuth, light_elevation=float(light_el),
                 light_azimuth=float(light_az), camera=case.name)
    shadow = res.shadow.reshape(-1, 4)
    if not idx.size:
        return res, ShadowStats(**stats, pixels=0, band_share=0.0, lit_share=0.0, disagreement=0.0,
                                soft_mean_error=0.0, soft_p95_error=0.0, soft_pixels=0, mean_fetches=0.0,
                                mean_shadow_fetches=0.0, capped_share=0.0)
    uv = ref_uv[idx]
    points = np.column_stack([uv, sample_surface(case.height, uv, case.tile)])
    lt = res.light_dir.reshape(-1, 3)[idx] if light_tex is None else np.asarray(light_tex, float)
    lit, band = edge_band(case.height, points, lt, tile=case.tile, tolerance=tolerance)
    gpu_lit = shadow[idx, 0] > 0.5
    outside = ~band
    disagree = float((gpu_lit != lit)[outside].sum() / idx.size)
    if pixels is not None:
        shape = res.status.shape
        for name, values in (("exact", lit), ("band", band), ("disagree", (gpu_lit != lit) & outside)):
            img = np.full(relief.size, -1 if name == "exact" else 0, np.int8)
            img[idx] = values
            pixels[name] = img.reshape(shape)
    pick = np.random.default_rng(0).permutation(idx.size)[:int(soft_pixels)]
    lt_pick = lt if lt.ndim == 1 else lt[pick]
    ref_soft = soft_shadows(case.height, points[pick], lt_pick, world_scale, mat.light_size, tile=case.tile,
                            tolerance=tolerance, rays=soft_rays)
    err = np.abs(shadow[idx[pick], 1] - ref_soft)
    its = res.iterations.ravel()[idx]
    return res, ShadowStats(**stats, pixels=int(idx.size), band_share=float(band.mean()),
                            lit_share=float(lit.mean()), disagreement=disagree,
                            soft_mean_error=float(err.mean()) if err.size else 0.0,
                            soft_p95_error=float(np.percentile(err, 95)) if err.size else 0.0,
                            soft_pixels=int(err.size), mean_fetches=float(its.mean()),
                            mean_shadow_fetches=float(shadow[idx, 2].mean()),
                            capped_share=float((shadow[idx, 3] == 1).mean()))


def verify_shadows(packed, *, max_ratio=1.0, tile=True, variant="exact", steps=None, views=DEFAULT_VIEWS,
                   lights=DEFAULT_LIGHTS, light_size=LIGHT_SIZE, size=RENDER_SIZE, depth=0.1,
                   max_disagreement=MAX_DISAGREEMENT, max_iterations=4096, min_step=1.0, source="<array>",
                   soft_pixels=SOFT_PIXELS, soft_rays=SOFT_RAYS, images=None, second=None) -> ShadowReport:
    """Self-shadows of a step map on the unit quad at each view and light, against exact shadows.

    Args:
        packed (numpy.ndarray): as for :func:`csm_assets.verify.maps.verify_step_map`.
        max_ratio (float): the ratio G = 1 stands for.
        tile (bool | tuple[bool, bool]): as the map was made.
        variant (str): the shader variant.
        steps (int | None): as :func:`~csm_assets.verify.maps.map_steps` (None: the
            variant's default).
        views: ``(elevation, azimuth)`` degrees of the camera.
        lights: ``(elevation, azimuth)`` degrees of the light.
        light_size (float): the light's angular radius in radians (>= 0; 0: hard shadows).
        size (int): render side in pixels.
        depth (float): texture-space depth.
        max_disagreement (float): the budget (see :class:`ShadowReport`).
        max_iterations (int): the exact variant's cap.
        min_step (float): the minimum step in texels.
        source (str): the map's name, for the report.
        soft_pixels (int): pixels whose soft shadow is checked against the exact one.
        soft_rays (int): rays per pixel of the exact soft answer.
        images (str | os.PathLike | None): a folder for per view and light PNGs (colour,
            exact and shader's hard answer).
        second (numpy.ndarray | None): a quadrant map's second image (the quadrant variant).

    Returns:
        The ShadowReport.

    Raises:
        ValueError: an unknown variant, a bad step count, depth or light size.
        GLUnavailable: no OpenGL context.
    """
    steps = map_steps(variant, steps)
    check_variants([variant], steps)
    light_size = non_negative(light_size, "light size (radians)")
    if second is not None or variant == "quadrant":
        map_variants("quadrant" if second is not None else "conservative", [variant])
    _, height, mat = prepare(packed, max_ratio, tile, depth, min_step, second=second)
    mat.light_size = float(light_size)
    with Renderer((size, size)) as r:
        report = ShadowReport(str(source), variant, int(steps), int(size), float(light_size), TOLERANCE,
                              float(max_disagreement), r.info.get("GL_RENDERER", "?"))
        for el, az in views:
            case = quad_view(height, el, az, mat.tile)
            for lel, laz in lights:
                res, stats = measure_shadows(
                    r, mat, case, lel, laz, variant=variant, steps=steps, max_iterations=max_iterations,
                    world_scale=(1.0, 1.0, depth), light_tex=quad_light(light_vector(lel, laz), depth),
                    soft_pixels=soft_pixels, soft_rays=soft_rays)
                report.views.append(stats)
                if images is not None:
                    save_shadow_image(images, f"shadow_el{el:g}_az{az:g}_light{lel:g}_{laz:g}", res)
    return report


def save_shadow_image(directory, stem: str, res) -> None:
    """``<stem>.png``: the colour image beside the shader's hard answer (white lit)."""
    from pathlib import Path

    from .images import write_png

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    c = np.clip(res.color[..., :3] * 255.0 + 0.5, 0, 255).astype(np.uint8)
    lit = np.repeat((np.clip(res.shadow[..., :1], 0, 1) * 255 + 0.5).astype(np.uint8), 3, axis=2)
    write_png(np.concatenate([c, lit], axis=1), d / f"{stem}.png")


SHADOW_COLUMNS = (f"{'elev':>5} {'azim':>5} {'l_el':>5} {'l_az':>5} {'pixels':>6} {'band':>6} {'lit':>6} "
                  f"{'disagr':>7} {'soft':>6} {'soft95':>6} {'fetch':>6} {'shadow':>6}")


def shadow_line(s: ShadowStats) -> str:
    """One table line of a view and light (see :data:`SHADOW_COLUMNS`)."""
    where = f"{s.camera:>11}" if s.camera else f"{s.elevation:5g} {s.azimuth:5g}"
    return (f"{where} {s.light_elevation:5g} {s.light_azimuth:5g} {s.pixels:6d} {100 * s.band_share:5.1f}% "
            f"{100 * s.lit_share:5.1f}% {100 * s.disagreement:6.2f}% {s.soft_mean_error:6.3f} "
            f"{s.soft_p95_error:6.3f} {s.mean_fetches:6.1f} {s.mean_shadow_fetches:6.1f}")


def light_text(report: ShadowReport) -> str:
    """The light size(s) the report was drawn with, as its header says them."""
    if report.light_source.startswith("per material"):
        return f"light sizes (rad) {report.light_source}"
    return f"light size {report.light_size:g} rad" + (f" ({report.light_source})" if report.light_source else "")


def format_shadow_report(report: ShadowReport) -> str:
    """The text ``verify --shadows`` prints: a header, a line per view and light, the verdict."""
    lines = [f"verify --shadows {report.source}: {report.variant}"
             + (f" {report.steps}" if report.steps and report.variant not in ("exact", "parallax") else "")
             + f", {report.size}x{report.size} px on {report.renderer}; {light_text(report)}, "
             f"tolerance {report.tolerance:g} texel, edge band 1 texel",
             SHADOW_COLUMNS]
    lines += [shadow_line(s) for s in report.views]
    lines += [f"NOT VERIFIABLE: {p}" for p in report.problems]
    verdict = "PASS" if report.passed else "FAIL"
    lines.append(f"{verdict}: worst disagreement {100 * report.worst:.2f}% of relief pixels outside the edge "
                 f"band (budget {100 * report.max_disagreement:g}%)")
    return "\n".join(lines)
