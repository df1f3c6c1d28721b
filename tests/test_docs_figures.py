"""The docs' figure scripts (docs/figures/) run, and the concepts figure shows what its caption
says: a ray marched through the project's own cones stays above the surface until its last
step and stops within a fraction of a texel of the exact hit."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "figures" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cone_steps_figure_marches_safely_to_the_exact_hit(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "cone_steps.png"
    r = _script("cone_steps").figure(out)
    assert out.stat().st_size > 10_000
    points = r["points"]
    assert all(z > h for _, z, h, _ in points[:-1]), "a cone step went under the surface"
    u, z, h, _ = points[-1]
    assert z <= h  # the march ended under the surface, as the shader's loop does
    assert points[-2][0] <= r["hit_u"] <= u  # the first crossing lies in the last step: none jumped over it
    assert abs(u - r["hit_u"]) * r["texels"] < 0.5  # the caption's "within a fraction of a texel"
    assert 5 <= len(points) - 1 <= 20  # a handful of steps, as drawn
