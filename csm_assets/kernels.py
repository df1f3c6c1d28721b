"""Numba kernels on a cold start: interpreted twins for tiny inputs, one notice on compiling.

Every kernel is ``@njit(cache=CACHE)`` without eager signatures: a kernel compiles the
first time a run calls it (about a second each on two cores) and loads from numba's
cache afterwards: one cache per machine, shared by every environment that installs the
same sources (:class:`SharedCacheLocator`). Where the input is tiny (a wall of a few triangles), running the
same Python source interpreted is quicker than compiling it: :func:`interpreted`
gives that twin, with the kernels it calls swapped for their twins too.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile
import threading
import types
from pathlib import Path

import numba
import numpy as np
from numba.core import config
from numba.core import caching
from numba.core.caching import _CacheLocator
from numba.core.dispatcher import Dispatcher
from numba.misc.appdirs import AppDirs

PACKAGE = Path(__file__).resolve().parent


def _writable(folder) -> bool:
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def _cache_root() -> str | None:
    """Where our kernels cache: ``$NUMBA_CACHE_DIR/csm-assets``, else the user's cache folder
    (``~/.cache/csm-assets/numba`` on Linux), else ``$TMPDIR/csm-assets-numba-UID``; None
    when none is writable."""
    if config.CACHE_DIR:
        candidates = [os.path.join(config.CACHE_DIR, "csm-assets")]
    else:
        uid = os.getuid() if hasattr(os, "getuid") else "user"
        candidates = [os.path.join(AppDirs(appname="csm-assets", appauthor=False).user_cache_dir, "numba"),
                      os.path.join(tempfile.gettempdir(), f"csm-assets-numba-{uid}")]
    return next((c for c in candidates if _writable(c)), None)


def _source_digest(path) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


@functools.cache  # once per process: the sources do not change under it
def kernels_key() -> str:
    """One key for this build of the kernels: Python, numba and numpy versions and the
    sources of every module of the package that defines a kernel (a kernel's cache holds
    the kernels it calls, so a change in any of them must miss). The same sources installed
    in two environments give the same key, wherever they are installed."""
    h = hashlib.sha256(f"{sys.version_info[:2]} numba {numba.__version__} numpy {np.__version__}".encode())
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_bytes()
        if b"@njit" in text:
            h.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + text)
    return h.hexdigest()[:20]


class SharedCacheLocator(_CacheLocator):
    """numba's cache for the package's kernels, keyed by content, not by install path.

    numba caches a kernel beside its source or under a hash of the source's absolute path,
    so every new environment (a pre-commit hook's, a tox env's, a fresh venv) compiles
    every kernel again. Here the cache lies in ``<root>/<kernels_key()>/<subpackage>``:
    the same sources share it across environments on the machine, and a change in any
    kernel's source selects a new folder. Functions outside the package are not ours.
    """

    def __init__(self, py_func, py_file, rel: Path):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._path = os.path.join(_ROOT, kernels_key(), *rel.parent.parts)

    def get_cache_path(self):
        return self._path

    def get_source_stamp(self):
        return _source_digest(self._py_file)  # by content: every install's own mtimes agree

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            rel = Path(py_file).resolve().relative_to(PACKAGE)
        except (OSError, ValueError):
            return None
        self = cls(py_func, py_file, rel)
        try:
            self.ensure_cache_path()
        except OSError:
            return None
        return self


_ROOT = None


def cache_location() -> bool:
    """Set up the shared cache of our kernels (:class:`SharedCacheLocator`); False when
    nowhere is writable (kernels then compile on every run; import must not fail).

    ``NUMBA_CACHE_LOCATOR_CLASSES``, numba's own override, still wins over ours.
    """
    global _ROOT
    _ROOT = _cache_root()
    if _ROOT is None:
        return False
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.58
    locators = impl._locator_classes
    if SharedCacheLocator not in locators:
        locators.insert(0, SharedCacheLocator)
    return True


CACHE = cache_location()  # every kernel is @njit(cache=CACHE)

_TWINS: dict[int, types.FunctionType] = {}
_GLOBALS: dict[str, dict] = {}
_LOCK = threading.Lock()
_NOTICE = None


def interpreted(kernel):
    """The interpreted twin of numba kernel ``kernel`` (same source, same results).

    Calls inside it to other kernels go to their twins. Call it under
    ``np.errstate(all="ignore")`` as numba's ``error_model="numpy"`` does.
    """
    with _LOCK:
        return _twin(kernel)


def _twin(kernel):
    if not isinstance(kernel, Dispatcher):
        return kernel
    twin = _TWINS.get(id(kernel))
    if twin is None:
        f = kernel.py_func
        twin = types.FunctionType(f.__code__, _module_globals(f), f.__name__, f.__defaults__,
                                  f.__closure__)
        _TWINS[id(kernel)] = twin
    return twin


def _module_globals(f) -> dict:
    """A copy of ``f``'s module globals with every kernel in it replaced by its twin."""
    g = _GLOBALS.get(f.__module__)
    if g is None:
        g = _GLOBALS[f.__module__] = dict(f.__globals__)
        for name, value in list(g.items()):
            if isinstance(value, Dispatcher):
                g[name] = _twin(value)
    return g


def run(kernel, *args, interpret: bool = False):
    """``kernel(*args)`` compiled, or interpreted (its twin, numpy's error model) if ``interpret``."""
    if not interpret:
        return kernel(*args)
    with np.errstate(all="ignore"):
        return interpreted(kernel)(*args)


def notice_compiling(stream=None, line: str = "csm-assets: compiling kernels, first run only"):
    """Write ``line`` once to ``stream`` (stderr) when one of our kernels compiles (not when
    it loads from numba's cache), and only where ``stream`` is a terminal.

    Registered once per process (later calls return the same listener; ``numba.core.
    event.unregister("numba:compile", it)`` removes it); None off a terminal.
    """
    global _NOTICE
    from numba.core import event

    stream = stream or sys.stderr
    if not getattr(stream, "isatty", lambda: False)():
        return None
    if _NOTICE is not None:
        return _NOTICE

    class CompileNotice(event.Listener):
        said = False

        def on_start(self, ev):
            d = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            mod = getattr(getattr(d, "py_func", None), "__module__", "") or ""
            if not self.said and mod.startswith("csm_assets"):
                self.said = True
                print(line, file=stream, flush=True)

        def on_end(self, ev):
            pass

    _NOTICE = CompileNotice()
    event.register("numba:compile", _NOTICE)
    return _NOTICE
