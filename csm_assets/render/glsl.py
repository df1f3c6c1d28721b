"""Load the project's GLSL sources by name, from the installed package or a checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

_CHECKOUT = Path(__file__).resolve().parents[2] / "shaders"


def shader_source(name: str) -> str:
    """The text of a project shader.

    Args:
        name: a file of ``shaders/`` (e.g. ``"csm.glsl"``).

    Raises:
        FileNotFoundError: no such shader.
    """
    return shader_path(name).read_text(encoding="utf-8")


def shader_path(name: str) -> Path:
    """A file path of a project shader, from the installed package or a checkout (USD
    resolves asset paths, so some callers need a file).

    Args:
        name: a file of ``shaders/``.

    Raises:
        FileNotFoundError: no such shader.
    """
    try:
        path = Path(str(resources.files("csm_assets.shaders").joinpath(name)))
        if path.is_file():
            return path
    except ModuleNotFoundError:
        pass
    path = _CHECKOUT / name
    if not path.is_file():
        raise FileNotFoundError(f"no shader {name!r} in csm_assets.shaders or {_CHECKOUT}")
    return path
