"""Which USD files are parts of another scene: layers a scene of their repository composes.

A USD layer that another scene composes (a sublayer, reference or payload) is part of that
scene, not a scene of its own. The answer must not depend on which files one run is given
(pre-commit splits a long file list between processes), so the composers are looked for
among every USD file of the layer's repository (else its project root, else its folder),
not only among the files of the run. Output folders (holding a ``csm-manifest.json``) and
hidden folders are not searched. Each layer file is read once per process and size/mtime.
"""

from __future__ import annotations

import functools
import os
import stat
from pathlib import Path

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
MANIFEST = "csm-manifest.json"


def _search_root(scene: Path) -> Path:
    from ..config.files import ConfigError, project_root, repository_root

    try:
        return repository_root(scene) or project_root(scene)
    except ConfigError:  # a broken configuration is reported where it applies, not here
        return scene.resolve().parent


def usd_files_under(root: Path) -> list[Path]:
    """The USD files (resolved) under ``root``, output and hidden folders left out."""
    found = []
    for folder, dirs, files in os.walk(root):
        if MANIFEST in files:
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found.extend(Path(folder, f).resolve() for f in sorted(files) if f.lower().endswith(USD_SUFFIXES))
    return found


@functools.lru_cache(maxsize=4096)
def _layers(path: Path, mtime_ns: int, size: int) -> frozenset[Path]:
    from ..formats.usd_assets import layer_files

    return frozenset(layer_files(path))


def layers_of(path: Path) -> frozenset[Path]:
    """The layer files (resolved) the USD scene at ``path`` composes, itself excluded; none for a
    file that is not a regular file (a FIFO named ``x.usda`` would block the read)."""
    try:
        st = path.stat()
    except OSError:
        return frozenset()
    if not stat.S_ISREG(st.st_mode):
        return frozenset()
    return _layers(path, st.st_mtime_ns, st.st_size)


def composers(scenes: list[Path]) -> dict[Path, Path]:
    """The USD files among ``scenes`` that another USD file of their repository composes.

    Layers that compose each other (a sublayer cycle, which USD reports and breaks) are
    scenes, not parts of one another: otherwise neither would be converted.

    Args:
        scenes: resolved scene paths (files of other formats are left alone).

    Returns:
        ``{layer: composer}``, one composer each (the first in path order).
    """
    usd = [s for s in scenes if s.suffix.lower() in USD_SUFFIXES]
    if not usd:
        return {}
    wanted = set(usd)
    candidates = dict.fromkeys(usd)
    for root in dict.fromkeys(_search_root(s) for s in usd):
        candidates.update(dict.fromkeys(usd_files_under(root)))
    found: dict[Path, Path] = {}
    for composer in sorted(candidates):
        for layer in layers_of(composer) & wanted:
            if layer != composer and composer not in layers_of(layer):
                found.setdefault(layer, composer)
    return found
