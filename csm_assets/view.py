"""``csm-assets view``: serve a converted glTF/GLB scene and a viewer on 127.0.0.1.

The page (``csm_assets/web``) loads the scene with the project's plugin for the engine chosen
(:data:`ENGINES`: three.js' GLTFLoader plugin, or Babylon.js' glTF loader extension). The
server (:class:`~csm_assets.view_server.BoundedServer`: a fixed pool of workers, timeouts,
a bound on open connections) listens on 127.0.0.1 only; it serves the page's own files,
``/api/scene.json`` and, under ``/scene/``, only the files the scene names (itself, its
buffers and images), each opened afresh and checked on every request
(:class:`~csm_assets.view_files.Folder`: inside the folder, a regular file, no link out),
streamed in chunks, with only the content types a glTF can reference. Every answer carries
``X-Content-Type-Options: nosniff`` and a restrictive CSP. Requests whose Host is not this
address are refused (DNS rebinding). Anything refused is a 404. Nothing is written.
"""

from __future__ import annotations

import base64
import hashlib
import http.server
import json
import os
import posixpath
import re
import sys
import threading
import time
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

from . import references
from .checks import FLOAT32_MAX
from .errors import FormatError, no_file
from .warning_codes import Notice, add, line
from .references import is_data_uri
from .view_files import OCTET_STREAM, PAGE_TYPES, SCENE_TYPES, Folder, Refused, content_type
from .view_levels import levels_problems
from .view_server import BoundedServer, make_handler_setup
from .web import web_root

SCENE_SUFFIXES = (".gltf", ".glb")
ENGINES = ("three", "babylon")  # the engines the page can draw with (csm_assets/web/viewer_entry.js)
CHUNK = 1 << 20  # a response is sent a chunk at a time, straight from the file
MIN_RATE = 1 << 20  # bytes a second a client must take, past the connection's timeout
SECURITY_HEADERS = {"X-Content-Type-Options": "nosniff", "Cache-Control": "no-store",
                    "Cross-Origin-Resource-Policy": "same-origin", "Referrer-Policy": "no-referrer",
                    "X-Frame-Options": "DENY"}
# everything but the page: nothing runs, nothing loads, not even when opened as a document
STRICT_CSP = "default-src 'none'; sandbox; frame-ancestors 'none'; base-uri 'none'; form-action 'none'"


def page_csp(html: str) -> str:
    """The page's CSP: scripts from this server and the page's own inline ones (the import
    map, by hash), styles by hash, images and fetches from this server and the blob:/data:
    URLs a glTF loader makes, WebAssembly and blob: workers (the Draco and meshopt decoders);
    nothing else (no other host, no frames, no forms, no plugins)."""
    def hashes(tag):
        return " ".join(f"'sha256-{base64.b64encode(hashlib.sha256(m.encode()).digest()).decode()}'"
                        for m in re.findall(rf"<{tag}\b[^>]*>(.*?)</{tag}>", html, re.S) if m.strip())
    return (f"default-src 'none'; script-src 'self' {hashes('script')} 'wasm-unsafe-eval'; "
            f"worker-src 'self' blob:; style-src {hashes('style')}; "
            "img-src 'self' blob: data:; connect-src 'self' blob: data:; base-uri 'none'; form-action 'none'; "
            "frame-ancestors 'none'")


def url_key(rel: str) -> str:
    """The key a scene file is found by: a relative path as a browser requests it
    (backslashes are slashes, dot segments resolved)."""
    return posixpath.normpath(rel.replace("\\", "/"))


def extension_problem(ext) -> str | None:
    """What is wrong with a material's extension object, as convert and verify read it
    (:mod:`csm_assets.formats.csm_params`; and a number past 32-bit floats, which the page's
    shader cannot hold), or None. The page's plugin checks it again (csm_check.js)."""
    from .formats.csm_params import GLTF_EXTENSION, PARAMETERS, read_values

    if not isinstance(ext, dict):
        return f"{GLTF_EXTENSION} is not an object"
    info = ext.get("stepMapTexture")
    if not isinstance(info, dict) or isinstance(info.get("index"), bool) or not isinstance(info.get("index"), int):
        return "stepMapTexture.index is not an integer"
    try:
        values = read_values(lambda p: ext.get(p.name), "", "")
    except FormatError as e:
        return str(e).removeprefix(": : ")
    numbers = [(p.name, values[p.attr]) for p in PARAMETERS if p.kind == "number"]
    for key in ("stepMapTexture", "stepMap2Texture"):
        info = ext.get(key) if isinstance(ext.get(key), dict) else {}
        moved = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
        for name in ("offset", "rotation", "scale"):  # their types: the reader's (gltf_schema)
            v = moved.get(name)
            numbers += [(f"{key}'s {name}", x) for x in (v if isinstance(v, list) else [v])
                        if isinstance(x, (int, float)) and not isinstance(x, bool)]
    huge = [f"{name} {v:g}" for name, v in numbers if abs(v) > FLOAT32_MAX]
    if huge:
        return f"{', '.join(huge)} {'is' if len(huge) == 1 else 'are'} beyond the shader's 32-bit floats " \
               f"({FLOAT32_MAX:.4g})"
    return quadrant_problem(ext, values["variant"])


def quadrant_problem(ext: dict, variant: str) -> str | None:
    """What is wrong with a material's ``stepMap2Texture`` (a quadrant step map's second image),
    or None: it is there exactly when ``variant`` is quadrant, a textureInfo with the first's
    texCoord (csm_check.js checks the same in the page; its being a textureInfo is the glTF
    reader's structural check, :mod:`csm_assets.formats.gltf_schema`)."""
    second = ext.get("stepMap2Texture")
    if variant == "quadrant" and second is None:
        return "variant quadrant draws a quadrant step map, two images: stepMap2Texture is missing"
    if second is None:
        return None
    if variant != "quadrant":
        return f"stepMap2Texture (a quadrant step map's second image) is drawn only by variant quadrant, not {variant}"
    first, second_uv = ext["stepMapTexture"].get("texCoord", 0), second.get("texCoord", 0)
    if second_uv != first:
        return f"stepMap2Texture.texCoord {second_uv!r} is not stepMapTexture's {first!r}"
    return None


@dataclass
class ViewScene:
    """What the server shows: the scene file, the folder served (``base``: the scene's, or the
    folder holding it and the files it names elsewhere in its project root, as a lean output
    names its scene's textures), the files it may serve (url key -> path relative to ``base``,
    opened afresh on each request), the materials carrying the extension, and the reader's warnings."""

    path: Path
    files: dict = field(default_factory=dict)
    csm_materials: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    base: Path | None = None

    def info(self) -> dict:
        rel = self.path.relative_to(self.base).as_posix() if self.base else self.path.name
        return {"name": self.path.name, "url": "scene/" + urllib.parse.quote(rel),
                "materials": self.csm_materials, "warnings": [str(w) for w in self.warnings]}


def load_scene(path) -> ViewScene:
    """Read and check a glTF/GLB scene as convert does (:class:`FormatError` when it is
    missing, unreadable, malformed or not glTF; files it names outside its project root are
    refused). Warns when no material carries the extension."""
    from .config.files import project_root
    from .formats import gltf

    path = Path(path)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise FormatError(path, "view shows glTF/GLB scenes (.gltf, .glb); convert others first")
    if not path.is_file():
        raise FormatError(path, "no such file")
    root = project_root(path)
    try:
        scene = gltf.read(path, root=root)
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from None
    doc = scene.source
    real = path.resolve()
    view = ViewScene(real, warnings=list(scene.warnings))
    folder, found = real.parent, {}
    uris = [b.get("uri") for b in doc.json.get("buffers", [])] + [i.get("uri") for i in doc.json.get("images", [])]
    for uri in uris:
        if not isinstance(uri, str) or is_data_uri(uri):
            continue
        rel = urllib.parse.unquote(uri)
        references.check(path, rel)  # as the reader did: no URL is ever requested by the page
        file = (folder / rel.replace("\\", "/")).resolve()
        if not file.is_relative_to(root):
            add(view.warnings, Notice("CSM501", str(path), f"{uri} lies outside the scene's project root; not served"))
        elif not file.is_file():  # missing, or a FIFO, a folder...: never opened
            why = no_file(file)
            gone = "is missing" if why.startswith("no such file") else why
            add(view.warnings, Notice("CSM502", str(path), f"{uri} {gone}; the page shows the scene without it"))
        else:
            found[rel] = file
    view.base = Path(os.path.commonpath([folder, *(f.parent for f in found.values())]))
    here = folder.relative_to(view.base).as_posix()
    view.files[url_key(real.relative_to(view.base).as_posix())] = real.relative_to(view.base).as_posix()
    for rel, file in found.items():  # the path a browser asks for, from the scene's url
        view.files[url_key(posixpath.join(here, rel.replace("\\", "/")))] = file.relative_to(view.base).as_posix()
    for i, m in enumerate(doc.json.get("materials", [])):
        ext = m.get("extensions", {}).get(gltf.EXTENSION)
        if ext is None:
            continue
        if isinstance(ext, dict):
            view.csm_materials.append({**ext, "name": m.get("name", "")})  # the material's own name wins
        why = extension_problem(ext)
        if why:
            add(view.warnings, Notice("CSM504", str(path), f"{why}; the page shows it without relief (the plain "
                                      "material)", (repr(m.get("name") or i),)))
        for file, why in [] if why else levels_problems(doc, ext, m.get("name") or f"material{i}"):
            add(view.warnings, Notice("CSM505", file, f"{why}; the page draws that step map's level 0 alone"))
    if not view.csm_materials:
        add(view.warnings, Notice("CSM503", str(path), f"no material carries {gltf.EXTENSION}; convert the scene "
                                  "first (shown without relief)"))
    return view


class _Handler(http.server.BaseHTTPRequestHandler):
    """One request (its head already read by the server); every answer carries SECURITY_HEADERS
    and a CSP (the page's, else ``default-src 'none'; sandbox``)."""

    server: "ViewServer"
    server_version = "csm-assets"
    sys_version = ""
    error_content_type = "text/plain; charset=utf-8"
    error_message_format = "%(code)d %(message)s\n"
    default_request_version = "HTTP/1.0"  # never an HTTP/0.9 answer (it has no headers)

    def __init__(self, sock, address, server, head: bytes):
        self.head = head
        self.csp = STRICT_CSP
        super().__init__(sock, address, server)

    def setup(self):
        make_handler_setup(self, self.request, self.head)

    def finish(self):
        pass

    def log_message(self, format, *args):  # quiet: the terminal shows the URL and errors only
        pass

    def end_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.send_header(name, value)
        self.send_header("Content-Security-Policy", self.csp)
        super().end_headers()

    def do_GET(self):
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
        if host not in ("127.0.0.1", "localhost"):
            return self.send_error(403, "only 127.0.0.1 is served")
        route = urllib.parse.unquote(urllib.parse.urlsplit(self.path).path)
        if route in ("/", "/index.html"):
            self.csp = self.server.page_csp
            return self._file(self.server.web, "index.html", PAGE_TYPES)
        if route == "/api/scene.json":
            info = {**self.server.scene.info(), "engine": self.server.engine}
            return self._send(json.dumps(info).encode(), "application/json")
        if route.startswith("/scene/"):
            rel = self.server.scene.files.get(url_key(route[len("/scene/"):]))
            return self._file(self.server.folder, rel, SCENE_TYPES) if rel else self.send_error(404)
        if route.startswith("/web/") and content_type(route, PAGE_TYPES) != OCTET_STREAM:
            return self._file(self.server.web, route[len("/web/"):], PAGE_TYPES)
        self.send_error(404)

    def _file(self, folder: Folder, rel: str, types: dict):
        try:
            f, size = folder.open(rel)
        except Refused:
            return self.send_error(404)
        with f:
            self.send_response(200)
            self.send_header("Content-Type", content_type(rel, types))
            self.send_header("Content-Length", str(size))
            self.end_headers()
            # at least MIN_RATE bytes a second, on top of the connection's timeout
            deadline = time.monotonic() + self.server.timeout + size / MIN_RATE
            sent = 0
            while sent < size:
                if time.monotonic() > deadline:
                    raise TimeoutError("response too slow")
                n = self.connection.sendfile(f, sent, min(CHUNK, size - sent))
                if n <= 0:  # the file shrank while being sent: cut the response short
                    raise OSError("file shrank")
                sent += n

    def _send(self, data: bytes, ctype: str):
        self.send_response(200)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)


class ViewServer(BoundedServer):
    """The viewer's server on 127.0.0.1:``port`` (0: a free port); the page draws with
    ``engine`` (:data:`ENGINES`); ``url`` once bound.
    Holds the scene's folder and the page's folder open until :meth:`server_close`."""

    def __init__(self, scene: ViewScene, port: int = 0, engine: str = "three"):
        if engine not in ENGINES:
            raise ValueError(f"--engine {engine}: expected one of {', '.join(ENGINES)}")
        self.scene = scene
        self.engine = engine
        self.folder = Folder(scene.base or scene.path.parent)
        self.web = Folder(web_root())
        self.page_csp = page_csp((web_root() / "index.html").read_text(encoding="utf-8"))
        try:
            super().__init__(_Handler, port)
        except BaseException:
            self.folder.close()
            self.web.close()
            raise

    def server_close(self) -> None:
        super().server_close()
        self.folder.close()
        self.web.close()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}/"


def serve(path, port: int = 0, open_browser: bool = True, out=sys.stdout, engine: str = "three") -> None:
    """Serve the scene, drawn with ``engine`` (:data:`ENGINES`), until interrupted
    (KeyboardInterrupt propagates after a clean shutdown). Raises :class:`FormatError` for a bad
    scene, ValueError for an unknown engine or when the port cannot be had."""
    if engine not in ENGINES:
        raise ValueError(f"--engine {engine}: expected one of {', '.join(ENGINES)}")
    scene = load_scene(path)
    for w in scene.warnings:
        sys.stderr.write(line(w))
    try:
        server = ViewServer(scene, port, engine)
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
