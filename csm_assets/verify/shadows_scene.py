"""``verify --shadows`` on a converted scene: each CSM primitive's self-shadows against exact ones.

Every primitive :mod:`csm_assets.verify.scene` can draw is drawn with self-shadowing from
its automatic views and the scene's cameras, under directional lights placed around the
primitive's mean facing (:func:`csm_assets.verify.shadows.light_vector` with
:func:`csm_assets.verify.views.facing_axis`: elevation above the plane it faces). The
light's texture-space direction is the shader's per pixel (curved meshes turn it), as the
view ray is; :func:`csm_assets.verify.shadows.measure_shadows` does the rest.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..render.mesh import uv_matrix
from ..render.renderer import Renderer
from .maps import DEFAULT_VIEWS, RENDER_SIZE, ViewCase, check_variants
from .shadows import DEFAULT_LIGHTS, LIGHT_SIZE, MAX_DISAGREEMENT, TOLERANCE, ShadowReport, measure_shadows


def verify_scene_shadows(path, *, lights=DEFAULT_LIGHTS, light_size=None, variant=None, steps=None,
                         size=RENDER_SIZE, views=DEFAULT_VIEWS, cameras=True, max_disagreement=MAX_DISAGREEMENT,
                         max_iterations=4096, min_step=None, images=None, loaded=None) -> ShadowReport:
    """The self-shadow report of a converted scene (rows named ``primitive: view``).

    Args:
        path (str | os.PathLike): a converted scene.
        lights: ``(elevation, azimuth)`` degrees of the light, above each primitive's surface.
        light_size (float | None): radians (None: each material's ``lightSize`` where it has
            one, else :data:`~csm_assets.verify.shadows.LIGHT_SIZE`).
        variant (str | None): override the materials' variants.
        steps (int | None): override the materials' step counts.
        size (int): render side in pixels.
        views: ``(elevation, azimuth)`` degrees of the automatic views.
        cameras (bool): also draw from the scene's own cameras.
        max_disagreement (float): the budget (see :class:`~csm_assets.verify.shadows.ShadowReport`).
        max_iterations (int): the exact variant's cap.
        min_step (float | None): override the materials' minimum step, in texels.
        images (str | os.PathLike | None): a folder for PNGs.
        loaded: the scene's :func:`~csm_assets.verify.scene.load_primitives`, when already read.

    Returns:
        The ShadowReport.

    Raises:
        FormatError: an unreadable scene, or nothing in it carries CSM settings.
        ValueError: an unknown variant or a bad step count.
        GLUnavailable: no OpenGL context.
    """
    from .views import auto_views, facing_axis
    from .scene import load_primitives, primitive_material, primitive_variants

    prims, cams = loaded or load_primitives(path)
    with Renderer((size, size)) as r:
        report = ShadowReport(Path(path).name, variant or "each material's variant", int(steps or 0), int(size),
                              LIGHT_SIZE if light_size is None else float(light_size), TOLERANCE,
                              float(max_disagreement), r.info.get("GL_RENDERER", "?"))
        used: dict[float, list] = {}  # light size -> materials drawn with it
        for p in prims:
            if p.mesh is None:
                report.problems.append(f"{p.name}: {p.problem}")
                continue
            s = p.stored
            (v,) = primitive_variants(p, [variant] if variant else None)  # a quadrant map: quadrant only
            n = int(steps or max(s.steps, 1))
            check_variants([v], n)
            height, mat = primitive_material(p, min_step)
            depth = mat.depth
            # world length of a unit along u and v as the shader takes it (surface_frag.glsl: the
            # columns of inverse(uv_per_world), dP/du and dP/dv, in the frame the march uses)
            across = np.linalg.norm(np.linalg.inv(uv_matrix(mat.uv_per_world)), axis=0)
            own = getattr(s, "light_size", None)
            mat.light_size = float(light_size if light_size is not None else own if own else LIGHT_SIZE)
            used.setdefault(mat.light_size, []).append(s.name if own or light_size is not None else f"{s.name}: default")
            axis = facing_axis(p.mesh.positions, p.mesh.normals)
            cases = [ViewCase(el, az, cam, p.mesh, height, mat.tile, name=f"{p.name}: {el:g}/{az:g}")
                     for el, az, cam in auto_views(p.mesh.positions, p.mesh.normals, views)]
            if cameras:
                cases += [ViewCase(math.nan, math.nan, cam, p.mesh, height, mat.tile, p.model, f"{p.name}: {name}")
                          for name, cam in cams]
            for case in cases:
                for lel, laz in lights:
                    res, stats = measure_shadows(r, mat, case, lel, laz, variant=v, steps=n,
                                                 max_iterations=max_iterations, world_scale=(*across, depth),
                                                 axis=tuple(axis))
                    report.views.append(stats)
                    if images is not None:
                        from ..scene import safe_name
                        from .shadows import save_shadow_image

                        save_shadow_image(images, safe_name(f"shadow_{case.name}_light{lel:g}_{laz:g}"
                                                            .replace("/", "_").replace(":", "")), res)
        if light_size is None and used:  # the header says what was drawn: the materials' own sizes
            sizes = sorted(used)
            report.light_size = sizes[0] if len(sizes) == 1 else report.light_size
            report.light_source = ("each material's own lightSize" + (", else the default" if any(
                n.endswith(": default") for ns in used.values() for n in ns) else "")
                if len(sizes) == 1 else "per material: " + ", ".join(
                    f"{v:g} for {', '.join(n.replace(': default', '') for n in used[v])}" for v in sizes))
    return report
