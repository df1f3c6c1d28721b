"""An OBJ's default material: the faces no ``usemtl`` names (an OBJ without any MTL, as
three.js's ninja head, has only those).

``--height =FILE`` (the empty material name) gives them a height when no MTL defines a
material of that name: :func:`default_material` makes the material the reader adds. The
converted OBJ then names a material for them: :func:`write` writes the OBJ with
``mtllib NAME.mtl`` and ``usemtl default`` put before its first line (every face before the
first ``usemtl`` takes it, as it took the default material) and that MTL, holding the CSM
statements of material ``default`` (``default_2``... when an MTL already defines it).
"""

from __future__ import annotations

from pathlib import Path

from ..atomic import atomic_path
from ..convert.output_folder import free_name
from ..height_source import material_height
from ..scene import Material, Scene
from .csm_params import mtl_lines

BOM = b"\xef\xbb\xbf"


def has_default_faces(text: str) -> bool:
    """Whether a face comes before any ``usemtl`` statement in OBJ ``text``."""
    for line in text.splitlines():
        key = line.split(None, 1)[0] if line.strip() else ""
        if key == "usemtl":
            return False
        if key == "f":
            return True
    return False


def default_material(scene: Scene, text: str, heights: dict, names) -> Material | None:
    """The default material with its command-line height, when ``heights`` names the empty
    material, no MTL defines one (``names``: the MTLs' material names) and faces take it."""
    if "" not in heights or "" in names or not has_default_faces(text):
        return None
    mat = Material("", ref="")
    mat.height, _ = material_height(heights, [""], scene, lambda: None)
    return mat


def output_name(names) -> str:
    """The name the converted default material takes: ``default``, else ``default_2``, ..."""
    name, n = "default", 2
    while name in names:
        name, n = f"default_{n}", n + 1
    return name


def write(scene: Scene, src_path: Path, out_dir: Path, csm, names, reserved: set) -> list[Path]:
    """The OBJ with ``mtllib``/``usemtl`` put first and its new MTL (the default material's CSM
    ``csm``); ``names``: the MTLs' material names; ``reserved``: names taken in ``out_dir``.
    Returns the two files written."""
    name = output_name(names)
    lib = free_name(f"{src_path.stem}_default", ".mtl", lambda n: n in reserved, scene.others)
    data = src_path.read_bytes()
    bom = BOM if data.startswith(BOM) else b""
    head = f"mtllib {lib}\nusemtl {name}\n".encode()
    target = out_dir / src_path.name
    with atomic_path(target) as tmp:
        tmp.write_bytes(bom + head + data[len(bom):])
    mtl_target = out_dir / lib
    lines = [f"# the default material of {src_path.name} (its faces named none), written by csm-assets",
             f"newmtl {name}", *mtl_lines(csm, csm.step_map.name)]
    with atomic_path(mtl_target) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return [target, mtl_target]
