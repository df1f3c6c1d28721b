"""A small HTTP/1.0 server with bounded resources, for ``csm-assets view`` (127.0.0.1 only).

One thread accepts connections and reads each request head without blocking; only a
complete head goes to one of ``workers`` threads (a fixed pool), which answers it with a
:class:`http.server.BaseHTTPRequestHandler` and closes the connection. So idle and slow
clients cost a socket, not a thread:

- a connection that has not sent its whole head within :attr:`BoundedServer.timeout`
  seconds is closed; a head over :data:`MAX_HEAD` bytes is answered as it stands (414/431);
- at most ``max_connections`` sockets are open at once (derived from the open-file limit,
  ``RLIMIT_NOFILE``): past it, the oldest connection still sending its head is closed; when
  every open one is being answered, accepting pauses (the kernel's queue holds the rest);
- a failed ``accept`` (out of file descriptors) closes the oldest idle connection or pauses
  accepting for a moment: the loop never spins;
- a response that makes no progress for ``timeout`` seconds is dropped (the handler's
  socket timeout), and the handler bounds a response's total time itself;
- closing, what the client still sends is drained for at most :data:`LINGER` seconds;
- errors of a request (a client gone mid-download, a timeout) are silent; anything
  unexpected is one ``csm-assets: warning:`` line, never a traceback.
"""

from __future__ import annotations

import errno
import io
import os
import queue
import selectors
import socket
import sys
import threading
import time

MAX_HEAD = 64 * 1024 + 2  # a request line BaseHTTPRequestHandler takes (65536) and its CRLF
LINGER = 0.25  # seconds a closing connection's unread input is drained
_FD_ERRORS = (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM)


def open_file_limit() -> int:
    """The soft open-file limit of this process (1024 where it cannot be read)."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        return 1 << 16 if soft == resource.RLIM_INFINITY else int(soft)
    except (ImportError, OSError, ValueError):
        return 1024


def _open_fds() -> int:
    try:
        return len(os.listdir("/proc/self/fd"))
    except OSError:
        return 32


class _Writer(io.RawIOBase):
    """The handler's ``wfile``: every write is a whole ``sendall``."""

    def __init__(self, sock):
        self.sock = sock

    def writable(self):
        return True

    def write(self, data):
        self.sock.sendall(data)
        return len(data)


def _close(sock, linger: float = LINGER) -> None:
    """Close after the answer: end our side, then read what the client still sends for at
    most ``linger`` seconds, so that unread input (a request past MAX_HEAD) does not make
    the kernel reset the connection before the client has read the answer."""
    try:
        sock.shutdown(socket.SHUT_WR)
        end = time.monotonic() + linger
        for _ in range(64):
            left = end - time.monotonic()
            if left <= 0:
                break
            sock.settimeout(left)
            if not sock.recv(65536):
                break
    except OSError:
        pass
    sock.close()


class BoundedServer:
    """Serve ``handler`` (a BaseHTTPRequestHandler subclass, built as
    ``handler(sock, address, server, head)``) on 127.0.0.1:``port`` (0: a free port).
    OSError when the port cannot be had. ``serve_forever``/``shutdown``/``server_close``
    as :mod:`socketserver`'s servers."""

    timeout = 10.0

    def __init__(self, handler, port: int = 0, workers: int | None = None):
        self.handler = handler
        limit = open_file_limit()
        self.workers = workers or max(2, min(16, limit // 16))
        # what is left of the file descriptors once the process's own and the workers'
        # files (one served file and two folders each) are counted
        self.max_connections = max(2, min(256, limit - _open_fds() - 3 * self.workers - 16))
        self.socket = socket.create_server(("127.0.0.1", int(port)), backlog=128)
        self.socket.setblocking(False)
        self.server_address = self.socket.getsockname()[:2]
        self._pending: dict[socket.socket, list] = {}  # socket -> [address, head, deadline]
        self._busy: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._stopped = threading.Event()
        self._stopped.set()
        self._accepting_at = 0.0  # accepting is paused until then

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.server_close()

    # the accepting thread
    def serve_forever(self, poll_interval: float = 0.5) -> None:
        self._stop.clear()
        self._stopped.clear()
        while len(self._threads) < self.workers:
            t = threading.Thread(target=self._work, daemon=True, name=f"csm-view-{len(self._threads)}")
            t.start()
            self._threads.append(t)
        sel = selectors.DefaultSelector()
        self._sel = sel
        listening = False
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                # full: accept still while an idle connection can make room, else pause
                can_accept = now >= self._accepting_at and (self._open() < self.max_connections
                                                           or bool(self._pending))
                if can_accept != listening:
                    if can_accept:
                        sel.register(self.socket, selectors.EVENT_READ)
                    else:
                        sel.unregister(self.socket)
                    listening = can_accept
                wait = poll_interval
                if self._pending:
                    wait = min(wait, max(0.0, next(iter(self._pending.values()))[2] - now))
                for key, _ in sel.select(wait):
                    if key.fileobj is self.socket:
                        self._accept(sel)
                    else:
                        self._read(sel, key.fileobj)
                self._expire(sel, time.monotonic())
        finally:
            for sock in list(self._pending):
                self._drop(sel, sock)
            sel.close()
            self._stopped.set()

    def _open(self) -> int:
        with self._lock:
            return len(self._pending) + len(self._busy)

    def _accept(self, sel) -> None:
        for _ in range(64):
            if self._open() >= self.max_connections and not self._evict(sel):
                return
            try:
                sock, address = self.socket.accept()
            except (BlockingIOError, InterruptedError, ConnectionAbortedError):
                return
            except OSError as e:
                if e.errno in _FD_ERRORS and self._evict(sel):
                    continue
                self._accepting_at = time.monotonic() + 0.1  # out of descriptors: wait, no spin
                return
            sock.setblocking(False)
            self._pending[sock] = [address, b"", time.monotonic() + self.timeout]
            sel.register(sock, selectors.EVENT_READ)

    def _evict(self, sel) -> bool:
        """Close the oldest connection still sending its head; False when there is none."""
        if not self._pending:
            return False
        self._drop(sel, next(iter(self._pending)))
        return True

    def _drop(self, sel, sock) -> None:
        self._pending.pop(sock, None)
        try:
            sel.unregister(sock)
        except (KeyError, ValueError):
            pass
        sock.close()

    def _read(self, sel, sock) -> None:
        entry = self._pending.get(sock)
        if entry is None:
            return
        try:
            data = sock.recv(MAX_HEAD)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            return self._drop(sel, sock)
        entry[1] += data
        head = entry[1]
        if b"\r\n\r\n" in head or b"\n\n" in head or len(head) >= MAX_HEAD:
            sel.unregister(sock)
            del self._pending[sock]
            with self._lock:
                self._busy.add(sock)
            self._jobs.put((sock, entry[0], head))

    def _expire(self, sel, now: float) -> None:
        for sock, entry in list(self._pending.items()):
            if entry[2] > now:
                break
            self._drop(sel, sock)

    # the workers
    def _work(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            sock, address, head = job
            try:
                sock.setblocking(True)
                sock.settimeout(self.timeout)
                self.handler(sock, address, self, head)
            except OSError:
                pass  # the client went away or stalled: nothing to tell the user
            except Exception as e:  # a bug in a handler: one line, the server goes on
                sys.stderr.write(f"csm-assets: warning: a request failed ({type(e).__name__}: {e})\n")
            finally:
                _close(sock)
                with self._lock:
                    self._busy.discard(sock)

    def shutdown(self) -> None:
        """Stop ``serve_forever`` (from another thread) and wait until it has."""
        self._stop.set()
        self._stopped.wait()

    def server_close(self) -> None:
        """Close the listening socket and every connection; stop the workers."""
        self._stop.set()
        self._stopped.wait(5)
        self.socket.close()
        with self._lock:
            busy = list(self._busy)
        for sock in busy:  # unblock workers sending to slow clients
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for _ in self._threads:
            self._jobs.put(None)
        self._threads.clear()


def make_handler_setup(handler, sock, head: bytes) -> None:
    """Give a BaseHTTPRequestHandler ``handler`` its streams: the request head already
    read (``rfile``) and the socket (``wfile``, whole writes)."""
    handler.connection = sock
    handler.rfile = io.BytesIO(head)
    handler.wfile = _Writer(sock)
