"""Resource limits: the largest image and mesh csm-assets reads, checked before allocating.

A hostile or broken file can declare far more data than it holds (a 1 MB PNG decoding to
30000x30000, a small ``.usdc`` declaring 20 M triangles, a glTF accessor of 10^9 elements).
Readers call :func:`check_texels` / :func:`check_vertices` with the *declared* size as
soon as they know it, before any array of that size exists, and the file is refused with a
:class:`~csm_assets.errors.FormatError` naming it (exit 3 on the command line).

Limits (whole numbers; ``0`` turns a limit off):

=========================== ====================== ====================================
environment variable        default                counts
=========================== ====================== ====================================
``CSM_ASSETS_MAX_TEXELS``   268435456 (16384²)     width x height of one image or map
``CSM_ASSETS_MAX_VERTICES`` 16777216 (2^24)        vertices, face corners or elements
                                                   of one mesh, accessor or array
=========================== ====================== ====================================

The environment is read at each check, so a library user may also call :func:`set_limits`
(which takes precedence over the environment). A step map of the default texel limit needs
about 12 GiB while it is made; a machine with less memory should lower it.
"""

from __future__ import annotations

import os

from .errors import FormatError

DEFAULT_MAX_TEXELS = 16384 * 16384
DEFAULT_MAX_VERTICES = 1 << 24
TEXELS_ENV = "CSM_ASSETS_MAX_TEXELS"
VERTICES_ENV = "CSM_ASSETS_MAX_VERTICES"

_overrides: dict[str, int] = {}


def _limit(env: str, default: int) -> int | None:
    """The limit in force for ``env`` (None when turned off with 0)."""
    if env in _overrides:
        value = _overrides[env]
    else:
        text = os.environ.get(env, "").strip()
        if not text:
            return default
        try:
            value = int(text.replace("_", ""))
        except ValueError:
            raise ValueError(f"{env}={text!r}: expected a whole number >= 0 (0: no limit)") from None
        if value < 0:
            raise ValueError(f"{env}={text!r}: expected a whole number >= 0 (0: no limit)")
    return value or None


def max_texels() -> int | None:
    """Largest width x height of one image (None: no limit)."""
    return _limit(TEXELS_ENV, DEFAULT_MAX_TEXELS)


def max_vertices() -> int | None:
    """Largest count of vertices / corners / elements of one mesh or array (None: no limit)."""
    return _limit(VERTICES_ENV, DEFAULT_MAX_VERTICES)


def set_limits(*, texels: int | None = None, vertices: int | None = None) -> None:
    """Override the environment for this process (0 turns a limit off); None leaves one as is."""
    for env, value in ((TEXELS_ENV, texels), (VERTICES_ENV, vertices)):
        if value is not None:
            if int(value) < 0:
                raise ValueError(f"{env}: expected a whole number >= 0, got {value!r}")
            _overrides[env] = int(value)


def reset_limits() -> None:
    """Forget :func:`set_limits` overrides (back to the environment and the defaults)."""
    _overrides.clear()


def check_texels(path, width: int, height: int, what: str = "image") -> None:
    """FormatError naming ``path`` when a ``width`` x ``height`` ``what`` is over the texel
    limit (or has a size that is not positive)."""
    width, height = int(width), int(height)
    if width <= 0 or height <= 0:
        raise FormatError(path, f"{what} declares {width}x{height} texels; expected a positive size")
    limit = max_texels()
    if limit is not None and width * height > limit:
        raise FormatError(path, f"{what} declares {width}x{height} pixels ({width * height} texels), over "
                                f"the limit of {limit} texels (raise it with {TEXELS_ENV}=N)")


def check_vertices(path, count: int, what: str = "mesh vertices") -> None:
    """FormatError naming ``path`` when ``count`` ``what`` are over the vertex limit (or negative)."""
    count = int(count)
    if count < 0:
        raise FormatError(path, f"{what}: a negative count {count}")
    limit = max_vertices()
    if limit is not None and count > limit:
        raise FormatError(path, f"{what}: {count} declared, over the limit of {limit} "
                                f"(raise it with {VERTICES_ENV}=N)")
