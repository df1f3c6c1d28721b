"""Load the project's GLSL sources by name, from the installed package or a checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

_CHECKOUT = Path(__file__).resolve().parents[2] / "shaders"


def shader_source(name: str) -> str:
    """The text of ``shaders/<name>`` (e.g. ``"csm.glsl"``); FileNotFoundError if absent."""
    return shader_path(name).read_text(encoding="utf-8")


def shader_path(name: str) -> Path:
    """A file path of ``shaders/<name>``, from the installed package or a checkout
    (USD resolves asset paths, so some callers need a file); FileNotFoundError if absent."""
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
