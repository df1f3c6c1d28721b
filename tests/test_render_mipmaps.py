"""A step map uploaded with mipmaps (what an engine that generates its own does: box-averaged
levels, LINEAR_MIPMAP_LINEAR) draws the same hits as one without, at 1 to 16 texels per pixel:
every march fetch of csm.glsl reads level 0 (textureLod). With implicit-LOD fetches (main's
shader before the change) most pixels far away marched the averaged levels and passed through
the surface; this test failed there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED_DATA, skip_without_gl
from csm_assets.map_file import load_packed
from csm_assets.render.renderer import VARIANTS, Material, Renderer
from csm_assets.verify.distance import distance_view

SIZE = 64
SAMPLES = Path(__file__).resolve().parents[1] / "samples"
MAPS = {  # name: (height map, depth map: white is deep)
    "bricks2": (SHARED_DATA / "bricks2_disp.jpg", True),
    "toy_box": (SHARED_DATA / "toy_box_disp.png", True),
    "bricks": (SAMPLES / "bricks_height.png", False),
    "cobbles": (SAMPLES / "cobbles.png", False),
}


@pytest.fixture(scope="module")
def renderer():
    skip_without_gl()
    with Renderer((SIZE, SIZE)) as r:
        yield r
        assert r.ctx.error == "GL_NO_ERROR"


def packed_map(name):
    path, invert = MAPS[name]
    if not path.exists():
        pytest.skip(f"{path} is absent")
    packed, max_ratio, _, min_step = load_packed(path, invert=invert, as_step_map=False)
    return packed, max_ratio, min_step


def draw(r, packed, max_ratio, min_step, texels, elevation, mipmaps, variant="exact", second=None, **more):
    view = distance_view(packed.shape, texels, elevation, 30.0, 0.1, SIZE)
    mat = Material(packed, max_ratio=max_ratio, depth=view.world_depth, tile=True, min_step=min_step,
                   uv_per_world=(view.uv_per_world, view.uv_per_world), mipmaps=mipmaps, step_map2=second, **more)
    return r.render(mat, view.camera, variant=variant, mesh=view.mesh, steps=16)


def same_hits(a, b) -> float:
    """Share of covered pixels whose hit uv, status and iterations are identical."""
    cov = a.covered
    same = ((a.hit_uv == b.hit_uv).all(-1) & (a.status == b.status) & (a.iterations == b.iterations))[cov]
    return float(same.mean())


@pytest.mark.parametrize("name", list(MAPS))
def test_mipmapped_step_maps_march_level_zero_on_real_maps(renderer, name):
    packed, max_ratio, min_step = packed_map(name)
    for texels in (1.0, 4.0, 16.0):
        plain = draw(renderer, packed, max_ratio, min_step, texels, 45.0, False)
        mipped = draw(renderer, packed, max_ratio, min_step, texels, 45.0, True)
        assert plain.covered.mean() > 0.9
        assert same_hits(plain, mipped) == 1.0, (name, texels)
        if texels == 16.0:  # the mipmaps are there: the shading fetch (textureGrad) filters the slopes
            assert np.abs(plain.color - mipped.color)[plain.covered].max() > 0.05


@pytest.mark.parametrize("variant", [v for v in VARIANTS if v != "quadrant"])
def test_every_variant_marches_level_zero_of_a_mipmapped_map(renderer, variant):
    packed, max_ratio, min_step = packed_map("cobbles")
    for elevation in (45.0, 20.0):
        plain = draw(renderer, packed, max_ratio, min_step, 16.0, elevation, False, variant)
        mipped = draw(renderer, packed, max_ratio, min_step, 16.0, elevation, True, variant)
        assert same_hits(plain, mipped) == 1.0, (variant, elevation)


def test_quadrant_maps_and_self_shadows_march_level_zero(renderer):
    from csm_assets.map_file import load_step_maps

    (sm,) = load_step_maps(MAPS["cobbles"][0], as_step_map=False, cones=("quadrant",)).values()
    s = sm.settings
    plain = draw(renderer, sm.pixels, s.max_ratio, s.min_step, 16.0, 20.0, False, "quadrant", sm.second)
    mipped = draw(renderer, sm.pixels, s.max_ratio, s.min_step, 16.0, 20.0, True, "quadrant", sm.second)
    assert same_hits(plain, mipped) == 1.0
    packed, max_ratio, min_step = packed_map("bricks")
    shadows = dict(self_shadow=True, light_direction=(1.0, 0.5, 0.6))
    plain, mipped = (draw(renderer, packed, max_ratio, min_step, 16.0, 45.0, m, **shadows) for m in (False, True))
    assert same_hits(plain, mipped) == 1.0
    assert np.array_equal(plain.shadow, mipped.shadow)
