"""The file formats as data, one row per extension: which module reads and writes it and what it
can hold. ``load_heightfield``/``save_heightfield``, the step map readers and writers, ``convert``
and the batch planner dispatch through these tables and nothing else lists extensions; the
format tables of docs/reference/formats.md and scenes.md are checked against them (``tests/test_format_registry.py``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from ..errors import FormatError


@dataclass(frozen=True)
class HeightfieldFormat:
    """A heightfield file format (a row of :data:`HEIGHTFIELD_FORMATS`).

    Attributes:
        extension (str): lower case, with the dot (``.png``).
        module (str): the module in ``csm_assets.formats`` that reads and writes it.
        name (str): the format's name, for messages and the docs' tables.
        height_bits (int): the bits of the heights it writes (8, 16, 32 = float).
        step_map_bits (tuple[int, ...]): the packed step maps it holds bit-exactly (empty: none).
        holes (bool): it marks holes (a ``mask``).
        bottom_up (bool): its first row is the image's bottom row (the readers flip).
        read (bool): csm-assets reads it.
        write (bool): csm-assets writes it.
    """

    extension: str
    module: str
    name: str
    height_bits: int
    step_map_bits: tuple[int, ...] = ()
    holes: bool = False
    bottom_up: bool = False
    read: bool = True
    write: bool = True


HEIGHTFIELD_FORMATS: tuple[HeightfieldFormat, ...] = (
    HeightfieldFormat(".png", "image", "PNG", 16, (8, 16)),
    HeightfieldFormat(".tga", "image", "TGA", 8, (8,)),
    HeightfieldFormat(".tif", "image", "TIFF", 32, (8, 16, 32)),
    HeightfieldFormat(".tiff", "image", "TIFF", 32, (8, 16, 32)),
    HeightfieldFormat(".exr", "image", "OpenEXR", 32, (32,)),
    HeightfieldFormat(".jpg", "image", "JPEG", 8),
    HeightfieldFormat(".jpeg", "image", "JPEG", 8),
    HeightfieldFormat(".hf", "rayshade", "Rayshade height field", 32, holes=True, bottom_up=True),
    HeightfieldFormat(".txt", "zbuf", "Rayshade z-buffer text", 32, holes=True, bottom_up=True),
    HeightfieldFormat(".etxt", "zbuf", "Rayshade z-buffer expanded text", 32, holes=True, bottom_up=True),
    HeightfieldFormat(".gif", "povray", "POV-Ray height field (GIF palette indices)", 8),
    HeightfieldFormat(".pot", "povray", "Fractint continuous potential", 16),
)
"""Every heightfield format, one row per extension (the Formats page's table)."""
HEIGHTFIELDS = {f.extension: f for f in HEIGHTFIELD_FORMATS}


@dataclass(frozen=True)
class SceneFormat:
    """A scene file format (a row of :data:`SCENE_FORMAT_ROWS`).

    Attributes:
        extension (str): lower case, with the dot (``.gltf``).
        module (str): the module in ``csm_assets.formats`` that reads and writes it.
        name (str): the format's name.
        step_map_bits (tuple[int, ...]): the step maps its materials can name (glTF images are
            PNG: no float).
        stores_tangents (bool): the file keeps tangents (OBJ has no statement for them, so none
            are made).
    """

    extension: str
    module: str
    name: str
    step_map_bits: tuple[int, ...]
    stores_tangents: bool


SCENE_FORMAT_ROWS: tuple[SceneFormat, ...] = (
    SceneFormat(".gltf", "gltf", "glTF 2.0", (8, 16), True),
    SceneFormat(".glb", "gltf", "glTF 2.0 binary", (8, 16), True),
    SceneFormat(".obj", "obj", "Wavefront OBJ + MTL", (8, 16, 32), False),
    SceneFormat(".usda", "usd", "USD text", (8, 16, 32), True),
    SceneFormat(".usdc", "usd", "USD crate", (8, 16, 32), True),
    SceneFormat(".usdz", "usd", "USD package", (8, 16, 32), True),
    SceneFormat(".usd", "usd", "USD", (8, 16, 32), True),
)
"""Every scene format, one row per extension (the Scene conversion page's table)."""
SCENES = {f.extension: f for f in SCENE_FORMAT_ROWS}


def heightfield_format(path) -> HeightfieldFormat | None:
    """The row of ``path``'s extension, or None."""
    return HEIGHTFIELDS.get(Path(path).suffix.lower())


def scene_format(path) -> SceneFormat | None:
    """The row of ``path``'s extension, or None."""
    return SCENES.get(Path(path).suffix.lower())


def scene_module(path):
    """The ``csm_assets.formats`` module that reads and writes scene ``path``; FormatError
    naming the known extensions for any other."""
    row = scene_format(path)
    if row is None:
        ext = Path(path).suffix.lower()
        raise FormatError(path, f"unknown scene format {ext or '(no extension)'!r}; known: "
                                f"{' '.join(sorted(SCENES))}")
    return importlib.import_module(f"csm_assets.formats.{row.module}")


def module_bits(module: str) -> tuple[int, ...]:
    """The step map bits every extension of scene ``module`` takes (its writers' one constant)."""
    return next(f.step_map_bits for f in SCENE_FORMAT_ROWS if f.module == module)


def module_stores_tangents(module: str) -> bool:
    """Whether the scene format of reader ``module`` (``"gltf"``, ``"obj"``, ``"usd"``) keeps tangents."""
    return next(f.stores_tangents for f in SCENE_FORMAT_ROWS if f.module == module)
