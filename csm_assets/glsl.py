"""Load the project's GLSL sources by name, from the installed package or a checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

_CHECKOUT = Path(__file__).resolve().parent.parent / "shaders"


def shader_source(name: str) -> str:
    """The text of ``shaders/<name>`` (e.g. ``"csm.glsl"``); FileNotFoundError if absent."""
    try:
        return resources.files("csm_assets.shaders").joinpath(name).read_text(encoding="utf-8")
    except (ModuleNotFoundError, FileNotFoundError):
        path = _CHECKOUT / name
        if not path.is_file():
            raise FileNotFoundError(f"no shader {name!r} in csm_assets.shaders or {_CHECKOUT}") from None
        return path.read_text(encoding="utf-8")
