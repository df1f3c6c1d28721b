"""The tutorial's screenshot (docs/tutorial_view.png): the sample scene converted as the
tutorial converts it, served by ``csm-assets view --no-browser`` and drawn by the viewer page
in headless chromium (WebGL2 on SwiftShader), panel shown, seen from the upper right at about
35 degrees, close enough to see the mortar's depth.

Run from the repository root: ``python docs/figures/tutorial_view.py`` (needs chromium on PATH
and the tests' CDP client, ``tests/cdp.py``).
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from cdp import Chromium  # noqa: E402
from PIL import Image  # noqa: E402

from csm_assets.render.renderer import Camera  # noqa: E402

OUT = ROOT / "docs" / "tutorial_view.png"
SIZE = (900, 560)
EYE, TARGET = (1.5, 1.05, 1.25), (0.15, 0.45, 0.0)  # the wall spans x -1..1, y 0..1 at z 0


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "converted"
        subprocess.run([sys.executable, "-m", "csm_assets", "convert", str(ROOT / "samples" / "brick_wall.gltf"),
                        "-o", str(out), "-q"], check=True, timeout=300)
        proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(out / "brick_wall.gltf"),
                                 "--no-browser"], stdout=subprocess.PIPE, text=True)
        try:
            url = proc.stdout.readline().split(" at ")[1].split()[0]
            with Chromium(*SIZE) as b:
                b.goto(url)
                info = b.eval("window.csmViewer.ready", timeout=120)
                assert "error" not in info, info
                cam = Camera(EYE, TARGET, up=(0.0, 1.0, 0.0), fov_deg=40.0)
                view, proj = cam.view(), cam.projection(SIZE[0] / SIZE[1])
                b.eval(f"window.csmViewer.setCamera({view.ravel().tolist()}, {proj.ravel().tolist()})")
                shot = Image.open(io.BytesIO(b.screenshot())).convert("RGB")
                shot.quantize(256, dither=Image.Dither.NONE).save(OUT, optimize=True)  # half the bytes
        finally:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=20)
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
