"""Keep C libraries' own stderr lines (libpng's "libpng error: ...") out of the tool's
output: the CLI promises one ``csm-assets: error:`` line, and the library's message
already comes back through its error state (OpenImageIO's ``geterror``)."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading

_lock = threading.Lock()


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
