"""``csm-assets view``'s check of the level chains a material names (docs/reference/levels.md): each
levels image read at start as verify reads it (:func:`csm_assets.levels_file.read_levels`: the
header before any pixel), against its step map's header. The page would draw a step map whose
levels image it cannot use with its level 0 alone; the terminal says which and why (CSM505)."""

from __future__ import annotations

from pathlib import Path

from .errors import FormatError

PAIRS = (("stepMapTexture", "stepMapLevelsTexture"), ("stepMap2Texture", "stepMap2LevelsTexture"))


def levels_problems(doc, ext: dict, name: str) -> list[tuple[str, str]]:
    """``[(levels image, why it cannot be used: what was expected)]`` of the CSM extension ``ext``
    (already checked: :func:`csm_assets.view.extension_problem` found nothing) of material
    ``name`` in the loaded glTF ``doc``. A levels image that is no file is left to CSM502, a step
    map whose header cannot be read to the page."""
    from .formats import image
    from .formats.csm_material import gltf_texture
    from .levels_file import read_levels

    out = []
    for step_key, key in PAIRS:
        if key not in ext or step_key not in ext:
            continue
        where = f"material {name!r}"
        try:
            step, _ = gltf_texture(doc, ext, step_key, f"{name}_{step_key}", where)
            levels, _ = gltf_texture(doc, ext, key, f"{name}_{key}", where)
            if levels.path is not None and not Path(levels.path).is_file():
                continue
            with step.as_file() as file:
                w, h, _, kind = image.read_layout(file)
        except FormatError:
            continue
        try:
            read_levels(levels, (h, w), kind, f"{key} of {where}", doc.path)
        except FormatError as e:
            out.append((e.path, str(e).removeprefix(e.path + ": ")))
    return out
