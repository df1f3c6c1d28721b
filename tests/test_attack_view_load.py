"""Attacks on the viewer's server by load: many idle connections under a low open-file limit,
clients that send their request a byte at a time, clients that never read their answer.
The server runs in a subprocess with ``RLIMIT_NOFILE`` lowered and a 2-second timeout; it
must keep answering fresh requests, not spin, drop the stalled clients, and print nothing."""

from __future__ import annotations

import socket
import time

import pytest

from conftest import GLTF_WALL, copy_samples
from view_http import answered_within, cpu_seconds, server_process

TIMEOUT = 2.0


@pytest.fixture
def wall(tmp_path):
    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    with open(folder / "bricks_color.png", "r+b") as f:  # big enough to fill the socket buffers
        f.truncate(64 << 20)
    return folder / "brick_wall.gltf"


def _connect(port, n: int) -> list[socket.socket]:
    out = []
    for _ in range(n):
        s = socket.socket()
        s.settimeout(0.5)
        try:
            s.connect(("127.0.0.1", port))
        except OSError:  # the kernel's queue is full: the server is not accepting
            s.close()
            continue
        out.append(s)
    return out


def test_many_idle_connections_under_a_low_open_file_limit(wall):
    """150 idle connections against a server allowed 64 open files: fresh requests are still
    answered at once (the oldest idle connections are closed), and the server does not spin."""
    with server_process(wall, nofile=64, timeout=TIMEOUT) as (proc, port, workers, most):
        assert most < 64 and workers <= 4
        idle = _connect(port, 150)
        try:
            assert len(idle) > most
            for _ in range(5):
                assert answered_within(port, 1.5) < 1.5
            cpu = cpu_seconds(proc.pid)
            time.sleep(1.0)
            assert cpu_seconds(proc.pid) - cpu < 0.3  # a spinning accept loop burns a whole second
            idle += _connect(port, 100)  # and again, past the limit, while the first ones are held
            assert answered_within(port, 1.5) < 1.5
        finally:
            for s in idle:
                s.close()
        assert answered_within(port, 1.5) < 1.5


def test_idle_and_slow_requests_time_out(wall):
    """A connection that sends nothing, and one that sends its request a byte every 0.3 s, are
    both closed after the timeout; requests meanwhile are answered."""
    with server_process(wall, nofile=64, timeout=TIMEOUT) as (proc, port, workers, _):
        idle = _connect(port, 1)[0]
        slow = [_connect(port, 1)[0] for _ in range(workers * 3)]
        t0 = time.monotonic()
        closed_at = {}
        request = b"GET /api/scene.json HTTP/1.0\r\nHost: 127.0.0.1\r\nX-Pad: " + b"a" * 100
        i = 0
        while len(closed_at) < len(slow) + 1 and time.monotonic() - t0 < TIMEOUT + 3:
            for s in slow:
                if s not in closed_at:
                    try:
                        s.send(request[i:i + 1])
                    except OSError:
                        closed_at[s] = time.monotonic() - t0
            i += 1
            if idle not in closed_at:
                idle.setblocking(False)
                try:
                    if idle.recv(1) == b"":
                        closed_at[idle] = time.monotonic() - t0
                except BlockingIOError:
                    pass
                except OSError:
                    closed_at[idle] = time.monotonic() - t0
            assert answered_within(port, 1.0) < 1.0
            time.sleep(0.3)
        for s in [idle, *slow]:
            s.close()
        assert len(closed_at) == len(slow) + 1, f"{len(closed_at)} of {len(slow) + 1} closed"
        assert max(closed_at.values()) < TIMEOUT + 1.5, closed_at


def test_clients_that_never_read_are_dropped(wall):
    """More downloads than workers, never read: each worker gives up after the timeout (no
    progress), so a fresh request waits at most about that long; nothing is printed."""
    with server_process(wall, nofile=64, timeout=TIMEOUT) as (proc, port, workers, _):
        stuck = _connect(port, workers + 2)
        for s in stuck:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.sendall(f"GET /scene/bricks_color.png HTTP/1.0\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        try:
            took = answered_within(port, 3 * TIMEOUT + 2)
            assert took < 2 * TIMEOUT + 2, took
            time.sleep(TIMEOUT + 1)
            assert answered_within(port, 1.0) < 1.0  # every worker is free again
        finally:
            for s in stuck:
                s.close()
