"""The viewer page in headless chromium, shared by the browser tests: serve a converted
scene with ``csm-assets view --no-browser``, load the page, set the camera to a
:class:`csm_assets.render.renderer.Camera`'s matrices, read the plugin's raw hit uv (a float render
target) and compare it with the project's moderngl render of the same camera and size.
"""

from __future__ import annotations

import base64
import io
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from cdp import CdpError, Chromium, find_chromium
from conftest import skip_without_gl
from view_scenes import moderngl_hits

SIZE = (288, 192)
FOV_DEG = 40.0  # the vertical field of view of camera()


def needs_browser() -> None:
    """Skips the calling test (module) unless chromium runs here with WebGL2 and EGL is there."""
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


def convert(src: Path, out: Path, *flags) -> Path:
    """``csm-assets convert SRC -o OUT -q FLAGS``; the converted scene's path."""
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(src), "-o", str(out), "-q", *flags],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return out / src.name


@contextmanager
def serving(scene: Path, engine: str = "three"):
    """``csm-assets view SCENE --no-browser --engine ENGINE``: yields the URL; Ctrl-C ends it with
    130, cleanly."""
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(scene), "--no-browser", "--engine", engine],
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


def camera(eye, target):
    from csm_assets.render.renderer import Camera

    return Camera(eye, target, up=(0.0, 1.0, 0.0), fov_deg=FOV_DEG)


def browser_raw(b: Chromium, cam, mode: str, relief: bool = True) -> np.ndarray:
    """float32 (h, w, 4) of a raw debug view, image order (relief False: the plain polygon's)."""
    w, h = SIZE
    view, proj = cam.view(), cam.projection(w / h)
    b.eval(f"window.csmViewer.setCamera({view.ravel().tolist()}, {proj.ravel().tolist()})")
    data = base64.b64decode(b.eval(f"window.csmViewer.readRaw('{mode}', {w}, {h}, {str(relief).lower()})"))
    return np.frombuffer(data, np.float32).reshape(h, w, 4)[::-1]


def load(b: Chromium, url: str) -> dict:
    """Open the viewer page; the page's ``ready`` answer (materials, warnings)."""
    b.goto(url)
    info = b.eval("window.csmViewer.ready", timeout=120)
    assert "error" not in info, info
    assert b.eval("window.csmViewer.glInfo()")["webgl2"]
    return info


def compare_hits(b: Chromium, scene: Path, cam, *, transform: bool = True) -> dict:
    """Agreement of the browser's hit uv (of the page loaded) with moderngl's render of
    ``scene`` at one camera (transform False: a render that ignores the step map's
    KHR_texture_transform)."""
    raw = browser_raw(b, cam, "rawUv")
    status_b = np.rint(raw[..., 3]).astype(int) - 1  # -1 nothing drawn
    ref_status, ref_uv, texels = moderngl_hits(scene, cam, SIZE, transform)
    covered = (status_b >= 0) | (ref_status >= 0)
    relief = (status_b == 0) & (ref_status == 0)
    err_image = np.hypot(*((raw[..., :2] - ref_uv) * texels).transpose(2, 0, 1))
    err = err_image[relief]
    return {"relief": int(relief.sum()), "covered": int(covered.sum()),
            "status_agree": float(np.mean(status_b[covered] == ref_status[covered])),
            "within_1_texel": float(np.mean(err <= 1.0)), "p50": float(np.median(err)),
            "raw": raw, "ref_uv": ref_uv, "texels": texels, "relief_mask": relief, "within_mask": err_image <= 1.0}


def png(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB")).astype(np.float64) / 255


def uv_screenshot_agreement(b: Chromium, scene: Path, cam) -> tuple[float, float]:
    """The screenshot check that the relief is drawn, not the fallback: of the relief pixels,
    the fractions whose shown hit-uv colour (fract(uv) within 1.5/255, wrapped) is moderngl's
    hit uv, and is the plain polygon's uv. Leaves the panel hidden and the uv view on."""
    s = compare_hits(b, scene, cam)
    b.eval("window.csmViewer.showPanel(false)")
    b.eval("window.csmViewer.setDebug('uv')")
    shot = png(b.screenshot())
    assert shot.shape[:2] == (SIZE[1], SIZE[0])
    flat_uv = browser_raw(b, cam, "rawUv", relief=False)[..., :2]

    def near(uv):
        d = np.abs(shot[..., :2] - np.mod(uv, 1.0))
        return float(np.mean(np.all(np.minimum(d, 1 - d) < 1.5 / 255, axis=-1)[s["relief_mask"]]))

    return near(s["ref_uv"]), near(flat_uv)
