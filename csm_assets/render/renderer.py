"""Headless renders with the project's shaders: the one owner of the GL context (:class:`Renderer`).
:func:`quad`'s world conventions: :mod:`csm_assets.render.mesh`."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..heightfield import check_max_ratio, tile_pair
from .camera import Camera, orbit_camera  # noqa: F401  (re-exported)
from .gl_context import GLUnavailable, check_texture_size, open_context  # noqa: F401  (re-exported)
from .glsl import shader_source
from .mesh import Mesh, quad, quad_field_to_world, uv_matrix  # noqa: F401  (re-exported)
from .textures import rgba8, upload

VARIANTS = {
    "exact": "intersect_cone_exact", "loop": "intersect_cone_loop",
    "fixed": "intersect_cone_fixed", "parallax": "intersect_parallax",
    "pom": "intersect_pom", "relief": "intersect_relief", "relaxed": "intersect_cone_relaxed",
    "quadrant": "intersect_cone_quadrant", "exact_interp": "intersect_cone_exact_interp",
}
STATUS_HIT, STATUS_CAP, STATUS_MISS, STATUS_EMPTY = 0, 1, 2, -1


MAX_MIN_STEP = 16.0
"""Texels: csm.glsl's CSM_MAX_MIN_STEP (materials hold (0, 1]; benchmarks sweep above)."""
ATTACHMENTS = 5  # colour, hit, info, the ray each pixel starts (uv, direction)
SHADOW_ATTACHMENTS = 7  # and light, shadow (made on the first self-shadowed draw)


class GLError(RuntimeError):
    """OpenGL reported an error (``ctx.error``) or a shader failed to build."""


@dataclass
class Material:
    """A step map and how to draw it.

    step_map: ``(H, W, 4)`` uint8, uint16 or float32 (packing.py's layout).
    max_ratio: the cone ratio G = 1 stands for. depth: world depth of the height
    range (heights 1..0 lie 0..depth under the polygon). tile: bool or pair.
    uv_per_world: texture units per world unit along tangent and bitangent, a pair; or a
    2x2 m, ``(u, v) = m @ (along t, along b)``, where u, v are sheared (mesh.uv_frame).
    color_map: optional ``(h, w, 3 or 4)`` uint8 colour texture.
    """

    step_map: np.ndarray
    max_ratio: float = 1.0
    depth: float = 0.1
    tile: object = True
    uv_per_world: tuple = (1.0, 1.0)
    color_map: np.ndarray | None = None
    min_step: float = 1.0  # texels (the paper's 1; 0.25 bilinear-safe; <= MAX_MIN_STEP)
    ambient: tuple = (0.2, 0.2, 0.2, 1.0)
    diffuse: tuple = (0.8, 0.8, 0.8, 1.0)
    light: tuple = (1.0, 1.0, 2.0)
    light_direction: tuple = (0.0, 0.0, 0.0)  # world, towards a directional light; zero: the point light
    self_shadow: bool = False  # draw with CSM_SELF_SHADOW (csm.glsl's csm_shadow)
    light_size: float = 0.0  # the light's angular radius, radians (0: hard shadows)
    step_map2: np.ndarray | None = None  # a quadrant map's second image (the quadrant variant's)
    mipmaps: bool = False  # step maps with averaged mipmaps, as engines make them (the march reads level 0)
    levels: tuple = ()  # the step map's chain (levels 1..n, GL's mip sizes) uploaded as its mips; the march picks one
    levels2: tuple = ()  # step_map2's chain


@dataclass
class RenderResult:
    """Images in image order (row 0 on top), shape ``(h, w, ...)``.

    color: float32 RGBA; hit_uv: float64 ``(h, w, 2)`` (not wrapped); hit_height:
    float64 (1 = top); ray_t: the shader's ray parameter; iterations: int32 (with
    self-shadowing, the shadow's steps too); status: int8 (0 hit, 1 stopped by the cap /
    not converged, 2 left a non-tiled texture, -1 no polygon); view_depth: float32 depth
    of the hit along the view axis (world units, as Rayshade's zbuf).
    ray_uv, ray_dir: float64 ``(h, w, 2)``, ``(h, w, 3)``: the texture-space ray the shader
    started from (uv at height 1, unit direction (u, v, down)).
    """

    color: np.ndarray
    hit_uv: np.ndarray
    hit_height: np.ndarray
    ray_t: np.ndarray
    iterations: np.ndarray
    status: np.ndarray
    view_depth: np.ndarray
    ray_uv: np.ndarray | None = None
    ray_dir: np.ndarray | None = None
    light_dir: np.ndarray | None = None  # self_shadow: float64 (h, w, 3) unit light direction (u, v, up)
    shadow: np.ndarray | None = None  # self_shadow: float64 (h, w, 4) hard lit, soft, shadow steps, status
    variant: str = ""
    lod: np.ndarray | None = None  # float64 (h, w): the level each pixel marched (csm_march_lod)
    draw_s: float = 0.0  # seconds of the fastest draw alone (ctx.finish() around it)

    @property
    def covered(self) -> np.ndarray:
        """bool ``(h, w)``: pixels the polygon covers."""
        return self.status != STATUS_EMPTY


class Renderer:
    """Owns the headless GL context; use as a context manager or call :meth:`close`.

    EGL (Mesa llvmpipe without a GPU); images in image order (row 0 on top).

    Args:
        size (tuple[int, int]): ``(width, height)`` of the images in pixels.

    Attributes:
        ctx (moderngl.Context): the context.

    Raises:
        ValueError: size < 1 or too big.
        GLError: no render targets (GLUnavailable: no context).
    """

    def __init__(self, size=(128, 128)):
        self.width, self.height = (int(size[0]), int(size[1]))
        if self.width < 1 or self.height < 1:
            raise ValueError(f"render size must be positive, got {size!r}")
        self.ctx = open_context()
        self._programs: dict = {}
        self._fbos: dict = {}  # attachments -> framebuffer
        self.check_errors("creating the context")
        try:
            largest = min(int(self.ctx.info["GL_MAX_RENDERBUFFER_SIZE"]), *self.ctx.info["GL_MAX_VIEWPORT_DIMS"])
            if max(self.width, self.height) > largest:
                raise ValueError(f"render size {self.width}x{self.height} is larger than this OpenGL "
                                 f"({self.ctx.info.get('GL_RENDERER', '?')}) can draw: at most {largest} pixels "
                                 f"a side")
            self._framebuffer(ATTACHMENTS)
        except Exception as e:
            self.ctx.release()
            if isinstance(e, (ValueError, GLError)):
                raise
            raise GLError(f"cannot allocate {self.width}x{self.height} render targets: {e}") from None

    def _framebuffer(self, attachments: int):
        """``attachments`` float RGBA targets, made once (GLError if they cannot be)."""
        if attachments not in self._fbos:
            try:
                rb = [self.ctx.renderbuffer((self.width, self.height), 4, dtype="f4") for _ in range(attachments)]
                self._fbos[attachments] = self.ctx.framebuffer(
                    rb, self.ctx.depth_renderbuffer((self.width, self.height)))
                self.check_errors("creating the framebuffer")
            except Exception as e:
                raise GLError(f"cannot allocate {self.width}x{self.height} render targets: {e}") from None
        return self._fbos[attachments]

    @property
    def info(self) -> dict:
        """GL_RENDERER, GL_VERSION and friends of the context."""
        return dict(self.ctx.info)

    def check_errors(self, what: str) -> None:
        """GLError when ``ctx.error`` reports one.

        Args:
            what: the work just done.
        """
        err = self.ctx.error
        if err != "GL_NO_ERROR":
            raise GLError(f"OpenGL error {err} while {what}")

    def program(self, variant: str = "exact", fixed_steps: int = 10, discard_misses: bool = False,
                self_shadow: bool = False):
        """The compiled program of ``variant`` (cached).

        Args:
            variant: in ``VARIANTS``.
            fixed_steps: CSM_FIXED_STEPS (1..127).
            discard_misses: CSM_DISCARD_MISSES.
            self_shadow: CSM_SELF_SHADOW.
        """
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
        if not 1 <= int(fixed_steps) <= 127:
            raise ValueError(f"fixed_steps must be in 1..127, got {fixed_steps!r}")
        key = (variant, int(fixed_steps), bool(discard_misses), bool(self_shadow))
        if key not in self._programs:
            head = (f"#version 330 core\n#define CSM_FIXED_STEPS {int(fixed_steps)}\n"
                    f"#define CSM_INTERSECT {VARIANTS[variant]}\n#define CSM_RAY_OUTPUTS\n")
            if discard_misses:
                head += "#define CSM_DISCARD_MISSES\n"
            if self_shadow:
                head += "#define CSM_SELF_SHADOW\n"
            if variant == "quadrant":
                head += "#define CSM_QUADRANT_MAPS\n"
            frag = head + shader_source("csm.glsl") + "\n" + shader_source("surface_frag.glsl")
            vert = "#version 330 core\n" + shader_source("surface_vert.glsl")
            try:
                self._programs[key] = self.ctx.program(vertex_shader=vert, fragment_shader=frag)
            except Exception as e:  # moderngl raises its own Error type with the GLSL log
                raise GLError(f"building the {variant!r} shader failed: {e}") from e
            self.check_errors(f"building the {variant!r} shader")
        return self._programs[key]

    def render(self, material: Material, camera: Camera, *, variant: str = "exact", steps: int = 10,
               binary_steps: int = 8, max_iterations: int = 2048, mesh: Mesh | None = None,
               model=None, draws: int = 1) -> RenderResult:
        """Draw ``mesh`` with ``material`` seen by ``camera``.

        Args:
            material: the step map.
            camera: the view.
            variant: in ``VARIANTS``.
            steps: of _loop, _fixed; pom's, relief's linear steps.
            binary_steps: pom's, relief's.
            max_iterations: _exact's cap.
            mesh: default :func:`quad`.
            model: ``(4, 4)`` (None: identity).
            draws: draws issued; ``draw_s`` is the fastest.
        """
        with self.ctx:  # current again if another Renderer's context was made meanwhile
            return self._render(material, camera, variant, steps, binary_steps, max_iterations, mesh, model, draws)

    def _render(self, material, camera, variant, steps, binary_steps, max_iterations, mesh, model, draws):
        mesh = quad() if mesh is None else mesh
        if (variant == "quadrant") != (material.step_map2 is not None):
            raise ValueError("the quadrant variant draws a quadrant map (two images: step_map and step_map2) "
                             "and only the quadrant variant does")
        if material.step_map2 is not None and len(material.levels) != len(material.levels2):
            raise ValueError("a quadrant map's two images need the same number of levels (levels, levels2)")
        shadows = bool(material.self_shadow)
        prog = self.program(variant, steps if variant == "fixed" else 10, self_shadow=shadows)
        model = np.eye(4) if model is None else np.asarray(model, float)
        view = camera.view()
        vp = camera.projection(self.width / self.height) @ view
        tx, ty = tile_pair(material.tile)
        self._uniforms(prog, {
            "model": model, "view_proj": vp, "view": view, "eye": camera.eye,
            "light": material.light, "light_direction": material.light_direction,
            "selfShadow": shadows, "lightSize": float(material.light_size), "ambient": material.ambient, "diffuse": material.diffuse,
            "depth": float(material.depth), "uv_per_world": uv_matrix(material.uv_per_world),
            "max_ratio": check_max_ratio(material.max_ratio), "tiled": (tx, ty),
            "conesteps": int(steps), "binary_steps": int(binary_steps),
            "max_iterations": int(max_iterations), "stepmap": 0, "texmap": 1, "stepmap2": 2,
            "min_step": float(material.min_step), "levels": len(material.levels),
            "use_texmap": material.color_map is not None,
        })
        steptex = self._texture(material.step_map, tx, ty, material.mipmaps, material.levels)
        colortex = None
        if material.color_map is not None:
            colortex = self._texture(rgba8(material.color_map), True, True)
        second = None if material.step_map2 is None else self._texture(material.step_map2, tx, ty, material.mipmaps,
                                                                          material.levels2)
        vao, buffers = self._vertex_array(prog, mesh)
        try:
            steptex.use(0)
            (colortex or steptex).use(1)
            (second or steptex).use(2)
            fbo = self._framebuffer(SHADOW_ATTACHMENTS if shadows else ATTACHMENTS)
            fbo.use()
            self.ctx.enable(self.ctx.DEPTH_TEST)
            best = float("inf")
            for _ in range(max(int(draws), 1)):
                fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                self.ctx.finish()
                t0 = time.perf_counter()
                vao.render()
                self.ctx.finish()
                best = min(best, time.perf_counter() - t0)
            self.check_errors(f"drawing with {variant!r}")
            color, hit, info, ray_uv, ray_dir = (self._read(fbo, k) for k in range(5))
            light, shadow = (self._read(fbo, k).astype(np.float64) for k in (5, 6)) if shadows else (None, None)
        finally:
            for obj in (vao, *buffers, steptex, colortex, second):
                if obj is not None:
                    obj.release()
        covered = info[..., 3] > 0.5
        status = np.where(covered, np.rint(info[..., 1]), STATUS_EMPTY).astype(np.int8)
        return RenderResult(color=color, hit_uv=hit[..., :2].astype(np.float64),
                            hit_height=hit[..., 2].astype(np.float64), ray_t=hit[..., 3].astype(np.float64),
                            iterations=np.rint(info[..., 0]).astype(np.int32), status=status,
                            view_depth=info[..., 2], ray_uv=ray_uv[..., :2].astype(np.float64),
                            lod=ray_uv[..., 2].astype(np.float64),
                            ray_dir=ray_dir[..., :3].astype(np.float64), variant=variant, draw_s=best,
                            light_dir=None if light is None else light[..., :3],
                            shadow=None if shadow is None else np.concatenate([light[..., 3:], shadow[..., :3]], -1))

    def _read(self, fbo, attachment: int) -> np.ndarray:
        data = fbo.read(attachment=attachment, components=4, dtype="f4")
        self.check_errors("reading the framebuffer")
        img = np.frombuffer(data, dtype=np.float32).reshape(self.height, self.width, 4)
        return img[::-1].copy()  # GL rows are bottom-up

    def _texture(self, img: np.ndarray, tx: bool, ty: bool, mipmaps: bool = False, levels=()):
        tex = upload(self.ctx, img, tx, ty, mipmaps, levels)
        self.check_errors("uploading a texture")
        return tex

    def _vertex_array(self, prog, mesh: Mesh):
        n = len(mesh.positions)
        parts = [np.asarray(a, np.float32).reshape(n, k) for a, k in
                 ((mesh.positions, 3), (mesh.normals, 3), (mesh.tangents, 4), (mesh.uvs, 2))]
        vbo = self.ctx.buffer(np.hstack(parts).astype(np.float32).tobytes())
        ibo = self.ctx.buffer(np.asarray(mesh.indices, np.uint32).tobytes())
        vao = self.ctx.vertex_array(prog, [(vbo, "3f 3f 4f 2f", "in_position", "in_normal",
                                            "in_tangent", "in_uv")], ibo, index_element_size=4)
        self.check_errors("building the vertex array")
        return vao, (vbo, ibo)

    @staticmethod
    def _uniforms(prog, values: dict) -> None:
        for name, value in values.items():
            if name not in prog:  # the compiler removed an unused uniform
                continue
            if isinstance(value, np.ndarray) and value.ndim == 2:
                prog[name].write(value.T.astype(np.float32).tobytes())  # GLSL is column-major
            elif isinstance(value, (tuple, list)):
                prog[name].value = tuple(x if isinstance(x, bool) else float(x) for x in value)
            else:
                prog[name].value = value

    def close(self) -> None:
        """Release the programs, framebuffers and the context."""
        for p in self._programs.values():
            p.release()
        self._programs.clear()
        for f in self._fbos.values():
            f.release()
        self._fbos.clear()
        self.ctx.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

