"""``csm-assets view``: serve a converted glTF/GLB scene and the three.js viewer on 127.0.0.1.

The page (``csm_assets/web``) loads the scene with the project's GLTFLoader plugin. The
server is the standard library's ``ThreadingHTTPServer`` bound to 127.0.0.1 only; it
serves the page's own files, ``/api/scene.json`` and, under ``/scene/``, only the files
the scene names (itself, its buffers and images). Requests whose Host is not this
address are refused (DNS rebinding). Nothing is written.
"""

from __future__ import annotations

import http.server
import json
import mimetypes
import posixpath
import sys
import threading
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

from .errors import FormatError
from .warning_codes import Notice, add, line
from .web import web_root

SCENE_SUFFIXES = (".gltf", ".glb")
_TYPES = {".js": "text/javascript", ".html": "text/html; charset=utf-8", ".json": "application/json",
          ".gltf": "model/gltf+json", ".glb": "model/gltf-binary", ".bin": "application/octet-stream",
          ".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".webp": "image/webp"}


@dataclass
class ViewScene:
    """What the server shows: the scene file, the files it may serve (url path -> file),
    the materials carrying the extension, and the reader's warnings."""

    path: Path
    files: dict = field(default_factory=dict)
    csm_materials: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    def info(self) -> dict:
        return {"name": self.path.name, "url": "scene/" + urllib.parse.quote(self.path.name),
                "materials": self.csm_materials, "warnings": [str(w) for w in self.warnings]}


def load_scene(path) -> ViewScene:
    """Read and check a glTF/GLB scene as convert does (:class:`FormatError` when it is
    missing, unreadable, malformed or not glTF). Warns when no material carries the extension."""
    from .formats import gltf

    path = Path(path)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise FormatError(path, "view shows glTF/GLB scenes (.gltf, .glb); convert others first")
    if not path.is_file():
        raise FormatError(path, "no such file")
    try:
        scene = gltf.read(path)
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    doc = scene.source
    view = ViewScene(path.resolve(), warnings=list(scene.warnings))
    view.files[path.name] = path.resolve()
    folder = path.resolve().parent
    uris = [b.get("uri") for b in doc.json.get("buffers", [])] + [i.get("uri") for i in doc.json.get("images", [])]
    for uri in uris:
        if not isinstance(uri, str) or uri.startswith("data:"):
            continue
        rel = urllib.parse.unquote(uri)
        file = (folder / rel).resolve()
        if not file.is_relative_to(folder):
            add(view.warnings, Notice("CSM501", str(path), f"{uri} lies outside the scene's folder; not served"))
        elif not file.is_file():
            add(view.warnings, Notice("CSM502", str(path), f"{uri} is missing; the page shows the scene without it"))
        else:
            view.files[posixpath.normpath(rel)] = file
    for m in doc.json.get("materials", []):
        ext = m.get("extensions", {}).get(gltf.EXTENSION)
        if isinstance(ext, dict):
            view.csm_materials.append({"name": m.get("name", ""), **ext})
    if not view.csm_materials:
        add(view.warnings, Notice("CSM503", str(path), f"no material carries {gltf.EXTENSION}; convert the scene "
                                  "first (shown without relief)"))
    return view


class _Handler(http.server.BaseHTTPRequestHandler):
    server: "ViewServer"

    def log_message(self, format, *args):  # quiet: the terminal shows the URL and errors only
        pass

    def do_GET(self):
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
        if host not in ("127.0.0.1", "localhost"):
            return self.send_error(403, "only 127.0.0.1 is served")
        route = urllib.parse.unquote(urllib.parse.urlsplit(self.path).path)
        if route in ("/", "/index.html"):
            return self._file(web_root() / "index.html")
        if route == "/api/scene.json":
            return self._send(json.dumps(self.server.scene.info()).encode(), ".json")
        if route.startswith("/scene/"):
            file = self.server.scene.files.get(posixpath.normpath(route[len("/scene/"):]))
            return self._file(file) if file else self.send_error(404)
        if route.startswith("/web/"):
            root = web_root().resolve()
            file = (root / route[len("/web/"):]).resolve()
            if file.is_relative_to(root) and file.suffix in (".js", ".html") and file.is_file():
                return self._file(file)
        self.send_error(404)

    def _file(self, file: Path):
        try:
            data = file.read_bytes()
        except OSError:
            return self.send_error(404)
        self._send(data, file.suffix.lower())

    def _send(self, data: bytes, suffix: str):
        self.send_response(200)
        self.send_header("Content-Type", _TYPES.get(suffix) or mimetypes.guess_type("x" + suffix)[0]
                         or "application/octet-stream")
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(data)


class ViewServer(http.server.ThreadingHTTPServer):
    """The viewer's server on 127.0.0.1:``port`` (0: a free port); ``url`` once bound."""

    daemon_threads = True

    def __init__(self, scene: ViewScene, port: int = 0):
        self.scene = scene
        super().__init__(("127.0.0.1", int(port)), _Handler)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}/"


def serve(path, port: int = 0, open_browser: bool = True, out=sys.stdout) -> None:
    """Serve the scene until interrupted (KeyboardInterrupt propagates after a clean shutdown).
    Raises :class:`FormatError` for a bad scene, ValueError when the port cannot be had."""
    scene = load_scene(path)
    for w in scene.warnings:
        sys.stderr.write(line(w))
    try:
        server = ViewServer(scene, port)
    except OSError as e:
        raise ValueError(f"--port {port}: cannot listen on 127.0.0.1:{port} ({e.strerror or e})") from None
    with server:
        out.write(f"csm-assets: viewing {scene.path.name} at {server.url} (Ctrl-C to stop)\n")
        out.flush()
        if open_browser:
            import webbrowser

            threading.Thread(target=webbrowser.open, args=(server.url,), daemon=True).start()
        try:
            server.serve_forever(poll_interval=0.2)
        finally:
            server.server_close()
