"""Tiny procedural fixtures and the path to the shared real data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

settings.register_profile("default", max_examples=40, deadline=None)
settings.load_profile("default")

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


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
