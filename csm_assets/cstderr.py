"""Keep C libraries' own stderr lines (libpng's "libpng error: ...") out of the tool's
output: the CLI promises one ``csm-assets: error:`` line, and the library's message
already comes back through its error state (OpenImageIO's ``geterror``).

File descriptor 2 is the process's, not a thread's: while one thread writes an image inside
:func:`captured`, a line another thread writes to fd 2 lands in the capture and is lost. The
CLI therefore writes its own lines through a duplicate of fd 2 (:func:`own_stderr`), which no
capture redirects. A program using the library that writes to fd 2 from other threads while
images are written can do the same.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import threading

_lock = threading.Lock()


def own_stderr() -> bool:
    """Point ``sys.stderr`` at a duplicate of file descriptor 2 (the same terminal, pipe or
    file, its encoding and errors kept) so that what Python writes there is never caught by a
    :func:`captured` block another thread holds. Call it before other threads start; True if
    it did, False where ``sys.stderr`` is not fd 2 (a test's buffer, no stderr: left as it is)."""
    s = sys.stderr
    try:
        if s is None or s.fileno() != 2:
            return False
        s.flush()
        fd = os.dup(2)
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        return False
    sys.stderr = io.TextIOWrapper(io.FileIO(fd, "w"), encoding=s.encoding, errors=s.errors,
                                  line_buffering=True, write_through=True)
    return True


@contextlib.contextmanager
def captured():
    """Redirect file descriptor 2 into a temporary file while the block runs; yields a
    list that holds the captured text (one string) afterwards. Nested and concurrent uses
    are serialized; where fd 2 cannot be redirected the block runs as it is."""
    out: list[str] = []
    with _lock:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):
            yield out
            return
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield out
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                sink.seek(0)
                out.append(sink.read().decode("utf-8", "replace"))
