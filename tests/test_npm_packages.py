"""The npm packages (packages/three, packages/babylon) as an engine programmer gets them: ``npm
pack`` (its prepack copies the plugin's modules from csm_assets/web), the tarball installed into
an empty project with the peer dependencies of its package.json from the registry, a page that
imports the package by name (the import map resolves it through the package's ``exports``) and
draws a converted scene's hit uv view in headless chromium, compared with moderngl's hit uv.
The package's TypeScript declarations are type-checked (strict tsc) against a small use of it.
Skips without node/npm or the registry (npm_tools)."""

from __future__ import annotations

import functools
import http.server
import json
import shutil
import subprocess
import threading
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from cdp import Chromium
from npm_tools import npm
from view_page import SIZE, camera, convert, needs_browser, png
from view_scenes import moderngl_hits, two_material_scene

pytestmark = pytest.mark.browser
ROOT = Path(__file__).resolve().parents[1]
PAGES = Path(__file__).resolve().parent / "npm_pages"
VIEW = ((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))
# package folder -> the import map's entries for its peers (besides the package itself)
PEER_IMPORTS = {
    "three": {"three": "./node_modules/three/build/three.module.js", "three/addons/": "./node_modules/three/examples/jsm/"},
    "babylon": {"@babylonjs/core/": "./node_modules/@babylonjs/core/",
                "@babylonjs/loaders/": "./node_modules/@babylonjs/loaders/"},
}
# what a TypeScript user adds to type-check against the package's declarations
TYPES = {"three": ["typescript@5", "@types/three"], "babylon": ["typescript@5"]}
# Babylon's own declarations do not check without WebGPU's and their matching DOM types: tsc skips
# checking inside .d.ts files there (the package's declarations are still what check.ts is checked against)
SKIP_LIB_CHECK = {"three": False, "babylon": True}


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return convert(two_material_scene(tmp_path_factory.mktemp("src")), tmp_path_factory.mktemp("out"))


@contextmanager
def static_server(folder: Path):
    """A plain HTTP server for ``folder`` on 127.0.0.1 in a thread; yields its URL."""
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(folder))
    handler.log_message = lambda *a: None
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{srv.server_address[1]}/"
    finally:
        srv.shutdown()
        srv.server_close()


def install(folder: str, project: Path) -> dict:
    """Pack packages/<folder> and install the tarball and its peers into ``project``; its package.json."""
    meta = json.loads((ROOT / "packages" / folder / "package.json").read_text())
    packed = project.parent / "packed"
    packed.mkdir(parents=True, exist_ok=True)
    npm(meta["name"], "pack", "--silent", "--pack-destination", str(packed), cwd=ROOT / "packages" / folder)
    (tarball,) = packed.glob("*.tgz")
    npm(meta["name"], "init", "-y", cwd=project)
    peers = [f"{name}@{rng}" for name, rng in meta["peerDependencies"].items()]
    npm(meta["name"], "install", "--no-audit", "--no-fund", str(tarball), *peers, *TYPES[folder], cwd=project)
    return meta


@pytest.mark.parametrize("folder", ["three", "babylon"])
def test_packed_package_installs_and_draws(tmp_path, scene, folder):
    project = tmp_path / "app"
    meta = install(folder, project)
    installed = project / "node_modules" / meta["name"]
    entry = meta["exports"]["."]
    assert (installed / entry["default"]).is_file() and (installed / entry["types"]).is_file()
    assert (installed / "README.md").is_file()
    shipped = {p.name for p in (installed / "dist").iterdir()}
    assert all((ROOT / "csm_assets" / "web" / name).read_bytes() == (installed / "dist" / name).read_bytes()
               for name in shipped), "the package's modules are the viewer's"
    # the declarations: a strict tsc of a small use of the package (tests/npm_pages/<folder>.ts)
    shutil.copy(PAGES / f"{folder}.ts", project / "check.ts")
    (project / "tsconfig.json").write_text(json.dumps({"compilerOptions": {
        "module": "nodenext", "moduleResolution": "nodenext", "target": "es2022", "strict": True, "noEmit": True,
        "types": [], "skipLibCheck": SKIP_LIB_CHECK[folder]}, "files": ["check.ts"]}))
    tsc = subprocess.run([str(project / "node_modules" / ".bin" / "tsc"), "-p", "."], cwd=project,
                         capture_output=True, text=True, timeout=300)
    assert tsc.returncode == 0, tsc.stdout[-2000:]
    shutil.copytree(scene.parent, project / "scene")
    shutil.copy(PAGES / f"{folder}.js", project / "app.js")
    imports = {**PEER_IMPORTS[folder], meta["name"]: f"./node_modules/{meta['name']}/{entry['default'].removeprefix('./')}"}
    (project / "index.html").write_text(
        '<!DOCTYPE html><html><head><meta charset="utf-8"><style>body { margin: 0; overflow: hidden }</style>'
        f'<script type="importmap">{json.dumps({"imports": imports})}</script></head>'
        '<body><script type="module" src="./app.js"></script></body></html>')
    cam = camera(*VIEW)
    w, h = SIZE
    with static_server(project) as url, Chromium(w, h) as b:
        b.goto(url)
        b.eval("new Promise((ok) => { const t = setInterval(() => { if (window.pageReady) { clearInterval(t); ok(); } }, 50); })",
               timeout=180)
        drawn = b.eval(f"window.draw('scene/{scene.name}', {cam.view().ravel().tolist()}, "
                       f"{cam.projection(w / h).ravel().tolist()})", timeout=180)
        assert sorted(m["name"] for m in drawn) == ["bricks", "cobbles"] and all(m["fallback"] is None for m in drawn)
        shot = png(b.screenshot())
        assert not b.console_errors(), b.console_errors()
    status, ref_uv, _ = moderngl_hits(scene, cam, SIZE)
    hit = status == 0
    d = np.abs(shot[..., :2] - np.mod(ref_uv, 1.0))
    near = np.all(np.minimum(d, 1 - d) < 1.5 / 255, axis=-1)
    assert hit.sum() > 0.2 * w * h
    assert near[hit].mean() >= 0.95, near[hit].mean()
