"""Reading a converted scene back for verify: the scene as the readers give it, with each
material's stored CSM settings (:mod:`csm_assets.formats.csm_material`) and the scene's cameras."""

from __future__ import annotations

from pathlib import Path

from ..config.files import project_root
from ..errors import FormatError
from ..formats import csm_material
from ..formats.registry import scene_module
from ..scene import HeightInput


def read_converted(path):
    """(scene, {material ref: StoredCsm}, cameras [(name, Camera)], {mesh key: world matrix})
    of a converted scene; FormatError when it carries no CSM material. Its files may lie anywhere
    in its project root (as convert reads scenes): a lean output names its scene's textures there."""
    path = Path(path)
    module = scene_module(path)
    root = project_root(path)
    first = module.read(path, root=root)
    fmt = module.__name__.rsplit(".", 1)[-1]
    cameras, models = [], {}
    if fmt == "gltf":
        from .views import gltf_cameras

        stored = csm_material.gltf_materials(first.source)
        cameras, models = gltf_cameras(first.source)
        heights = {first.materials[i].name: HeightInput(s.step_map, s.tex_coord, origin="csm")
                   for i, s in stored.items()}
    elif fmt == "obj":
        src = first.source
        stored = {}
        for lib in src.libraries:  # the first library defining a name wins, as in reading
            found = csm_material.obj_materials(path, lib.path, lib.materials)
            stored.update({k: v for k, v in found.items() if k not in stored})
        heights = {name: s.step_map.path for name, s in stored.items()}
    else:
        from .views import usd_cameras

        stored = csm_material.usd_materials(first.source, path)
        cameras, models = usd_cameras(first.source)
        heights = {ref: HeightInput(s.step_map, origin="csm") for ref, s in stored.items()}
    if not stored:
        raise FormatError(path, "no material carries CSM settings; convert the scene first")
    return module.read(path, heights=heights, root=root), stored, cameras, models
