"""Cold-start machinery: interpreted twins give the compiled kernels' results, the compile
notice, and serial kernels on threads give the same cones as one thread."""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys

import numba
import numpy as np
import pytest
from numba.core import event

from csm_assets.cones import exact as cones
from csm_assets import kernels
from csm_assets.tangents.mikktspace import mikktspace
from csm_assets.polling import run_chunks


def _tangled(rng):
    nv, nf, k = rng.integers(3, 60), rng.integers(1, 200), rng.integers(2, 8)
    vals = rng.normal(size=k).astype(np.float32)
    faces = rng.integers(0, nv, (nf, 3)).reshape(-1)
    p = vals[rng.integers(0, k, (nv, 3))][faces]
    uv = vals[rng.integers(0, k, (nv, 2))][faces]
    n = rng.normal(size=(nv, 3)).astype(np.float32)[faces]
    return p, n, uv


def test_interpreted_mikktspace_is_bit_identical_to_compiled():
    """Tangled meshes (shared, repeated and degenerate corners, non-manifold edges,
    zero uv areas) and a smooth grid: the twin and the compiled kernels agree exactly."""
    rng = np.random.default_rng(7)
    meshes = [_tangled(rng) for _ in range(60)]
    g = np.stack(np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 1, 9)), -1).reshape(-1, 2)
    tri = np.array([[0, 1, 13], [0, 13, 12]])
    idx = (np.arange(11)[:, None, None] + 12 * np.arange(8)[None, :, None]).reshape(-1, 1, 1)
    faces = (idx + tri).reshape(-1)
    p = np.c_[g, np.sin(g[:, 0] * 3)].astype(np.float32)[faces]
    meshes.append((p, np.tile(np.float32([0, 0, 1]), (len(faces), 1)), g.astype(np.float32)[faces]))
    for p, n, uv in meshes:
        t1, o1 = mikktspace(p, n, uv, interpret=True)
        t2, o2 = mikktspace(p, n, uv, interpret=False)
        np.testing.assert_array_equal(t1, t2)
        np.testing.assert_array_equal(o1, o2)


def test_small_meshes_run_interpreted_by_default(monkeypatch):
    seen = []
    real = kernels.run
    monkeypatch.setattr("csm_assets.tangents.mikktspace.run",
                        lambda k, *a, interpret: seen.append(interpret) or real(k, *a, interpret=interpret))
    p, n, uv = _tangled(np.random.default_rng(1))
    mikktspace(p, n, uv)
    assert seen and all(seen)


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_compile_notice_once_on_a_terminal_only(monkeypatch):
    monkeypatch.setattr(kernels, "_NOTICE", None)
    assert kernels.notice_compiling(io.StringIO()) is None
    out = _Tty()
    listener = kernels.notice_compiling(out)
    try:
        assert kernels.notice_compiling(out) is listener

        def other(x):
            return x + 1

        numba.njit(other)(1)  # not ours: no notice
        assert out.getvalue() == ""

        def ours(x):
            return x * 2

        ours.__module__ = "csm_assets.probe"
        numba.njit(ours)(1)
        numba.njit(ours)(2.0)
        assert out.getvalue() == "csm-assets: compiling kernels, first run only\n"
    finally:
        event.unregister("numba:compile", listener)


@pytest.mark.parametrize("method", sorted(cones.METHODS))
@pytest.mark.parametrize("threads", [1, 3])
def test_threads_give_the_same_cones(method, threads, monkeypatch):
    """Chunks on several threads (dynamic balance) give one thread's result bit for bit."""
    h = np.random.default_rng(3).integers(0, 9, (37, 29)).astype(np.float64) / 8
    ref = cones.exact_ratios(h, True, False, 1.0, method=method)
    monkeypatch.setattr("csm_assets.polling.thread_count", lambda: threads)
    calls = []
    got = cones.exact_ratios(h, True, False, 1.0, method=method,
                             progress=lambda d, t: calls.append((d, t)))
    np.testing.assert_array_equal(got, ref)
    assert calls[-1][0] == calls[-1][1]


def test_run_chunks_raises_a_kernels_error():
    done = np.zeros(10, np.uint8)

    def kernel(a, b):
        if a >= 4:
            raise ValueError("boom")
        done[a:b] = 1

    with pytest.raises(ValueError, match="boom"):
        run_chunks(kernel, 10, done, None, chunk=2, threads=2)


def test_cache_location_falls_back_to_the_temp_dir(monkeypatch, tmp_path):
    """Without a writable user cache folder the kernels cache under $TMPDIR; with nowhere
    writable at all, caching is off (import must not fail); NUMBA_CACHE_DIR wins."""
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", "")
    monkeypatch.setattr(kernels.tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(kernels, "_writable", lambda d: str(d).startswith(str(tmp_path)))
    assert kernels.cache_location()
    assert kernels._ROOT.startswith(str(tmp_path / "csm-assets-numba-"))
    monkeypatch.setattr(kernels, "_writable", lambda d: False)
    assert not kernels.cache_location()
    monkeypatch.setattr(kernels, "_writable", lambda d: True)
    monkeypatch.setattr(config, "CACHE_DIR", "/somewhere")
    assert kernels.cache_location()
    assert kernels._ROOT == os.path.join("/somewhere", "csm-assets")
    monkeypatch.setattr(config, "CACHE_DIR", "")
    kernels.cache_location()


_CACHE_STATS = """
import numpy as np, sys
from numba.core.dispatcher import Dispatcher
import csm_assets
csm_assets.cone_ratios(np.random.default_rng(1).random((48, 40), dtype=np.float32))
ds = [v for name, m in list(sys.modules.items()) if name.startswith("csm_assets")
      for v in vars(m).values() if isinstance(v, Dispatcher)]
print(csm_assets.__file__, sum(sum(d.stats.cache_hits.values()) for d in ds), sum(sum(d.stats.cache_misses.values()) for d in ds))
"""


def test_two_installs_share_one_kernel_cache(tmp_path):
    """Two environments holding the same sources at different paths (a tox env, a
    pre-commit hook's env) share one cache: the second compiles nothing and writes nothing
    beside its sources; a changed kernel source compiles again."""
    cache = tmp_path / "cache"

    def install(name):
        shutil.copytree(kernels.PACKAGE, tmp_path / name / "csm_assets",
                        ignore=shutil.ignore_patterns("__pycache__", "web", "blender"))
        return tmp_path / name

    def hits_misses(site):
        env = {**os.environ, "PYTHONPATH": str(site), "NUMBA_CACHE_DIR": str(cache)}
        r = subprocess.run([sys.executable, "-c", _CACHE_STATS], env=env, capture_output=True, text=True,
                           timeout=600, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        where, hits, misses = r.stdout.split()
        assert where.startswith(str(site))
        return int(hits), int(misses)

    a, b = install("a"), install("b")
    assert hits_misses(a)[1] > 0  # compiled
    hits, misses = hits_misses(b)
    assert (hits > 0, misses) == (True, 0)
    assert not list(b.rglob("*.nbi")) and not list(b.rglob("*.nbc"))
    ring = b / "csm_assets" / "cones" / "ring.py"
    ring.write_text(ring.read_text() + "\n# another build\n")
    assert hits_misses(b)[1] > 0
