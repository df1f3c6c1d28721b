"""Resource limits: how big an input may be before it is refused, checked before allocating.

Each limit has a default and an environment variable ``CSM_ASSETS_MAX_<KIND>`` that
overrides it (a positive integer), so a pipeline with big assets and big machines can
raise it and a service taking untrusted files can lower it:

- ``CSM_ASSETS_MAX_TEXELS``: texels of one image (default 2**28, a 16384 x 16384 map).
- ``CSM_ASSETS_MAX_VERTICES``: elements of one mesh accessor or vertex array, and the
  vertices a scene may hold in all (default 2**25, 33.5 M).
- ``CSM_ASSETS_MAX_MATERIALS``: materials (and textures, images) of one scene
  (default 65536).
- ``CSM_ASSETS_MAX_JSON_OBJECTS``: JSON objects of one glTF document, counted as its
  ``{`` bytes before parsing (default 2**21; a million-material file is refused in a
  second instead of taking 3 GB to parse).

A file over a limit is a :class:`~csm_assets.errors.FormatError` (exit 3) naming the
file, what it declares, the limit and the variable to raise.

An image within ``CSM_ASSETS_MAX_TEXELS`` is still refused, from its header and before it
is decoded, when making its step map would need more memory than the process can have
(:func:`check_memory`: :data:`BYTES_PER_TEXEL` a texel, against the memory available, the
address-space limit ``ulimit -v`` and the cgroup's ``memory.max``); the message says how
much it needs, how much there is and the texel limit to lower.
"""

from __future__ import annotations

import os

from .errors import FormatError

DEFAULTS = {"TEXELS": 1 << 28, "VERTICES": 1 << 25, "MATERIALS": 1 << 16, "JSON_OBJECTS": 1 << 21}


def env_name(kind: str) -> str:
    return f"CSM_ASSETS_MAX_{kind.upper()}"


def limit(kind: str) -> int:
    """The limit of ``kind`` (TEXELS, VERTICES, MATERIALS): the environment's, else the
    default. ValueError (a usage error, exit 2) when the variable is not a positive integer."""
    kind = kind.upper()
    raw = os.environ.get(env_name(kind))
    if raw is None or raw.strip() == "":
        return DEFAULTS[kind]
    try:
        value = int(raw.strip().replace("_", ""))
    except ValueError:
        value = 0
    if value <= 0:
        raise ValueError(f"{env_name(kind)}={raw!r}: expected a positive integer")
    return value


def check(path, kind: str, count: int, what: str, noun: str | None = None) -> None:
    """FormatError naming ``path`` when ``count`` (of ``noun``, default the kind's own
    name) that ``what`` declares exceeds the ``kind`` limit; for texels, also when the
    memory to make its step map is not there (:func:`check_memory`)."""
    top = limit(kind)
    if count > top:
        raise FormatError(path, f"{what} declares {count:,} {noun or kind.lower()}, over the limit of "
                                f"{top:,} (raise it with {env_name(kind)})")
    if kind.upper() == "TEXELS":
        check_memory(path, count, what)


# bytes one texel costs while its step map is made, with margin (benchmarks/memory.py, peak RSS over
# the interpreter's, 2048^2, 2026-12-07: conservative cones of 8- and 16-bit maps 25-26, quadrant
# cones 33-34, float input 29 and 36.5; 128 before the packing worked in bands, quadrant 66 before
# its cones were kept as codes; docs/measurements/memory.md).
BYTES_PER_TEXEL = 40


def _gib(n: float) -> str:
    return f"{n / (1 << 30):.1f} GiB"


def available_memory() -> tuple[int, str] | None:
    """``(bytes, where)``: the most this process can still allocate, and what bounds it
    (``MemAvailable``, ``ulimit -v``, ``ulimit -d``, the cgroup's ``memory.max``); None where
    nothing can be read (not Linux)."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            info = dict(line.split(":", 1) for line in f)
        found.append((int(info["MemAvailable"].split()[0]) * 1024, "memory available"))
        with open("/proc/self/status") as f:
            status = dict(line.split(":", 1) for line in f if ":" in line)
        mapped = int(status["VmSize"].split()[0]) * 1024
        data = int(status.get("VmData", "0 kB").split()[0]) * 1024
    except (OSError, KeyError, ValueError):
        return None
    try:
        import resource

        for rlimit, used, name in ((resource.RLIMIT_AS, mapped, "ulimit -v"), (resource.RLIMIT_DATA, data, "ulimit -d")):
            soft = resource.getrlimit(rlimit)[0]
            if soft != resource.RLIM_INFINITY:
                found.append((max(soft - used, 0), f"the process's {name}"))
    except (ImportError, OSError, ValueError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            top = f.read().strip()
        if top != "max":
            with open("/sys/fs/cgroup/memory.current") as f:
                found.append((max(int(top) - int(f.read()), 0), "the cgroup's memory.max"))
    except (OSError, ValueError):
        pass
    return min(found)


def check_memory(path, texels: int, what: str) -> None:
    """FormatError naming ``path`` when making the step map of ``texels`` (declared by
    ``what``) needs more memory than :func:`available_memory` finds, before anything is
    decoded: how much it needs, how much there is, and the texel limit to lower."""
    need = texels * BYTES_PER_TEXEL
    free = available_memory()
    if free is None or need <= free[0]:
        return
    fits = max(free[0] // BYTES_PER_TEXEL, 1)
    raise FormatError(path, f"{what} ({texels:,} texels) needs about {_gib(need)} of memory to make its step "
                            f"map ({BYTES_PER_TEXEL} bytes a texel), and {free[1]} leaves about {_gib(free[0])}; "
                            f"lower {env_name('TEXELS')} (now {limit('TEXELS'):,}) to {fits:,} or less, so "
                            "inputs this big are refused up front, or give the process more memory")
