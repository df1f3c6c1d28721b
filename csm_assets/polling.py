"""Run a serial numba kernel over chunks of work on several threads, with progress.

The cone kernels are plain serial ``@njit(nogil=True)`` functions over a range of
work units (rows of a map, levels); this module runs them on ``numba.get_num_threads()``
Python threads that take chunks from a shared queue (dynamic balancing, so rows of
very different cost even out). A serial kernel compiles several times faster than a
``parallel=True`` one, which matters on a fresh install where every kernel compiles
once. The calling thread reports ``done.sum()`` now and then.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np


def thread_count() -> int:
    """Threads to use: numba's setting (``NUMBA_NUM_THREADS``, ``numba.set_num_threads``)."""
    import numba

    return max(1, int(numba.get_num_threads()))


def run_chunks(kernel: Callable[[int, int], None], n: int, done: np.ndarray,
               progress: Callable[[int, int], None] | None, *, chunk: int = 1,
               threads: int | None = None, interval: float = 0.2) -> None:
    """Call ``kernel(start, stop)`` for consecutive ranges of ``chunk`` units covering 0..n.

    The kernel marks its finished units in ``done`` (uint8); ``progress(done.sum(),
    done.size)`` is called every ``interval`` s and once at the end. Errors raised by
    the kernel are raised here (the first one; the other threads stop taking chunks).
    """
    threads = max(1, min(threads or thread_count(), -(-n // max(chunk, 1)) if n else 1))
    starts = iter(range(0, n, max(chunk, 1)))
    lock = threading.Lock()
    failure: list[BaseException] = []

    def work():
        while not failure:
            with lock:
                s = next(starts, None)
            if s is None:
                return
            try:
                kernel(s, min(n, s + chunk))
            except BaseException as e:  # handed to the caller's thread below
                failure.append(e)

    if threads == 1 and progress is None:
        work()
    else:
        workers = [threading.Thread(target=work, name=f"csm-cones-{i}", daemon=True)
                   for i in range(threads)]
        for w in workers:
            w.start()
        for w in workers:
            while w.is_alive():
                w.join(interval)
                if w.is_alive() and progress is not None:
                    progress(int(done.sum()), done.size)
    if failure:
        raise failure[0]
    if progress is not None:
        progress(done.size, done.size)


def row_chunk(rows: int, threads: int | None = None) -> int:
    """Rows per chunk: about 16 chunks per thread, so uneven rows balance out."""
    return max(1, rows // (16 * (threads or thread_count())))
