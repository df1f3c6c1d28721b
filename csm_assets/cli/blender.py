"""``csm-assets blender install``: the Blender add-on into a Blender (:func:`csm_assets.blender.install.install`)."""

from __future__ import annotations

import sys

from .common import EXIT_OK, EXIT_OUTPUT


def add(sub) -> None:
    b = sub.add_parser("blender", help="install the Blender add-on (glTF export and import of CSM materials)",
                       description="Install csm-assets' add-on into Blender: Blender's own glTF exporter then "
                                   "writes a step map and EXT_materials_cone_step_mapping for every material "
                                   "whose height comes from an image (Displacement or Bump node), and its importer "
                                   "turns them back into relief nodes. Blender must run the same Python version "
                                   "as this csm-assets (Blender 4.2 to 5.0: Python 3.11).")
    actions = b.add_subparsers(dest="action", metavar="ACTION", required=True)
    i = actions.add_parser("install", help="copy the add-on into Blender's add-ons folder and enable it",
                           description="Write the add-on package csm_assets_gltf into Blender's user add-ons "
                                       "folder, enable it in Blender and save Blender's preferences.")
    i.add_argument("--blender", metavar="EXE",
                   help="the Blender executable (default: blender on PATH, else the bpy module of this Python)")
    i.set_defaults(run=run)


def run(args) -> int:
    from ..blender.install import install

    report = install(args.blender)
    state = "enabled" if report.enabled else "NOT enabled (see Blender's messages: enable it in Preferences > Add-ons)"
    sys.stdout.write(f"installed csm_assets_gltf into {report.folder} (Blender {report.blender}); {state}\n")
    return EXIT_OK if report.enabled else EXIT_OUTPUT
