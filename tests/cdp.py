"""A tiny headless-chromium driver: the DevTools protocol over ``--remote-debugging-pipe``.

No dependency beyond the standard library: chromium reads NUL-terminated JSON commands
on fd 3 and writes replies and events on fd 4. One page, flat sessions. The browser is
killed when the context manager ends, whatever happened.
"""

from __future__ import annotations

import base64
import json
import os
import select
import shutil
import subprocess
import tempfile
import time

# WebGL2 without a GPU: ANGLE on SwiftShader (Chromium refuses it unless told it is wanted)
FLAGS = ["--headless", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
         "--no-first-run", "--no-default-browser-check", "--disable-extensions", "--disable-dev-shm-usage",
         "--disable-background-networking", "--disable-component-update", "--mute-audio",
         "--force-device-scale-factor=1", "--hide-scrollbars"]


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        exe = shutil.which(name)
        if exe:
            return exe
    return None


class CdpError(RuntimeError):
    pass


class Chromium:
    """``with Chromium(640, 480) as b: b.goto(url); b.eval("1 + 1")``."""

    def __init__(self, width: int, height: int, timeout: float = 60.0):
        exe = find_chromium()
        if exe is None:
            raise CdpError("no chromium on PATH")
        self.timeout = timeout
        self.size = (int(width), int(height))
        self._profile = tempfile.TemporaryDirectory(prefix="csm-chromium-")
        to_child, self._out = os.pipe()
        self._in, from_child = os.pipe()
        # keep the child's ends off 3 and 4, which the shell below fills
        to_child, from_child = (self._high(fd) for fd in (to_child, from_child))
        args = [exe, *FLAGS, f"--window-size={width},{height}", f"--user-data-dir={self._profile.name}",
                "--remote-debugging-pipe", "about:blank"]
        shell = f'exec "$0" "$@" 3<&{to_child} 4>&{from_child} {to_child}<&- {from_child}>&-'
        self.proc = subprocess.Popen(["bash", "-c", shell, *args], pass_fds=(to_child, from_child),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(to_child)
        os.close(from_child)
        self._buf = b""
        self._id = 0
        self.events: list = []
        self.session = None

    @staticmethod
    def _high(fd: int) -> int:
        new = os.dup2(fd, fd + 20) if fd < 10 else fd
        if new != fd:
            os.close(fd)
        return new

    def __enter__(self):
        try:
            targets = self.call("Target.getTargets")["targetInfos"]
            page = next(t for t in targets if t["type"] == "page")
            self.session = self.call("Target.attachToTarget", {"targetId": page["targetId"], "flatten": True},
                                     session=False)["sessionId"]
            self.call("Page.enable")
            self.call("Runtime.enable")
            self.call("Emulation.setDeviceMetricsOverride", {"width": self.size[0], "height": self.size[1],
                                                             "deviceScaleFactor": 1, "mobile": False})
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self._write({"id": 10**9, "method": "Browser.close"})
                self.proc.wait(timeout=10)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, 9)
            self.proc.wait()
        for fd in (self._in, self._out):
            try:
                os.close(fd)
            except OSError:
                pass
        self._profile.cleanup()

    def _write(self, msg: dict) -> None:
        os.write(self._out, json.dumps(msg).encode() + b"\0")

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise CdpError("chromium did not answer in time")
            ready, _, _ = select.select([self._in], [], [], left)
            if ready:
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise CdpError("chromium closed the pipe")
                self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def call(self, method: str, params: dict | None = None, session=None, timeout: float | None = None):
        """Send a command and return its result (events seen meanwhile go to ``events``)."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session is not False and (session or self.session):
            msg["sessionId"] = session or self.session
        self._write(msg)
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            reply = self._read(deadline)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise CdpError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_event(self, method: str, timeout: float | None = None) -> dict:
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            for i, e in enumerate(self.events):
                if e.get("method") == method:
                    return self.events.pop(i)
            self.events.append(self._read(deadline))

    def goto(self, url: str) -> None:
        self.events.clear()
        self.call("Page.navigate", {"url": url})
        self.wait_event("Page.loadEventFired")

    def eval(self, expression: str, timeout: float | None = None):
        """The value of a JS expression (promises awaited); CdpError on an exception."""
        r = self.call("Runtime.evaluate", {"expression": expression, "awaitPromise": True,
                                           "returnByValue": True}, timeout=timeout)
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            raise CdpError(f"{expression[:60]}: {d.get('exception', {}).get('description') or d.get('text')}")
        return r["result"].get("value")

    def console_errors(self) -> list:
        return [e["params"] for e in self.events if e.get("method") == "Runtime.exceptionThrown"
                or (e.get("method") == "Runtime.consoleAPICalled" and e["params"].get("type") == "error")]

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])
