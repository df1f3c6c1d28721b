"""Lean outputs: a converted scene names the scene's own textures where they are, by a
relative path, instead of copying them (``textures = "reference"``).

:func:`textures_mode` decides per conversion: ``"reference"`` for outputs beside the scene
(``<stem>_<ext>_csm/``, the hook's layout), ``"copy"`` for any other output folder (a
self-contained folder to ship), unless the options say which. :class:`Links` gives a writer
the relative path of a texture, or None where it must be copied as before: a texture outside
the output's project root (the configuration's folder, else the git repository's root, else
the output folder itself, as every reader of the output bounds its references, so an output
outside any project copies), one inside an output folder (never a file csm-assets wrote), one
on another drive. Referenced textures are inputs of the scene (hashed in the manifest), never
outputs: nothing that removes outputs can remove them.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

from ..config.files import project_root
from .manifest import NAME as MANIFEST
from .options import ConvertOptions

OUTPUT_SUFFIX = "_csm"  # beside-the-scene layout: wall.gltf -> wall_gltf_csm/


def output_name(scene: Path) -> str:
    """The name of a scene's output folder in a batch: ``<stem>_<ext>`` (wall.gltf -> wall_gltf)."""
    return f"{scene.stem}_{scene.suffix.lstrip('.').lower()}"


def beside(scene: Path) -> Path:
    """Where the outputs of ``scene`` go beside it (the hook's layout): ``<stem>_<ext>_csm/``."""
    return scene.parent / f"{output_name(scene)}{OUTPUT_SUFFIX}"


def textures_mode(opts: ConvertOptions, in_path, out_dir) -> ConvertOptions:
    """``opts`` with ``textures`` decided (see the module doc): as given, else "reference"
    when ``out_dir`` is the folder beside ``in_path``, else "copy"."""
    if opts.textures is not None:
        return opts
    here = Path(out_dir).resolve() == beside(Path(in_path)).resolve()
    return dataclasses.replace(opts, textures="reference" if here else "copy")


def links(opts: ConvertOptions, in_path, out_dir) -> Links | None:
    """The :class:`Links` of a conversion of ``in_path`` into ``out_dir`` when its textures are
    referenced (``opts.textures`` decided by :func:`textures_mode`), else None (copied)."""
    if opts.textures != "reference":
        return None
    out_dir = Path(out_dir).resolve()
    return Links(out_dir, project_root(out_dir / Path(in_path).name))


@dataclass(frozen=True)
class Links:
    """Where the converted scene is written (``out_dir``, resolved) and how far its references
    may reach (``root``, the project root of the output)."""

    out_dir: Path
    root: Path

    def to(self, file) -> str | None:
        """The relative path (``/``-separated) from the output folder to ``file``, the file
        itself named (a link in the repository stays a link), or None when it must be copied
        (see the module doc)."""
        file = Path(file)
        try:
            here = file.parent.resolve() / file.name
            real = here.resolve()
            rel = Path(os.path.relpath(here, self.out_dir)).as_posix()
        except (OSError, ValueError):  # another drive: no relative path
            return None
        if not here.is_file() or not real.is_relative_to(self.root) or not here.is_relative_to(self.root) \
                or here.parent == self.out_dir or _in_output_folder(here, self.root):
            return None
        return rel


def _in_output_folder(file: Path, root: Path) -> bool:
    """Whether a folder holding ``file``, up to ``root``, is an output folder (holds a manifest)."""
    folder = file.parent
    while folder.is_relative_to(root):
        if os.path.lexists(folder / MANIFEST):
            return True
        if folder == root:
            return False
        folder = folder.parent
    return False
