"""Where a scene's project configuration and project root are (as ruff and pre-commit find theirs).

Walking up from the scene's folder, the first folder that holds ``csm-assets.toml``, or a
``pyproject.toml`` with a ``[tool.csm-assets]`` table, gives the configuration (the first
wins in one folder). The walk stops at the repository's root (the folder holding ``.git``):
a file above the repository never applies to it.

The **project root** is the configuration's folder, else the repository's root, else the
scene's own folder; every path is resolved (symlinks followed), so the answer never
depends on the working directory or on how a path was spelled.
"""

from __future__ import annotations

import re
from pathlib import Path

CONFIG_NAME = "csm-assets.toml"
PYPROJECT = "pyproject.toml"
TOOL_TABLE = re.compile(r"^\s*\[\s*tool\s*\.\s*(csm-assets|\"csm-assets\"|'csm-assets')\s*[.\]]", re.MULTILINE)


def has_tool_table(pyproject: Path) -> bool:
    """Whether ``pyproject`` holds a ``[tool.csm-assets]`` table (or a sub-table of it).
    A text match: the file is parsed (and its errors reported) only when it is used."""
    try:
        return TOOL_TABLE.search(pyproject.read_text(encoding="utf-8", errors="replace")) is not None
    except OSError:
        return False


def _config_in(folder: Path) -> Path | None:
    """The configuration file in ``folder`` itself, or None."""
    own = folder / CONFIG_NAME
    if own.is_file():
        return own
    pyproject = folder / PYPROJECT
    return pyproject if pyproject.is_file() and has_tool_table(pyproject) else None


def _folders(start: Path):
    """``start`` (resolved) and the folders above it, up to the repository's root or the
    filesystem's: each with whether it is a repository's root."""
    for folder in (start, *start.parents):
        is_repo = (folder / ".git").exists()
        yield folder, is_repo
        if is_repo:
            return


def scene_folder(scene) -> Path:
    return Path(scene).resolve().parent


def find_config(scene) -> Path | None:
    """The configuration file that applies to ``scene`` (resolved), or None."""
    for folder, _ in _folders(scene_folder(scene)):
        found = _config_in(folder)
        if found is not None:
            return found
    return None


def repository_root(scene) -> Path | None:
    """The git repository (or worktree) holding ``scene``, or None."""
    for folder, is_repo in _folders(scene_folder(scene)):
        if is_repo:
            return folder
    return None


def project_root(scene, config: Path | None = None) -> Path:
    """The folder ``scene``'s inputs are recorded relative to (resolved): ``config``'s folder
    (by default the configuration :func:`find_config` finds), else the repository's root,
    else the scene's own folder."""
    config = config if config is not None else find_config(scene)
    if config is not None:
        return Path(config).resolve().parent
    return repository_root(scene) or scene_folder(scene)

