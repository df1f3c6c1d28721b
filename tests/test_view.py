"""``csm-assets view`` without a browser: what the server serves and refuses, Ctrl-C,
the shipped files (the generated GLSL module, package data, every JS import resolvable)."""

from __future__ import annotations

import http.client
import json
import re
import signal
import subprocess
import sys
import threading
import tomllib
from contextlib import contextmanager
from pathlib import Path

import pytest

from conftest import GLTF_WALL, copy_samples
from csm_assets.view import ViewServer, load_scene
from csm_assets.web import GLSL_MODULE, SCHEMA_MODULE, glsl_module, schema_module, web_root

ROOT = Path(__file__).resolve().parents[1]


@contextmanager
def server(scene_path, engine: str = "three"):
    srv = ViewServer(load_scene(scene_path), engine=engine)
    t = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    t.start()
    try:
        yield srv.server_address[1]
    finally:
        srv.shutdown()
        srv.server_close()
        t.join(5)


def get(port, path, host="127.0.0.1"):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        c.request("GET", path, headers={"Host": f"{host}:{port}"})
        r = c.getresponse()
        return r.status, r.getheader("Content-Type"), r.read()
    finally:
        c.close()


@pytest.fixture
def wall(tmp_path):
    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    (folder / "secret.txt").write_text("not for the browser")
    return folder / "brick_wall.gltf"


def test_serves_page_scene_and_its_files_only(wall):
    with server(wall) as port:
        status, ctype, body = get(port, "/")
        assert status == 200 and ctype.startswith("text/html") and b"importmap" in body
        info = json.loads(get(port, "/api/scene.json")[2])
        assert info["url"] == "scene/brick_wall.gltf" and info["name"] == "brick_wall.gltf"
        assert any("no material carries" in w for w in info["warnings"])  # not converted: shown plain
        for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
            status, _, body = get(port, f"/scene/{name}")
            assert status == 200 and body == (wall.parent / name).read_bytes()
        assert get(port, "/web/csm_plugin.js")[1] == "text/javascript"
        assert get(port, "/web/three/three.module.min.js")[0] == 200
        for path in ("/scene/secret.txt", "/scene/brick_wall.glb", "/scene/../scene/secret.txt",
                     "/scene/%2e%2e/secret.txt", "/web/../view.py", "/web/__init__.py", "/web/three/LICENSE",
                     "/etc/passwd", "/scene/"):
            assert get(port, path)[0] == 404, path
        assert get(port, "/", host="attacker.example")[0] == 403  # DNS rebinding


def test_babylon_engine_serves_its_page_and_build(wall):
    """--engine babylon: scene.json says so (the page's viewer_entry.js picks the viewer by it), the
    vendored Babylon.js build and the plugin are served; an unknown engine is refused before serving."""
    with server(wall) as port:
        assert json.loads(get(port, "/api/scene.json")[2])["engine"] == "three"
    with server(wall, "babylon") as port:
        assert json.loads(get(port, "/api/scene.json")[2])["engine"] == "babylon"
        assert get(port, "/")[0] == 200
        for path in ("/web/babylon/babylon.js", "/web/babylon/babylon.glTF2FileLoader.min.js", "/web/csm_babylon.js",
                     "/web/babylon/core.js"):
            status, ctype, _ = get(port, path)
            assert status == 200 and ctype == "text/javascript", path
        assert get(port, "/web/babylon/LICENSE")[0] == 404
    with pytest.raises(ValueError, match="--engine vulkan: expected one of three, babylon"):
        ViewServer(load_scene(wall), engine="vulkan")
    r = subprocess.run([sys.executable, "-m", "csm_assets", "view", str(wall), "--engine", "vulkan", "--no-browser"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "invalid choice: 'vulkan'" in r.stderr, r.stderr


def test_listens_on_loopback_only(wall):
    srv = ViewServer(load_scene(wall))
    try:
        assert srv.server_address[0] == "127.0.0.1" and srv.url.startswith("http://127.0.0.1:")
    finally:
        srv.server_close()


def test_ctrl_c_ends_it_with_130(wall):
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(wall), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert re.match(r"csm-assets: viewing brick_wall.gltf at http://127\.0\.0\.1:\d+/ ", line), line
        port = int(line.split("127.0.0.1:")[1].split("/")[0])
        assert get(port, "/api/scene.json")[0] == 200
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 130, err
    lines = [x for x in err.splitlines() if x.strip()]
    assert all(x.startswith(("csm-assets: warning:", "csm-assets: info:")) for x in lines[:-1]), err
    assert lines[-1] == "csm-assets: view stopped (interrupted)"


def test_glsl_module_is_generated_from_csm_glsl():
    assert (web_root() / GLSL_MODULE).read_text() == glsl_module(), \
        "regenerate: python -c 'from csm_assets.web import *; (web_root() / GLSL_MODULE).write_text(glsl_module())'"


def test_schema_module_is_generated_from_the_schema():
    text = (ROOT / "docs" / "EXT_materials_cone_step_mapping.schema.json").read_text()
    assert (web_root() / SCHEMA_MODULE).read_text() == schema_module(text), \
        ("regenerate: python -c 'from csm_assets.web import *; (web_root() / SCHEMA_MODULE).write_text("
         "schema_module(open(\"docs/EXT_materials_cone_step_mapping.schema.json\").read()))'")


def test_plugin_variants_are_the_schema_enum():
    schema = json.loads((ROOT / "docs" / "EXT_materials_cone_step_mapping.schema.json").read_text())
    block = re.search(r"export const VARIANTS = Object.freeze\(\{(.*?)\}\);", (web_root() / "csm_settings.js").read_text(),
                      re.S).group(1)
    assert re.findall(r"(\w+):", block) == schema["properties"]["variant"]["enum"]


@pytest.mark.parametrize("change, said", [({"steps": 10**9}, "steps 1000000000 is outside 0..127"),
                                          ({"variant": "constructor"}, "variant 'constructor' is none of"),
                                          ({"depthScale": "abc"}, "depthScale must be a number"),
                                          ({"tile": "yes"}, "tile must be two booleans"),
                                          ({"variant": "quadrant"}, "stepMap2Texture is missing"),
                                          ({"stepMap2Texture": {"index": 0}},
                                           "drawn only by variant quadrant, not exact"),
                                          ({"variant": "quadrant", "stepMap2Texture": {"index": 0, "texCoord": 1}},
                                           "stepMap2Texture.texCoord 1 is not stepMapTexture's 0")])
def test_bad_extension_values_are_warned_and_served(tmp_path, change, said):
    """view says which material the page shows without relief, and serves the scene (the
    page's plugin falls back for it)."""
    scene = tmp_path / "s.gltf"
    doc = json.loads((ROOT / "samples" / "brick_wall.gltf").read_text())
    for name in ("brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        (tmp_path / name).write_bytes((ROOT / "samples" / name).read_bytes())
    doc["materials"][0].setdefault("extensions", {})["EXT_materials_cone_step_mapping"] = {
        "stepMapTexture": {"index": 0}, "depthScale": 0.05, **change}
    scene.write_text(json.dumps(doc))
    view = load_scene(scene)
    (notice,) = [w for w in view.warnings if "without relief" in str(w)]
    assert notice.code == "CSM504" and said in str(notice) and "'bricks'" in str(notice), notice


def test_a_second_step_map_that_is_no_texture_info_is_refused(tmp_path):
    """stepMap2Texture is checked as glTF's textureInfo by the reader, as stepMapTexture is: a
    string index is a FormatError naming its JSON pointer (exit 3), not a page without relief."""
    from csm_assets.errors import FormatError

    doc = json.loads((ROOT / "samples" / "brick_wall.gltf").read_text())
    doc["materials"][0].setdefault("extensions", {})["EXT_materials_cone_step_mapping"] = {
        "stepMapTexture": {"index": 0}, "depthScale": 0.05, "variant": "quadrant", "stepMap2Texture": {"index": "0"}}
    (tmp_path / "s.gltf").write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="stepMap2Texture/index: expected the index of one of the 2 textures"):
        load_scene(tmp_path / "s.gltf")


def test_package_data_ships_every_web_file():
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "csm_assets.web" in conf["packages"]
    root = web_root()
    shipped = {p for pattern in conf["package-data"]["csm_assets.web"] for p in root.glob(pattern)}
    wanted = {p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".py"}
    assert wanted <= shipped, sorted(str(p.relative_to(root)) for p in wanted - shipped)
    assert (root / "three" / "LICENSE").read_text().startswith("The MIT License")
    assert "Apache License" in (root / "babylon" / "LICENSE").read_text()[:200]


@pytest.mark.parametrize("entry, wanted", [
    ("viewer.js", {"csm_plugin.js", "csm_geometry.js", "csm_shader.js", "three.module.min.js",
                   "three.core.min.js", "GLTFLoader.js", "OrbitControls.js", "BufferGeometryUtils.js"}),
    ("viewer_babylon.js", {"csm_babylon.js", "csm_babylon_shader.js", "core.js", "loaders.js"})])
def test_every_js_import_resolves(entry, wanted):
    """Each engine's viewer (loaded by viewer_entry.js) imports only files that are shipped (through
    the page's import map), both plugins import the shared modules, and the Babylon.js build the
    entry loads first is shipped."""
    root = web_root()
    html = (root / "index.html").read_text()
    imports = json.loads(re.search(r'<script type="importmap">(.*?)</script>', html, re.S).group(1))["imports"]
    entry_js = (root / "viewer_entry.js").read_text()
    assert f"import('./{entry}')" in entry_js and 'src="./web/viewer_entry.js"' in html
    for src in re.findall(r"'\./web/(babylon/[^']+)'", entry_js):  # classic scripts (Babylon's UMD build)
        assert (root / src).is_file(), src

    def resolve(spec: str, importer: Path) -> Path:
        if spec.startswith("."):
            return (importer.parent / spec).resolve()
        for prefix, target in sorted(imports.items(), key=lambda kv: -len(kv[0])):
            if spec == prefix or (prefix.endswith("/") and spec.startswith(prefix)):
                return (root / target.removeprefix("./web/") / spec[len(prefix):]).resolve()
        raise AssertionError(f"{importer.name}: {spec!r} is not in the import map")

    todo, seen = [root / entry], set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        assert f.is_file(), f
        code = "\n".join(x for x in f.read_text().splitlines() if not x.lstrip().startswith(("*", "//", "/*")))
        for spec in re.findall(r"""(?:^|[;\n])\s*import\b[^;'"]*?from\s*['"]([^'"]+)['"]""", code):
            todo.append(resolve(spec, f))
    names = {p.name for p in seen}
    shared = {"csm_settings.js", "csm_frame.js", "csm_frag.js", "csm_glsl.js", "csm_check.js", "csm_schema.js"}
    assert wanted | shared | {"viewer_panel.js"} <= names, sorted((wanted | shared) - names)
