"""Peak memory of a command, measured from outside it: the kernel's count of its resident pages.

Linux records in a process's ``ru_maxrss`` the resident size of the memory it replaced at
``exec`` too: a child forked from a big process (a test runner, a benchmark that has read large
maps) starts with the parent's size as its peak. So the command runs under a small launcher (a
bare Python that imports nothing else), which forks it, waits for it with ``os.wait4`` and prints
its peak and CPU time: the command's own figures, as ``/usr/bin/time`` gives them.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

_LAUNCHER = """
import json, os, subprocess, sys
child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
err = child.stderr.read()
_, status, use = os.wait4(child.pid, 0)
print(json.dumps({"peak": use.ru_maxrss * 1024, "cpu": use.ru_utime + use.ru_stime,
                  "code": os.waitstatus_to_exitcode(status), "err": err.decode(errors="replace")[-2000:]}))
"""


def measure(cmd, *, cwd=None, env=None) -> dict:
    """``{"peak": bytes, "cpu": seconds, "wall": seconds}`` of command ``cmd`` (a list); RuntimeError
    with its last stderr when it fails."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-S", "-c", _LAUNCHER, *map(str, cmd)], cwd=cwd, env=env,
                         capture_output=True, text=True, check=True).stdout
    wall = time.perf_counter() - start
    got = json.loads(out.strip().splitlines()[-1])
    if got["code"]:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed ({got['code']}): {got['err'].strip()}")
    return {"peak": got["peak"], "cpu": got["cpu"], "wall": wall}
