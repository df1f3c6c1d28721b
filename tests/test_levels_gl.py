"""The levels as an engine uploads them: OpenGL takes a map and its levels as one mipmap-complete
texture (odd and non-square sizes included), and ``textureLod`` at level k reads level k's texels."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import skip_without_gl

from csm_assets.step_levels import level_shapes
from csm_assets.stepmap import StepMapSettings, make_step_map

VERTEX = """#version 330
in vec2 pos;
void main() { gl_Position = vec4(pos, 0.0, 1.0); }
"""
FRAGMENT = """#version 330
uniform sampler2D step_map;
uniform int level;
out vec4 colour;
void main() {
    ivec2 size = textureSize(step_map, level);
    vec2 uv = gl_FragCoord.xy / vec2(size);  // a texel centre of the level (pixel centres are at .5)
    colour = textureLod(step_map, uv, float(level));
}
"""


@pytest.mark.parametrize("shape,bits", [((13, 20), 8), ((8, 1), 16), ((16, 16), 8)])
def test_gl_reads_each_level_as_a_mip_level(shape, bits):
    skip_without_gl()
    import moderngl

    h = np.random.default_rng(4).random(shape).astype(np.float32)
    sm = make_step_map(h, StepMapSettings(levels="average", bits=bits))
    levels = [sm.pixels, *sm.levels]
    assert [lv.shape[:2] for lv in levels[1:]] == level_shapes(shape)
    ctx = moderngl.create_standalone_context(backend="egl")
    try:
        top = float(np.iinfo(sm.pixels.dtype).max)  # 8-bit as UNORM8; 16-bit as floats of the codes / 65535
        upload = [lv if bits == 8 else (lv / top).astype("f4") for lv in levels]
        tex = ctx.texture((shape[1], shape[0]), 4, dtype="f1" if bits == 8 else "f4")
        tex.build_mipmaps(0, len(levels) - 1)  # allocates levels 1..n (GL's sizes); ours replace them
        for k, lv in enumerate(upload):  # GL's rows go up: flip each level as the renderer does
            tex.write(np.ascontiguousarray(lv[::-1]).tobytes(), level=k)
        tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)
        prog = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
        quad = ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], "f4").tobytes())
        vao = ctx.vertex_array(prog, [(quad, "2f", "pos")])
        tex.use(0)
        fbo = ctx.simple_framebuffer((shape[1], shape[0]), components=4, dtype="f4")
        fbo.use()
        for k, lv in enumerate(levels):  # one pixel a texel of level k, in the framebuffer's corner
            hk, wk = lv.shape[:2]
            fbo.viewport = (0, 0, wk, hk)
            prog["level"].value = k
            vao.render(moderngl.TRIANGLE_STRIP)
            got = np.frombuffer(fbo.read(viewport=(0, 0, wk, hk), components=4, dtype="f4"), "f4")
            np.testing.assert_allclose(got.reshape(hk, wk, 4)[::-1], lv / top, atol=0.25 / top,
                                       err_msg=f"level {k} of {len(levels) - 1}")
        assert ctx.error == "GL_NO_ERROR"
    finally:
        ctx.release()
