"""Big arrays go back to the system when freed (glibc's malloc), so that the peak memory of a
command is what its live arrays take.

glibc serves a block of at least its *mmap threshold* (128 KiB at start) with its own mapping,
unmapped when freed, but it raises the threshold to the size of each such block freed (up to
32 MiB): after a 4 MiB array goes, every array below 4 MiB comes from the heap, whose freed
space mostly stays resident. A step map works in bands of such arrays, and measured from outside,
a 2048 x 2048 quadrant map peaked 8 bytes a texel higher that way (41.5 against 32.9 with the
threshold fixed: docs/measurements/memory.md). :func:`fix_mmap_threshold` fixes it at start (the
commands call it; a library caller may). Elsewhere (no glibc) it does nothing.
"""

from __future__ import annotations

import ctypes

M_MMAP_THRESHOLD = -3  # mallopt's parameter (malloc.h)
THRESHOLD = 128 * 1024  # glibc's starting value, kept


def fix_mmap_threshold(size: int = THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``size`` bytes (no more dynamic raising); True if done."""
    try:
        mallopt = getattr(ctypes.CDLL(None), "mallopt", None)  # the process's own symbols: libc's
    except (OSError, TypeError):  # no such handle (Windows)
        return False
    return bool(mallopt is not None and mallopt(M_MMAP_THRESHOLD, int(size)) == 1)
