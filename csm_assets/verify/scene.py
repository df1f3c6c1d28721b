"""Verify a converted scene (glTF, GLB, OBJ, USD) as each of its materials will render.

The scene is read with the same readers as ``convert``, and each material's CSM
settings are read back (:mod:`csm_assets.formats.csm_material`). Every primitive
with a CSM material is drawn with the shipped GLSL, its own positions, normals,
tangents (OBJ stores none: MikkTSpace makes them, as docs/guides/engine.md asks a consumer to)
and uvs, from automatic views around it (:mod:`csm_assets.verify.views`) and from
the scene's cameras, with the variant and step count the material was converted
with (``variants``/``steps`` override). Each pixel's shader ray is traced exactly
(:class:`csm_assets.verify.maps.ViewCase`), so curved meshes and any uv layout are
verified. A primitive that cannot be drawn (no normals, no tangents, no area) is
reported as not verifiable, and the scene does not pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..depth import too_deep
from ..errors import FormatError
from ..formats.registry import scene_module
from ..printable import printable
from ..render.gl_context import check_texture_size
from ..render.mesh import mesh_frame, uv_scale  # noqa: F401  (re-exported: exporters use them)
from ..render.renderer import Mesh as RenderMesh, Renderer
from ..levels_file import read_levels
from ..udim import parts
from .converted import read_converted  # noqa: F401 (the verify API)
from .images import save_case_images, unique_stem
from .maps import (DEFAULT_VIEWS, RENDER_SIZE, VIEW_COLUMNS, ViewCase, check_variants, measure_view, prepare,
                   view_line)
from .reports import PrimitiveReport, SceneReport, VariantReport
from .stats import fit, steps_text
from .variants import map_variants

LABEL_WIDTH = 64  # characters of "primitive / material" in the table; longer ones keep start and end


NO_PIXELS = ("no pixel of its relief could be measured at any view (uvs outside [0, 1] on an axis that "
             "does not tile? rays there miss)")


@dataclass
class Primitive:
    """What is drawn: a render mesh (or the reason there is none), its material's settings,
    the packed step map and the primitive's world matrix (for the scene's cameras).
    uv_per_world: the mesh's uv units per world unit (render.mesh.uv_scale: its relief is
    depthScale / uv_per_world deep); frame: the 2x2 the march uses (render.mesh.mesh_frame)."""

    name: str
    stored: object            # csm_material.StoredCsm
    packed: np.ndarray
    mesh: RenderMesh | None
    problem: str = ""
    model: np.ndarray | None = None
    uv_per_world: float = 1.0
    packed2: np.ndarray | None = None  # a quadrant map's second image
    levels: tuple = ()  # the level chains of packed and packed2 (levels 1..n each; not a UDIM set's), checked
    frame: np.ndarray | None = None  # None where mesh is None


def render_mesh(mesh, *, generate_tangents: bool):
    """(render Mesh as corner arrays, None) of a scene Mesh, or (None, why it cannot be drawn).
    uvs become glTF's (v down); tangents: generated ones, stored ones, or MikkTSpace's when
    ``generate_tangents`` (formats that store none)."""
    if mesh.normals is None:
        return None, "no normals: the shader needs a tangent frame (add normals, then convert again)"
    if mesh.uvs is None:
        return None, "no uvs"
    f = np.asarray(mesh.faces, np.int64)
    if mesh.corner_tangents is not None:
        tangents = np.asarray(mesh.corner_tangents, np.float64).reshape(-1, 4)
    elif mesh.tangents is not None:
        tangents = np.asarray(mesh.tangents, np.float64)[f].reshape(-1, 4)
    elif generate_tangents:
        from ..tangents.frames import mikktspace_tangents

        n = np.asarray(mesh.normals, np.float64)
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        tangents = mikktspace_tangents(mesh.positions, n, mesh.uvs, f,
                                       flip_v=mesh.uv_origin == "top-left").reshape(-1, 4)
    else:
        return None, "no tangents: convert the scene again to write them"
    uvs = np.asarray(mesh.uvs, np.float64)
    if mesh.uv_origin == "bottom-left":
        uvs = uvs * [1.0, -1.0] + [0.0, 1.0]
    arrays = [np.asarray(mesh.positions, np.float64)[f].reshape(-1, 3),
              np.asarray(mesh.normals, np.float64)[f].reshape(-1, 3), tangents, uvs[f].reshape(-1, 2)]
    if not all(np.isfinite(a).all() for a in arrays):
        return None, "non-finite positions, normals, tangents or uvs"
    if not len(f):
        return None, "no triangles"
    idx = np.arange(3 * len(f), dtype=np.uint32).reshape(-1, 3)
    return RenderMesh(*(a.astype(np.float32) for a in arrays), idx), None


def primitives(scene, stored: dict, models: dict, *, generate_tangents: bool, maps=None) -> list[Primitive]:
    """The drawable primitives of a scene whose materials ``stored`` describes (by ref).
    maps: ``{step map texture key: packed}`` shared between calls (read once each)."""
    maps = {} if maps is None else maps
    out = []
    for mesh, s, lacks in parts(scene.meshes, stored):  # a UDIM set's mesh: a part per tile
        packed, second = (_read_map(t, maps) for t in (s.step_map, s.step_map2))
        if second is not None and (second.shape, second.dtype) != (packed.shape, packed.dtype):
            raise FormatError(s.step_map2.path or scene.path, f"material {s.name!r}: the second step map image is "
                                                              f"{second.shape} {second.dtype}, not {packed.shape} "
                                                              f"{packed.dtype} as the first")
        levels = () if s.tiles else tuple(_read_levels(t, packed, maps, s.name, scene.path) for t in s.levels)
        rmesh, problem = (None, lacks) if lacks else render_mesh(mesh, generate_tangents=generate_tangents)
        k, frame = (uv_scale(rmesh), mesh_frame(rmesh)) if rmesh is not None else (0.0, None)
        if rmesh is not None and (k == 0.0 or frame is None):
            rmesh, problem = None, "no triangle with both world and uv area (and a tangent off its normal)"
        if rmesh is not None and too_deep(s.depth_scale, packed.shape):
            rmesh, problem = None, f"depthScale: {too_deep(s.depth_scale, packed.shape)}"
        ref = mesh.ref
        model = models.get(ref[0] if isinstance(ref, tuple) else str(getattr(ref, "path", ref)))
        out.append(Primitive(mesh.name, s, packed, rmesh, problem or "", model, k, second, levels,
                             frame if rmesh is not None else None))
    return out


def _read_map(texture, maps: dict):
    """The packed pixels of a step map image (None for no texture), read once into ``maps``."""
    from ..formats import read_step_map

    if texture is None:
        return None
    key = texture.path or id(texture.data)
    if key not in maps:
        with texture.as_file() as file:
            maps[key] = read_step_map(file)
    return maps[key]


def _read_levels(texture, packed, maps: dict, material: str, scene_path) -> tuple:
    """Levels 1..n of step map ``packed`` cut from its levels image ``texture``, read once into
    ``maps`` (:func:`csm_assets.levels_file.read_levels`: a FormatError naming the image and what
    was expected when it is not the documented size and type)."""
    key = ("levels", texture.path or id(texture.data), packed.shape, str(packed.dtype))
    if key not in maps:
        maps[key] = tuple(read_levels(texture, packed.shape, packed.dtype, f"material {material!r}", scene_path))
    return maps[key]


def verify_primitives(prims, *, source="<scene>", variants=None, steps=None, size=RENDER_SIZE, views=DEFAULT_VIEWS,
                      cameras=(), max_error=1.0, max_iterations=4096, images=None, min_step=None,
                      renderer=None, progress=None) -> SceneReport:
    """Draw each primitive with each variant (default: its material's) at the automatic
    ``views`` around it and from ``cameras`` (``[(name, Camera)]``), against the exact tracer.
    steps: override the materials' step counts. images: a directory for PNGs and the
    contact sheet. renderer: an open :class:`Renderer` of ``size`` to reuse.
    progress: ``progress("drawing", done, total)`` by view, per primitive. variants: None, a
    list or "all" (:func:`primitive_variants`)."""
    from .views import auto_views

    for p in prims:  # every refusal before any drawing
        check_variants(primitive_variants(p, variants), steps or max(p.stored.steps, 1))
    own = renderer is None
    r = renderer or Renderer((size, size))
    try:
        for p in (p for p in prims if p.mesh is not None):  # refused before any upload
            check_texture_size(r.ctx, p.packed.shape, p.stored.step_map.path or source)
        report = SceneReport(str(source), int(size), float(max_error), r.info.get("GL_RENDERER", "?"),
                             [f"{el:g}/{az:g}" for el, az in views] + [name for name, _ in cameras])
        sheet, stems = [], set()
        for p in prims:
            stem = unique_stem(p.name, stems)
            s = p.stored
            rep = PrimitiveReport(p.name, s.name, s.step_map.name, tuple(p.packed.shape[:2]), str(p.packed.dtype),
                                  s.depth_scale, s.max_ratio, tuple(s.tile), float(min_step or s.min_step),
                                  problem=p.problem)
            report.primitives.append(rep)
            if p.mesh is None:
                continue
            height, mat = primitive_material(p, rep.min_step)
            cases = [ViewCase(el, az, cam, p.mesh, height, mat.tile)
                     for el, az, cam in auto_views(p.mesh.positions, p.mesh.normals, views)]
            cases += [ViewCase(math.nan, math.nan, cam, p.mesh, height, mat.tile, p.model, name)
                      for name, cam in cameras]
            for variant in primitive_variants(p, variants):
                n = int(steps or max(s.steps, 1))
                vrep = VariantReport(variant, 0 if variant in ("exact", "parallax") else n)
                for done, case in enumerate(cases):
                    if progress:
                        progress(f"drawing {p.name} {variant}", done, len(cases))
                    res, stats, err, _ = measure_view(r, mat, case, variant, n, max_iterations)
                    vrep.views.append(stats)
                    if images is not None:
                        sheet.append(save_case_images(Path(images), p.name, stem, variant, case, res, err,
                                                      size))
                rep.variants.append(vrep)
            if not any(v.pixels for vr in rep.variants for v in vr.views):
                rep.problem = NO_PIXELS
        if images is not None and sheet:
            from .images import contact_sheet

            contact_sheet(Path(images) / "contact_sheet.png", sheet, max_error)
    finally:
        if own:
            r.close()
    return report


def primitive_material(p: Primitive, min_step=None) -> tuple:
    """(the heights the shader samples, float64 ``(H, W)``; the Material) of a drawable primitive
    as verify draws it: marched in its mesh's frame (:attr:`Primitive.frame`, the engines' dP/du,
    dP/dv: sheared where the placement shears), depthScale / uv_per_world world units deep.
    min_step: texels (None: the material's)."""
    s = p.stored
    _, height, mat = prepare(p.packed, s.max_ratio, s.tile, max(s.depth_scale, 1e-6) / p.uv_per_world,
                             float(min_step or s.min_step), p.frame, second=p.packed2)
    return height, mat


def load_primitives(path):
    """``(primitives, cameras)`` of the converted scene at ``path``, as verify draws them;
    FormatError when nothing in it carries CSM settings."""
    scene, stored, cams, models = read_converted(path)
    prims = primitives(scene, stored, models, generate_tangents=not scene_module(path).STORES_TANGENTS)
    if not prims:
        raise FormatError(path, "no mesh uses a CSM material (nothing to verify)")
    return prims, cams


def verify_scene(path, *, variants=None, steps=None, size=RENDER_SIZE, views=DEFAULT_VIEWS, cameras=True,
                 max_error=1.0, max_iterations=4096, images=None, min_step=None, loaded=None,
                 progress=None) -> SceneReport:
    """Verify a converted scene: every CSM primitive against the exact tracer (see the
    module docstring).

    Args:
        path (str | os.PathLike): a converted .gltf, .glb, .obj or USD scene.
        variants (list[str] | str | None): None (each material's own variant), a list, or
            ``"all"``.
        steps (int | None): override the materials' step counts.
        size (int): render side in pixels.
        views: ``(elevation, azimuth)`` degrees of the automatic views around each primitive.
        cameras (bool): also draw from the scene's own cameras.
        max_error (float): the budget in texels (p95 at every view).
        max_iterations (int): the cap of the exact variant.
        images (str | os.PathLike | None): a folder for PNGs and the contact sheet.
        min_step (float | None): override the materials' minimum step, in texels.
        loaded: its :func:`load_primitives`, when already read.
        progress: ``progress("drawing", done, total)`` by view, per primitive.

    Returns:
        The SceneReport.

    Raises:
        FormatError: an unreadable scene, or nothing in it carries CSM settings.
        ValueError: an unknown variant or a step count outside 1..127.
        GLUnavailable: no OpenGL context.
    """
    prims, cams = loaded or load_primitives(path)
    return verify_primitives(prims, source=Path(path).name, variants=variants, steps=steps, size=size,
                             views=views, cameras=cams if cameras else (), max_error=max_error,
                             max_iterations=max_iterations, images=images, min_step=min_step, progress=progress)


def format_scene_report(report: SceneReport) -> str:
    """The report as a text table: one block per primitive and variant."""
    labels = [printable(f"{p.name} / {p.material}") for p in report.primitives]
    width = min(max([32, *map(len, labels)]), LABEL_WIDTH)  # as wide as the names, to a point
    lines = [f"verify {report.source}: {report.size}x{report.size} px on {report.renderer}; views "
             f"{' '.join(report.views)}",
             f"{'primitive / material':{width}} {'variant':8} {'steps':>5} {VIEW_COLUMNS}"]
    for p, label in zip(report.primitives, labels):
        label = fit(label, width)
        if p.problem:
            lines.append(f"{label:{width}} NOT VERIFIABLE: {p.problem}")
            continue
        for v in p.variants:
            for s in v.views:
                lines.append(f"{label:{width}} {v.variant:8} {steps_text(v.steps):>5} {view_line(s)}")
    bad = [p for p in report.primitives if not p.passed(report.max_error)]
    unverified = sum(1 for p in bad if p.problem)
    worst = max((p.worst_p95 for p in report.primitives if not p.problem), default=math.nan)
    verdict = "PASS" if report.passed else "FAIL"
    worst_text = f"{worst:.3f} texels" if math.isfinite(worst) else "n/a"
    lines.append(f"{verdict}: {len(report.primitives)} primitive(s), worst p95 error {worst_text} (budget "
                 f"{report.max_error:g}); {len(bad) - unverified} over budget, {unverified} not verifiable"
                 + (f"; to fix: {report.fix}" if report.fix and not report.passed else ""))
    return "\n".join(lines)


def primitive_variants(p, variants) -> list[str]:
    """:func:`~csm_assets.verify.variants.map_variants` of primitive ``p``'s map (quadrant when it has a
    second image; None: its material's variant)."""
    return map_variants("quadrant" if p.packed2 is not None else "conservative", variants, p.stored.variant)
