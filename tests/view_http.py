"""Helpers for the viewer's server tests: serve a scene in a thread or in a subprocess (with
its own open-file limit and timeout), plain HTTP requests, raw sockets."""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from csm_assets.view import ViewServer, load_scene


@contextmanager
def served(scene_path, timeout: float | None = None):
    """The scene served in a thread of this process; yields the server."""
    srv = ViewServer(load_scene(scene_path))
    if timeout is not None:
        srv.timeout = timeout
    t = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    t.start()
    try:
        yield srv
    finally:
        srv.shutdown()
        srv.server_close()
        t.join(5)


def request(port, path, host="127.0.0.1", method="GET", timeout=10.0):
    """``(status, headers dict (lower-case names), body)`` of one request."""
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        c.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        c.putheader("Host", f"{host}:{port}")
        c.endheaders()
        r = c.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        c.close()


def raw(port, data: bytes, timeout=10.0) -> bytes:
    """Send ``data`` as it is; everything the server answers until it closes."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        out = b""
        while chunk := s.recv(65536):
            out += chunk
        return out


# a server process with a low open-file limit and a short timeout: it prints its port
SERVER = """
import resource, signal, sys
nofile = int(sys.argv[2])
if nofile:
    resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
signal.signal(signal.SIGINT, signal.default_int_handler)
from csm_assets.view import ViewServer, load_scene
srv = ViewServer(load_scene(sys.argv[1]))
srv.timeout = float(sys.argv[3])
print(srv.server_address[1], srv.workers, srv.max_connections, flush=True)
try:
    srv.serve_forever(poll_interval=0.05)
except KeyboardInterrupt:
    srv.server_close()
"""


@contextmanager
def server_process(scene: Path, nofile: int = 0, timeout: float = 10.0):
    """Yields ``(proc, port, workers, max_connections)``; on exit stops it with SIGINT and
    asserts it wrote nothing on stderr (no traceback, no line)."""
    proc = subprocess.Popen([sys.executable, "-c", SERVER, str(scene), str(nofile), str(timeout)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        port, workers, most = map(int, line.split())
        yield proc, port, workers, most
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise
    assert err == "", err


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def peak_rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM")


def answered_within(port, seconds: float, path="/api/scene.json") -> float:
    """Seconds a fresh request took to be answered 200 (AssertionError past ``seconds``)."""
    t0 = time.monotonic()
    status, _, body = request(port, path, timeout=seconds)
    assert status == 200, status
    json.loads(body)
    return time.monotonic() - t0
