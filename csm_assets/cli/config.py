"""``csm-assets config show SCENE``: the settings that apply to a scene and where each comes
from (default, a configuration's ``file:line``, the command line), as ``ruff check
--show-settings`` does (:mod:`csm_assets.config.settings`)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .common import EXIT_OK, UsageError
from .scenes import add_scene_flags, add_warning_flags, resolver


def add(sub) -> None:
    c = sub.add_parser("config", help="show the settings that apply to a scene and where each comes from",
                       description="Print the settings convert, check and hook use for a scene: the defaults, "
                                   "its project configuration (the nearest csm-assets.toml, or pyproject.toml "
                                   "with [tool.csm-assets], walking up from the scene), and the flags given, "
                                   "with where each comes from. Exit 2 for a configuration that cannot be used, "
                                   "naming its file and line.")
    actions = c.add_subparsers(dest="action", metavar="ACTION", required=True)
    show = actions.add_parser("show", help="the settings of one scene",
                              description="The settings of SCENE and where each comes from: the defaults, its "
                                          "project configuration (or the one --config names) and the flags "
                                          "given here.")
    show.add_argument("scene", metavar="SCENE", help="a scene file")
    add_scene_flags(show)
    add_warning_flags(show, "show the settings with --strict given")
    show.add_argument("--json", action="store_true", help="print them as JSON")
    show.set_defaults(run=run)


def run(args) -> int:
    from ..convert.pipeline import SCENE_FORMATS, scene_root

    scene = Path(args.scene)
    if not scene.is_file():
        raise UsageError(f"{scene}: no such scene file")
    if scene.suffix.lower() not in SCENE_FORMATS:
        raise UsageError(f"{scene}: not a scene file ({', '.join(sorted(SCENE_FORMATS))})")
    found = resolver(args).settings(scene)
    opts = found.options()
    root = scene_root(scene, opts)
    rows = [(s.key, _shown(s.value, root), s.source) for s in found.settings.values()]
    if args.json:
        print(json.dumps({"scene": str(scene), "config": str(found.config) if found.config else None,
                          "root": str(root),
                          "settings": [{"key": k, "value": v, "source": src} for k, v, src in rows]}, indent=2))
        return EXIT_OK
    out = sys.stdout
    out.write(f"scene:  {scene}\nconfig: {found.config or '(none found)'}\nroot:   {root}\n")
    width = max(len(k) for k, _, _ in rows)
    vwidth = max(len(json.dumps(v)) for _, v, _ in rows)
    for key, value, source in rows:
        out.write(f"{key:<{width}} = {json.dumps(value):<{vwidth}}  # {source}\n")
    return EXIT_OK


def _shown(value, root: Path):
    """A setting's value as TOML would write it (paths relative to the project root)."""
    from ..convert.manifest import path_key
    from ..height_source import HeightSpec

    return path_key(root, value.path) if isinstance(value, HeightSpec) else value  # the key says depth-map
