"""Progress for long numba kernels without splitting them into many parallel launches.

A parallel launch costs a few milliseconds when the cores are shared, so each
kernel runs as one launch (GIL released: ``nogil=True``) in a worker thread and
marks its finished units in ``done``; the caller's thread reports ``done.sum()``.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np


def run_polled(kernel: Callable[[], None], done: np.ndarray,
               progress: Callable[[int, int], None] | None, interval: float = 0.2) -> None:
    """Run ``kernel()``; meanwhile call ``progress(done.sum(), done.size)`` every ``interval`` s.

    The kernel always runs in a worker thread, so the calling thread stays free to take
    Ctrl-C (KeyboardInterrupt) at once instead of after the kernel. Errors raised by the
    kernel are raised here.
    """
    if progress is None:
        progress = _quiet
    failure: list[BaseException] = []

    def work():
        try:
            kernel()
        except BaseException as e:  # handed to the caller's thread below
            failure.append(e)

    worker = threading.Thread(target=work, name="csm-cones", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(interval)
        if worker.is_alive():
            progress(int(done.sum()), done.size)
    if failure:
        raise failure[0]
    progress(done.size, done.size)


def _quiet(done: int, total: int) -> None:
    """No progress to show."""
