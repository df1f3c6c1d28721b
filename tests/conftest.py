"""Tiny procedural fixtures and the path to the shared real data."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# Tests send SIGINT to the CLI processes they start (Ctrl-C must end a run with 130). A shell
# starts background jobs with SIGINT ignored, the ignoring is inherited through exec, and
# Python then never raises KeyboardInterrupt: 20 tests failed that way under `pytest &`. A
# handler (unlike SIG_IGN) is reset to the default on exec, so every child starts with
# SIGINT as a terminal would deliver it, whoever started the suite.
signal.signal(signal.SIGINT, signal.default_int_handler)

# Every run draws new examples (a fixed seed would only hide the next bug: pin each one
# hypothesis finds with @example). CI (the CI variable set; .ci/run sets it) runs 10 times as
# many: on the tie maps of issue 28 the bug it fixed took 33-344 examples to find (median 90,
# 20 seeds), so 40 find it by chance and 400 nearly always. A test that takes a share of
# them says so with examples(share).
settings.register_profile("default", max_examples=40, deadline=None)
settings.register_profile("ci", max_examples=400, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "default")


def examples(share: float = 1.0) -> settings:
    """Settings for a property test that runs ``share`` of the profile's examples (at least 5)."""
    return settings(max_examples=max(5, round(settings.default.max_examples * share)), deadline=None)

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="module")
def dask_cluster():
    """A Dask LocalCluster on loopback: two worker processes of one thread (skipped without Dask)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as c:
        yield c


@pytest.fixture
def shared_data() -> Path:
    """``../shared/data`` beside the checkout; the test skips where it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is absent")
    return SHARED_DATA


def spike(shape=(9, 7), at=(4, 3), top=1.0) -> np.ndarray:
    h = np.zeros(shape)
    h[at] = top
    return h


def checkerboard(shape=(6, 8)) -> np.ndarray:
    r, c = np.indices(shape)
    return ((r + c) % 2).astype(np.float64)


SAMPLES = Path(__file__).resolve().parents[1] / "samples"
GLTF_WALL = ("brick_wall.gltf", "brick_wall.bin", "brick_wall.glb", "bricks_color.png", "bricks_height.png")
OBJ_WALL = ("brick_wall.obj", "brick_wall.mtl", "bricks_color.png", "bricks_height.png", "bricks_normal.png")


def copy_samples(folder: Path, names) -> Path:
    """Copy sample files into ``folder`` (created); returns the folder."""
    import shutil

    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(SAMPLES / name, folder / name)
    return folder


def random_field(n, seed, smooth=2.0) -> np.ndarray:
    """A tileable random field in [0, 1], float32 ``n`` or ``(H, W)``; ``smooth`` is the
    Gaussian sigma in texels (0: white noise)."""
    from scipy.ndimage import gaussian_filter

    h = np.random.default_rng(seed).random(n if isinstance(n, tuple) else (n, n))
    if smooth:
        h = gaussian_filter(h, smooth, mode="wrap")
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32)


def glsl_define(name: str) -> float:
    """The value ``shaders/csm.glsl`` gives ``#define name`` (its default), for tests that hold an
    emulation's constant to the shader's."""
    import re

    from csm_assets.render.glsl import shader_source

    return float(re.search(rf"#define {name} ([0-9.]+)", shader_source("csm.glsl")).group(1))


def skip_without_gl() -> None:
    """pytest.skip unless a headless OpenGL (EGL) context can be made."""
    import moderngl

    try:
        moderngl.create_standalone_context(backend="egl").release()
    except Exception as e:  # moderngl raises plain Exceptions for a missing EGL
        pytest.skip(f"no headless OpenGL context: {e}")


def local_hook_config(hook: str) -> str:
    """A ``.pre-commit-config.yaml`` running hook ``hook`` of this checkout's
    ``.pre-commit-hooks.yaml`` as a local system hook (the csm-assets on PATH): the same entry
    and file patterns, without the environment a python hook has pre-commit build."""
    import yaml

    root = Path(__file__).resolve().parents[1]
    spec = next(h for h in yaml.safe_load((root / ".pre-commit-hooks.yaml").read_text()) if h["id"] == hook)
    return yaml.safe_dump({"repos": [{"repo": "local", "hooks": [dict(spec, language="system")]}]})
