"""The local process pool of a batch (:mod:`csm_assets.convert.batch`): workers started by
spawn (numba's OpenMP threads do not survive a fork), one kernel thread each, that die with
their parent and leave Ctrl-C to it, and the pool's stop after Ctrl-C."""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes, each started by :func:`worker_start`."""
    return ProcessPoolExecutor(workers, initializer=worker_start, initargs=(os.getpid(),),
                               mp_context=multiprocessing.get_context("spawn"))


def worker_start(parent: int) -> None:
    """Process-pool initializer: the workers share the cores, so each kernel gets one; a
    worker whose parent died (``kill -9`` of the batch) exits instead of running on; Ctrl-C
    (SIGINT to the whole process group) is ignored, the main process says it and stops the
    workers with SIGTERM, which ends a worker quietly (its job's clean-up runs)."""
    import numba

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _stop_worker)
    sys.unraisablehook = _stop_again
    if hasattr(signal, "pthread_sigmask"):  # blocked by the parent while it started us (run)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    numba.set_num_threads(1)
    _die_with_parent(parent)
    threading.Thread(target=_exit_with_parent, args=(parent,), name="csm-parent-watch", daemon=True).start()


def _die_with_parent(parent: int) -> None:
    """Linux: the kernel kills this worker when its parent dies (``PR_SET_PDEATHSIG``)."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
        if os.getppid() != parent:
            os._exit(1)


def _stop_worker(signum, frame) -> None:
    raise SystemExit(130)  # quiet, unlike KeyboardInterrupt; finally blocks run


def _stop_again(unraisable) -> None:
    """A stop raised where it cannot unwind (inside a C callback: numba's compiler calls back
    into Python while it compiles, on a fresh clone's first run) would print "Exception ignored"
    and a traceback, and the worker would run on: the signal is sent again a moment later, from
    another thread (sent from here it would be taken here, still inside the callback), until it
    lands in Python outside one. Other unraisable exceptions are reported as usual."""
    if isinstance(unraisable.exc_value, SystemExit):
        again = threading.Timer(0.01, os.kill, (os.getpid(), signal.SIGTERM))
        again.daemon = True
        again.start()
        return
    sys.__unraisablehook__(unraisable)


@contextlib.contextmanager
def sigint_blocked():
    """SIGINT held back while worker processes start: they inherit the mask (so none dies of a
    Ctrl-C before its initializer ignores it); here it is delivered when the block ends."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def stop_pool(pool: ProcessPoolExecutor, wait: float = 10.0) -> None:
    """After Ctrl-C: drop the queued scenes and end the workers (SIGTERM, then SIGKILL for one
    that has not ended after ``wait`` seconds)."""
    pool.shutdown(wait=False, cancel_futures=True)
    workers = multiprocessing.active_children()
    for p in workers:
        p.terminate()
    end = time.monotonic() + wait
    for p in workers:
        p.join(max(0.0, end - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1.0)


def _exit_with_parent(parent: int, interval: float = 0.25) -> None:
    while os.getppid() == parent:
        time.sleep(interval)
    os._exit(1)  # orphaned: the staging folder it leaves is removed by the next run
