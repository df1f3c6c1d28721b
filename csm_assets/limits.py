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
    name) that ``what`` declares exceeds the ``kind`` limit."""
    top = limit(kind)
    if count > top:
        raise FormatError(path, f"{what} declares {count:,} {noun or kind.lower()}, over the limit of "
                                f"{top:,} (raise it with {env_name(kind)})")
