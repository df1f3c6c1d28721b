"""The reference MikkTSpace (mikktspace.c from the pymikktspace sdist), built for the tests.

The sdist is fetched from PyPI's simple index at test time and checked against a pinned
sha256 (``pip download`` cannot be used: it builds the package's metadata, which fails on
Python 3.11). Its mikktspace.c/.h are compiled with tests/mikktspace_shim.c by gcc into a
shared library called through ctypes. Nothing of MikkTSpace is kept in the repository.
Set CSM_MIKKTSPACE_SRC to a folder holding mikktspace.c/.h (or to the sdist) to work
offline.
"""

from __future__ import annotations

import ctypes
import hashlib
import io
import json
import os
import shutil
import subprocess
import tarfile
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np

SDIST = "pymikktspace-0.3.0.tar.gz"
SDIST_SHA256 = "26e88815c1ec5cd02481be6055d61a5a45f65e1cd04f95cf0917aa63dfc1115c"
INDEX = "https://pypi.org/simple/pymikktspace/"
MEMBER_DIR = "_external/MikkTSpace/"
SHIM = Path(__file__).with_name("mikktspace_shim.c")


class Unavailable(RuntimeError):
    """No network, no gcc: the reference cannot be had here (tests skip)."""


def _fetch_sdist() -> bytes:
    req = urllib.request.Request(INDEX, headers={"Accept": "application/vnd.pypi.simple.v1+json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            files = json.load(r)["files"]
        url = next(f["url"] for f in files if f["filename"] == SDIST)
        with urllib.request.urlopen(url, timeout=60) as r:
            data = r.read()
    except (urllib.error.URLError, OSError, TimeoutError) as e:
        raise Unavailable(f"cannot download {SDIST} from PyPI: {e}") from e
    if hashlib.sha256(data).hexdigest() != SDIST_SHA256:
        raise RuntimeError(f"{SDIST} from PyPI does not have the pinned sha256")
    return data


def _extract(data: bytes, dest: Path) -> None:
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        for m in tar.getmembers():
            name = m.name.split("/", 1)[-1]
            if name in (MEMBER_DIR + "mikktspace.c", MEMBER_DIR + "mikktspace.h"):
                (dest / Path(name).name).write_bytes(tar.extractfile(m).read())
    if not (dest / "mikktspace.c").is_file() or not (dest / "mikktspace.h").is_file():
        raise RuntimeError(f"{SDIST} holds no {MEMBER_DIR}mikktspace.c/.h")


def build(workdir: Path) -> Path:
    """Fetch, extract and compile; the path of the shared library made in ``workdir``."""
    gcc = shutil.which("gcc")
    if gcc is None:
        raise Unavailable("gcc is not installed")
    src = os.environ.get("CSM_MIKKTSPACE_SRC")
    if src and Path(src).is_dir():
        for name in ("mikktspace.c", "mikktspace.h"):
            shutil.copy(Path(src) / name, workdir / name)
    else:
        _extract(Path(src).read_bytes() if src else _fetch_sdist(), workdir)
    lib = workdir / "libcsm_mikk.so"
    cmd = [gcc, "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-I", str(workdir),
           str(SHIM), str(workdir / "mikktspace.c"), "-o", str(lib), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise Unavailable(f"gcc cannot build mikktspace.c here: {done.stderr.strip()[-500:]}")
    return lib


class Reference:
    """``tangents(p, n, uv)`` of unindexed triangle lists with the compiled mikktspace.c."""

    def __init__(self, lib_path: Path):
        self._lib = ctypes.CDLL(str(lib_path))
        f = self._lib.csm_mikk_tangents
        ptr = ctypes.POINTER(ctypes.c_float)
        f.argtypes = [ctypes.c_int, ptr, ptr, ptr, ptr]
        f.restype = ctypes.c_int
        self._f = f

    def tangents(self, p, n, uv) -> np.ndarray:
        """float32 ``(F, 3, 4)`` from per-corner ``(3F, 3)``, ``(3F, 3)``, ``(3F, 2)``."""
        arrays = [np.ascontiguousarray(a, dtype=np.float32).reshape(-1, k)
                  for a, k in ((p, 3), (n, 3), (uv, 2))]
        nf = arrays[0].shape[0] // 3
        out = np.zeros((nf, 3, 4), np.float32)
        ptr = ctypes.POINTER(ctypes.c_float)
        if nf:
            ok = self._f(nf, *(a.ctypes.data_as(ptr) for a in arrays), out.ctypes.data_as(ptr))
            if not ok:
                raise RuntimeError("genTangSpaceDefault failed")
        return out
