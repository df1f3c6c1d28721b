"""The viewer in a real browser on a lean output (issue 35): the converted scene beside its source
names the source's textures by ``../`` uris; the page loads them through ``csm-assets view`` (no
console error: three.js and Babylon.js log one for an image they could not load) and draws the
relief as moderngl does, in both engines. Skips when chromium or EGL is missing."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

from attack import assert_clean_run, run_cli
from cdp import Chromium
from conftest import SAMPLES
from view_page import SIZE, camera, compare_hits, load, needs_browser, png, serving

pytestmark = pytest.mark.browser


@pytest.mark.parametrize("engine", ["three", "babylon"])
def test_the_page_loads_a_lean_outputs_textures_and_draws_its_relief(tmp_path, engine):
    needs_browser()
    if shutil.which("git") is None:
        pytest.skip("needs git")
    repo = tmp_path / "assets"
    repo.mkdir()
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(SAMPLES / name, repo / name)
    subprocess.run(["git", "init", "-q"], cwd=repo, check=True)
    assert_clean_run(run_cli("hook", "brick_wall.gltf", cwd=repo), 1)
    scene = repo / "brick_wall_gltf_csm" / "brick_wall.gltf"
    assert json.loads(scene.read_text())["images"][0]["uri"] == "../bricks_color.png"
    with serving(scene, engine) as url, Chromium(*SIZE) as b:
        info = load(b, url)
        assert [m["fallback"] for m in info["materials"]] == [None]
        s = compare_hits(b, scene, camera((0.9, 0.9, 1.1), (0.0, 0.5, 0.0)))
        assert s["status_agree"] >= 0.99 and s["within_1_texel"] >= 0.99, s
        b.eval("window.csmViewer.setDebug('off')")
        shown = png(b.screenshot())
        assert np.ptp(shown[..., :3]) > 0.2  # the colour texture, not one flat colour
        assert not b.console_errors(), b.console_errors()
