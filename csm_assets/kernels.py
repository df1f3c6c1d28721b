"""Numba kernels on a cold start: interpreted twins for tiny inputs, one notice on compiling.

Every kernel is ``@njit(cache=CACHE)`` without eager signatures: a kernel compiles the
first time a run calls it (about a second each on two cores) and loads from numba's
cache afterwards. Where the input is tiny (a wall of a few triangles), running the
same Python source interpreted is quicker than compiling it: :func:`interpreted`
gives that twin, with the kernels it calls swapped for their twins too.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import types
from pathlib import Path

import numpy as np
from numba.core import config
from numba.core.dispatcher import Dispatcher
from numba.misc.appdirs import AppDirs

def _writable(folder) -> bool:
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def cache_location() -> bool:
    """Make sure numba has somewhere to cache our kernels; False when nowhere is writable.

    numba caches beside the source (``__pycache__``, fine in a venv) or in the user's
    cache folder; in a container with a read-only install and no writable home it
    finds neither and ``cache=True`` fails at import. Then the kernels cache in
    ``$TMPDIR/csm-assets-numba-UID`` (``NUMBA_CACHE_DIR`` always wins).
    """
    if config.CACHE_DIR:
        return True
    if _writable(Path(__file__).parent / "__pycache__"):
        return True
    if _writable(AppDirs(appname="numba", appauthor=False).user_cache_dir):
        return True
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    fallback = os.path.join(tempfile.gettempdir(), f"csm-assets-numba-{uid}")
    if _writable(fallback):
        config.CACHE_DIR = fallback
        return True
    return False


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
