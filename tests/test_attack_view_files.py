"""Attacks on what ``csm-assets view`` serves: files swapped after start-up (links out, a FIFO,
``/dev/zero``, a folder on the way), active content types, the security headers on every
answer, streaming (a big file costs no memory), and odd requests (NUL bytes, long names)."""

from __future__ import annotations

import json
import os
import re
import shutil
import time

import pytest

from conftest import GLTF_WALL, copy_samples
from view_http import peak_rss_mb, raw, request, served, server_process

ACTIVE = {"page.html": b"<script>alert(1)</script>", "pic.svg": b"<svg onload='alert(1)'/>",
          "code.js": b"alert(1)", "sheet.css": b"*{}", "map.webp": b"RIFF", "sub/deep.png": b"\x89PNG"}


@pytest.fixture
def wall(tmp_path):
    """The sample wall with extra images the scene names: active types, and one in a sub-folder."""
    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    (folder / "sub").mkdir()
    for name, data in ACTIVE.items():
        (folder / name).write_bytes(data)
    doc = json.loads((folder / "brick_wall.gltf").read_text())
    doc["images"] += [{"uri": name} for name in ACTIVE]
    (folder / "brick_wall.gltf").write_text(json.dumps(doc))
    (tmp_path / "secret.txt").write_text("the viewer's user's secret")
    return folder / "brick_wall.gltf"


def test_only_gltf_types_are_served_as_such(wall):
    with served(wall) as srv:
        port = srv.server_address[1]
        types = {name: request(port, f"/scene/{name}")[1]["content-type"] for name in ACTIVE}
        assert types == {"page.html": "application/octet-stream", "pic.svg": "application/octet-stream",
                         "code.js": "application/octet-stream", "sheet.css": "application/octet-stream",
                         "map.webp": "image/webp", "sub/deep.png": "image/png"}
        assert request(port, "/scene/brick_wall.gltf")[1]["content-type"] == "model/gltf+json"
        assert request(port, "/scene/bricks_color.png")[1]["content-type"] == "image/png"


def test_every_answer_carries_nosniff_and_a_csp(wall):
    with served(wall) as srv:
        port = srv.server_address[1]
        answers = {path: request(port, path) for path in
                   ("/", "/api/scene.json", "/scene/brick_wall.gltf", "/scene/page.html", "/web/viewer.js",
                    "/nothing", "/scene/../secret.txt")}
        answers["other host"] = request(port, "/", host="evil.example")
        answers["POST"] = request(port, "/", method="POST")
        for what, (status, headers, _) in answers.items():
            assert headers.get("x-content-type-options") == "nosniff", what
            csp = headers.get("content-security-policy", "")
            assert "default-src 'none'" in csp and "frame-ancestors 'none'" in csp, (what, csp)
            # 'wasm-unsafe-eval' (compiling WebAssembly, for the Draco and meshopt decoders) is no JS eval
            assert "'unsafe-inline'" not in csp and "'unsafe-eval'" not in csp and "*" not in csp, (what, csp)
            assert headers.get("cross-origin-resource-policy") == "same-origin", what
        assert [answers[p][0] for p in ("/", "/scene/page.html", "/nothing", "other host", "POST")] == \
            [200, 200, 404, 403, 501]
        page = answers["/"][1]["content-security-policy"]
        assert "script-src 'self' 'sha256-" in page and "connect-src 'self' blob: data:" in page
        assert "sandbox" in answers["/scene/page.html"][1]["content-security-policy"]  # never a page
        assert "sandbox" not in page


def test_files_swapped_after_start_up_are_refused(wall, tmp_path):
    """A served image replaced by a link out, a FIFO, /dev/zero, a folder; a sub-folder replaced
    by a link to another folder: each is 404 at once (no hang, no read of the device)."""
    folder = wall.parent
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "deep.png").write_text("outside the scene")
    with served(wall) as srv:
        port = srv.server_address[1]
        assert request(port, "/scene/bricks_color.png")[0] == 200
        assert request(port, "/scene/sub/deep.png")[0] == 200
        color = folder / "bricks_color.png"
        swaps = {"link out": lambda: color.symlink_to(tmp_path / "secret.txt"),
                 "fifo": lambda: os.mkfifo(color), "folder": lambda: color.mkdir()}
        if os.path.exists("/dev/zero"):
            swaps["/dev/zero"] = lambda: color.symlink_to("/dev/zero")
        for what, swap in swaps.items():
            color.unlink() if color.is_symlink() or color.is_file() or color.is_fifo() else color.rmdir()
            swap()
            t0 = time.monotonic()
            status, _, body = request(port, "/scene/bricks_color.png", timeout=5)
            assert status == 404 and b"secret" not in body, what
            assert time.monotonic() - t0 < 2, what
        (folder / "sub").rename(folder / "sub_was")
        (folder / "sub").symlink_to(outside)
        status, _, body = request(port, "/scene/sub/deep.png")
        assert status == 404 and b"outside" not in body
        # the scene file itself swapped for a link out
        wall.rename(folder / "was.gltf")
        wall.symlink_to(tmp_path / "secret.txt")
        assert request(port, "/scene/brick_wall.gltf")[0] == 404


def test_a_link_that_stays_inside_is_followed(wall):
    folder = wall.parent
    with served(wall) as srv:
        (folder / "bricks_color.png").rename(folder / "sub" / "real.png")
        (folder / "bricks_color.png").symlink_to("sub/real.png")
        status, _, body = request(srv.server_address[1], "/scene/bricks_color.png")
        assert status == 200 and body == (folder / "sub" / "real.png").read_bytes()


def test_a_file_over_the_size_bound_is_refused(wall):
    """A sparse file bigger than a GLB can be (4 GiB) is not served."""
    big = wall.parent / "map.webp"
    with served(wall) as srv:
        with open(big, "r+b") as f:
            f.truncate(1 << 32)
        assert request(srv.server_address[1], "/scene/map.webp")[0] == 404


def test_big_files_are_streamed_not_held(wall):
    """A 400 MB (sparse) image downloaded twice costs the server process no 400 MB."""
    size = 400 << 20
    with open(wall.parent / "map.webp", "r+b") as f:
        f.truncate(size)
    with server_process(wall) as (proc, port, _, _):
        before = peak_rss_mb(proc.pid)
        for _ in range(2):
            status, headers, body = request(port, "/scene/map.webp", timeout=60)
            assert status == 200 and int(headers["content-length"]) == size == len(body)
            del body
        assert peak_rss_mb(proc.pid) - before < 60, (before, peak_rss_mb(proc.pid))


def test_odd_requests_leave_no_traceback(wall):
    """NUL bytes, over-long names, bad encodings, a client gone mid-download: 4xx answers, the
    server goes on, and its stderr stays empty (server_process asserts it on exit)."""
    size = 64 << 20
    with open(wall.parent / "map.webp", "r+b") as f:
        f.truncate(size)
    with server_process(wall) as (proc, port, _, _):
        for path in ("/scene/%00", "/web/%00.js", "/web/a%00b.js", "/scene/brick_wall.gltf%00.png",
                     "/web/" + "a" * 5000 + ".js", "/scene/" + "a" * 60000, "/web/%ff%fe.js", "/scene/%c0%af",
                     "/web/" + "../" * 50 + "etc/passwd", "/scene/\\..\\secret.txt"):
            assert request(port, path)[0] == 404, path[:40]
        head = raw(port, b"GET /" + b"a" * 70000 + b" HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
        assert re.match(rb"HTTP/1\.[01] 414 ", head), head[:80]
        assert raw(port, b"GET /\x00 HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n").startswith(b"HTTP/1.0 404")
        tls = raw(port, b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03\r\n\r\n")
        assert tls.startswith(b"HTTP/1.0 400") and b"nosniff" in tls, tls[:200]
        assert b"nosniff" in raw(port, b"GET /\r\n\r\n")
        assert raw(port, b"GET / HTTP/1.0\r\n" + b"X: y\r\n" * 200 + b"\r\n").startswith(b"HTTP/1.0 431")
        import socket

        for _ in range(3):  # gone mid-download
            s = socket.create_connection(("127.0.0.1", port))
            s.sendall(f"GET /scene/map.webp HTTP/1.0\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
            s.recv(4096)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")  # RST
            s.close()
        assert request(port, "/api/scene.json")[0] == 200
        time.sleep(0.3)


def test_backslash_and_encoded_uris_are_found(tmp_path):
    """A uri the readers accept with a backslash (``sub\\\\map.png``) or percent-encoding is
    served at the path a browser asks for (``/scene/sub/map.png``)."""
    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    (folder / "sub dir").mkdir()
    shutil.move(folder / "bricks_color.png", folder / "sub dir" / "bricks color.png")
    doc = json.loads((folder / "brick_wall.gltf").read_text())
    doc["images"][0]["uri"] = "sub%20dir\\bricks%20color.png"
    (folder / "brick_wall.gltf").write_text(json.dumps(doc))
    with served(folder / "brick_wall.gltf") as srv:
        info = json.loads(request(srv.server_address[1], "/api/scene.json")[2])
        assert not any("missing" in w for w in info["warnings"]), info["warnings"]
        status, _, body = request(srv.server_address[1], "/scene/sub%20dir/bricks%20color.png")
        assert status == 200 and body == (folder / "sub dir" / "bricks color.png").read_bytes()
