"""One rule for the references a scene makes to other files: glTF uris, OBJ/MTL file names,
USD asset paths, and the files ``csm-assets view`` serves.

A reference is read as a browser would read it (leading and trailing spaces and control
characters dropped, tabs and newlines removed anywhere, ``\\`` as ``/``), then refused when it
is:

- a URL: any ``scheme:`` prefix in any case (``HTTP://host/x``, ``https:host/x.png``,
  ``file:x``, ``data:`` where a file is expected); a name holding a colon in its first
  part is written ``./a:b.png``;
- an absolute path: ``/x``, a Windows drive (``C:\\x``, ``C:/x``, ``C:x``);
- a UNC or network path: ``\\\\host\\share``, ``//host/x``.

glTF's ``data:`` URIs (any case) are found by :func:`is_data_uri` before this rule applies.
"""

from __future__ import annotations

import re
from pathlib import Path

from .errors import FormatError

_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*):")
_EDGE = "".join(map(chr, range(0x21)))  # C0 controls and space, dropped at both ends
_INSIDE = re.compile("[\t\n\r]")  # removed anywhere by a browser's URL parser


def browser_form(ref: str) -> str:
    """``ref`` as a browser's URL parser reads it (WHATWG URL: ends stripped of C0 controls
    and spaces, tabs and newlines removed), with ``\\`` as ``/``."""
    return _INSIDE.sub("", ref.strip(_EDGE)).replace("\\", "/")


def scheme(ref: str) -> str | None:
    """The URL scheme of ``ref`` in lower case (``'http'`` for ``HTTP://x``), or None for a
    path; one letter before the colon is a Windows drive, not a scheme."""
    m = _SCHEME.match(browser_form(ref))
    return m.group(1).lower() if m and len(m.group(1)) > 1 else None


def is_data_uri(ref) -> bool:
    """Whether ``ref`` is a ``data:`` URI (the scheme in any case)."""
    return isinstance(ref, str) and scheme(ref) == "data"


def refusal(ref: str) -> str | None:
    """Why ``ref`` cannot name a file beside the scene (see the module doc), or None."""
    text = browser_form(ref)
    if text.startswith("//"):
        return "a UNC or network path"
    if text.startswith("/"):
        return "an absolute path"
    if re.match(r"^[A-Za-z]:", text):
        return "an absolute path (a Windows drive)"
    name = scheme(text)
    if name:
        return f"a URL ({name}:)"
    return None


def check(scene_path, ref: str, what: str = "") -> None:
    """FormatError naming ``scene_path`` when ``ref`` is refused by the rule."""
    why = refusal(ref)
    if why:
        raise FormatError(scene_path, f"{what}refers to {ref!r}, {why}: absolute paths and URLs are refused")


OUTSIDE_HINT = "allow it with --allow-outside-paths, or allow-outside-paths = true in csm-assets.toml"


def reach(scene_path, *, allow_outside: bool = False, root=None) -> Path | None:
    """The folder every file a scene names must lie in (resolved): ``root`` (the project
    root, see :mod:`csm_assets.config.files`), else the scene's own folder; None (anywhere)
    with ``allow_outside``."""
    if allow_outside:
        return None
    return Path(root).resolve() if root is not None else Path(scene_path).resolve().parent


def refuse_outside(scene_path, ref: str, full, within: Path | None, what: str = "") -> None:
    """:func:`outside`'s error when the file ``full`` (named as ``ref``) lies outside
    ``within`` (see :func:`reach`; None: anywhere)."""
    if within is not None and not Path(full).resolve().is_relative_to(within):
        raise outside(scene_path, ref, what, within)


def outside(scene_path, ref: str, what: str = "", within: Path | None = None) -> FormatError:
    """The error for ``ref`` leading out of ``within``, the project root (None: the scene's
    folder); it names that folder, and the option and the configuration key that allow it.
    When the scene path is (or passes through) a link, it says so: references are read
    beside the link's target."""
    scene_path = Path(scene_path)
    real = scene_path.resolve()
    own = within is None or Path(within) == real.parent
    where = "the scene's folder, its project root" if own else f"the project root {within}"
    message = f"{what}refers to {ref!r}, outside {where}; refused"
    if scene_path.is_symlink() and real.parent != scene_path.absolute().parent.resolve():
        return FormatError(scene_path, f"{message}: the scene path is a link to {real}, and the files a "
                                       f"scene names must lie in {'its own folder' if own else 'that root'} "
                                       f"({real.parent if own else within}); open {real} instead (or "
                                       f"{OUTSIDE_HINT})")
    return FormatError(scene_path, f"{message} ({OUTSIDE_HINT})")
