"""The viewer in a real browser: headless chromium (WebGL2 on SwiftShader) against moderngl.

Each test serves a converted scene with ``csm-assets view --no-browser``, loads the page,
sets the camera to the exact view and projection matrices of a
:class:`csm_assets.render.Camera`, and compares the plugin's hit uv (read from a float
render target) with the project's moderngl render of the same camera and size. Skips
when chromium or EGL is missing. Set ``CSM_VIEWER_SCREENSHOT=PATH`` to keep the lit
screenshot of the two-material scene (the README's picture).
"""

from __future__ import annotations

import base64
import io
import json
import os
import shutil
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from cdp import CdpError, Chromium, find_chromium
from conftest import SAMPLES, skip_without_gl
from view_scenes import moderngl_hits, two_material_scene

pytestmark = pytest.mark.browser
SIZE = (288, 192)


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    if find_chromium() is None:
        pytest.skip("no chromium (apt-get install chromium)")
    skip_without_gl()
    try:
        with Chromium(64, 64) as b:
            webgl2 = b.eval("!!document.createElement('canvas').getContext('webgl2')")
    except CdpError as e:
        pytest.skip(f"chromium does not start here: {e}")
    if not webgl2:
        pytest.skip("chromium gives no WebGL2 here (SwiftShader missing?)")


def _convert(src: Path, out: Path) -> Path:
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(src), "-o", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return out / src.name


@contextmanager
def serving(scene: Path):
    """``csm-assets view SCENE --no-browser``: yields the URL; Ctrl-C ends it with 130, cleanly."""
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(scene), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert " at http://127.0.0.1:" in line, (line, proc.stderr.read() if proc.poll() is not None else "")
        yield line.split(" at ")[1].split()[0]
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise
    assert proc.returncode == 130, err
    assert "Traceback" not in err, err


def _camera(eye, target):
    from csm_assets.render import Camera

    return Camera(eye, target, up=(0.0, 1.0, 0.0), fov_deg=40.0)


def _browser_raw(b: Chromium, camera, mode: str, relief: bool = True) -> np.ndarray:
    """float32 (h, w, 4) of a raw debug view, image order (relief False: the plain polygon's)."""
    w, h = SIZE
    view, proj = camera.view(), camera.projection(w / h)
    b.eval(f"window.csmViewer.setCamera({view.ravel().tolist()}, {proj.ravel().tolist()})")
    data = base64.b64decode(b.eval(f"window.csmViewer.readRaw('{mode}', {w}, {h}, {str(relief).lower()})"))
    return np.frombuffer(data, np.float32).reshape(h, w, 4)[::-1]


def _load(b: Chromium, url: str) -> dict:
    b.goto(url)
    info = b.eval("window.csmViewer.ready", timeout=120)
    assert "error" not in info, info
    assert b.eval("window.csmViewer.glInfo()")["webgl2"]
    return info


def compare_hits(b: Chromium, scene: Path, camera) -> dict:
    """Agreement of the browser's hit uv with moderngl's at one camera."""
    raw = _browser_raw(b, camera, "rawUv")
    status_b = np.rint(raw[..., 3]).astype(int) - 1  # -1 nothing drawn
    ref_status, ref_uv, texels = moderngl_hits(scene, camera, SIZE)
    covered = (status_b >= 0) | (ref_status >= 0)
    relief = (status_b == 0) & (ref_status == 0)
    err = np.hypot(*((raw[..., :2] - ref_uv) * texels).transpose(2, 0, 1))[relief]
    return {"relief": int(relief.sum()), "covered": int(covered.sum()),
            "status_agree": float(np.mean(status_b[covered] == ref_status[covered])),
            "within_1_texel": float(np.mean(err <= 1.0)), "p50": float(np.median(err)),
            "raw": raw, "ref_uv": ref_uv, "relief_mask": relief}


def _png(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB")).astype(np.float64) / 255


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    out = tmp_path_factory.mktemp("wall")
    return _convert(SAMPLES / "brick_wall.gltf", out)


WALL_VIEWS = [((0.9, 0.9, 1.1), (0.0, 0.5, 0.0)), ((-0.2, 0.3, 0.9), (0.1, 0.5, 0.0)),
              ((1.2, 0.55, 0.3), (0.0, 0.5, 0.0))]  # the last at 14 degrees: grazing


def test_wall_hit_uv_matches_moderngl_and_relief_shows(wall):
    w, h = SIZE
    with serving(wall) as url, Chromium(w, h) as b:
        info = _load(b, url)
        assert [m["fallback"] for m in info["materials"]] == [None]
        for eye, target in WALL_VIEWS:
            s = compare_hits(b, wall, _camera(eye, target))
            assert s["relief"] > 0.3 * w * h, s["relief"]
            assert s["status_agree"] >= 0.99, s["status_agree"]
            assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])
        # the screenshot: the hit uv view shows the relief's uv, not the polygon's (the fallback)
        cam = _camera(*WALL_VIEWS[0])
        s = compare_hits(b, wall, cam)
        b.eval("window.csmViewer.showPanel(false)")
        b.eval("window.csmViewer.setDebug('uv')")
        shot = _png(b.screenshot())
        assert shot.shape[:2] == (h, w)
        flat_uv = _browser_raw(b, cam, "rawUv", relief=False)[..., :2]
        sel = s["relief_mask"]

        def near(uv):  # the shown fract(uv) within 1.5 of 255 (wrapped), over the relief pixels
            d = np.abs(shot[..., :2] - np.mod(uv, 1.0))
            return float(np.mean(np.all(np.minimum(d, 1 - d) < 1.5 / 255, axis=-1)[sel]))

        assert near(s["ref_uv"]) >= 0.95, near(s["ref_uv"])
        assert near(flat_uv) < near(s["ref_uv"]) - 0.2, (near(flat_uv), near(s["ref_uv"]))
        b.eval("window.csmViewer.setDebug('lit')")
        lit = b.screenshot()
        b.eval("window.csmViewer.setDebug('off')")
        plain = _png(b.screenshot())
        assert np.mean(np.abs(_png(lit) - plain).max(axis=-1) > 0.05) > 0.2
        b.eval("window.csmViewer.setDebug('heat')")
        heat = _png(b.screenshot())
        assert np.mean(np.abs(heat - plain).max(axis=-1) > 0.05) > 0.3
        assert not b.console_errors(), b.console_errors()


def test_glb_hit_uv_matches_moderngl(tmp_path):
    scene = _convert(SAMPLES / "brick_wall.glb", tmp_path / "out")
    for p in scene.parent.glob("*.png"):  # the GLB holds its images: the files beside it are not needed
        p.unlink()
    with serving(scene) as url, Chromium(*SIZE) as b:
        _load(b, url)
        s = compare_hits(b, scene, _camera(*WALL_VIEWS[0]))
        assert s["relief"] > 0.3 * SIZE[0] * SIZE[1]
        assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])


def test_two_materials_external_and_embedded_images(tmp_path):
    scene = _convert(two_material_scene(tmp_path / "src"), tmp_path / "out")
    with serving(scene) as url, Chromium(*SIZE) as b:
        info = _load(b, url)
        assert sorted(m["name"] for m in info["materials"]) == ["bricks", "cobbles"]
        assert all(m["fallback"] is None for m in info["materials"])
        cam = _camera((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))
        s = compare_hits(b, scene, cam)
        assert s["status_agree"] >= 0.99, s["status_agree"]
        assert s["within_1_texel"] >= 0.99, (s["within_1_texel"], s["p50"])
        hit = s["relief_mask"]
        assert hit[:, : SIZE[0] // 3].mean() > 0.2 and hit[:, -SIZE[0] // 3:].mean() > 0.2  # both quads
        b.eval("window.csmViewer.showPanel(false)")
        lit = b.screenshot()
        b.eval("window.csmViewer.setDebug('off')")
        plain = _png(b.screenshot())
        changed = np.abs(_png(lit) - plain).max(axis=-1) > 0.05
        assert changed[:, : SIZE[0] // 3].mean() > 0.2 and changed[:, -SIZE[0] // 3:].mean() > 0.2
        assert not b.console_errors(), b.console_errors()
    if os.environ.get("CSM_VIEWER_SCREENSHOT"):  # the README's picture
        Path(os.environ["CSM_VIEWER_SCREENSHOT"]).write_bytes(lit)


def test_switching_variant_and_steps_recompiles(wall):
    with serving(wall) as url, Chromium(*SIZE) as b:
        _load(b, url)
        cam = _camera(*WALL_VIEWS[0])
        exact = _browser_raw(b, cam, "rawInfo")
        b.eval("window.csmViewer.setVariant('fixed', 3)")
        fixed = _browser_raw(b, cam, "rawInfo")
        drawn = fixed[..., 1] > 0
        assert np.all(fixed[..., 0][drawn] == 3)  # the fixed variant runs its steps, no more
        assert np.mean(exact[..., 0][drawn]) > 3
        assert not b.console_errors(), b.console_errors()




FALLBACK_PROBE = """(async () => {
  const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
  const { CSMExtension } = await import('./web/csm_plugin.js');
  const loader = new GLTFLoader();
  loader.register((parser) => new CSMExtension(parser, { webgl2: false }));
  const gltf = await loader.loadAsync('scene/brick_wall.gltf');
  const out = [];
  gltf.scene.traverse((o) => { if (o.isMesh) out.push([o.material.userData.csm.fallback, !!o.geometry.attributes.csmDpdu]); });
  return out;
})()"""


def test_fallbacks_without_webgl2_or_tangents(wall, tmp_path):
    """The plain PBR material where the relief cannot run: no WebGL2, or a mesh without TANGENT."""
    with serving(wall) as url, Chromium(*SIZE) as b:
        _load(b, url)
        assert b.eval(FALLBACK_PROBE) == [["no WebGL2", False]]
    doc = json.loads(wall.read_text())
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            del prim["attributes"]["TANGENT"]
    for f in wall.parent.iterdir():
        if f.is_file():
            shutil.copy(f, tmp_path / f.name)
    (tmp_path / wall.name).write_text(json.dumps(doc))
    with serving(tmp_path / wall.name) as url, Chromium(*SIZE) as b:
        info = _load(b, url)
        assert [m["fallback"] for m in info["materials"]] == ["no TANGENT"]
        assert not b.console_errors(), b.console_errors()
