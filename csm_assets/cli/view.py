"""``csm-assets view SCENE``: serve a converted glTF/GLB scene and a three.js or Babylon.js viewer on
127.0.0.1 (:func:`csm_assets.view.serve`) until Ctrl-C (exit 130)."""

from __future__ import annotations

import sys

from ..view import ENGINES, serve
from .common import EXIT_INTERRUPTED, EXIT_OK, default, number

PORT = default(serve, "port")


def add(sub) -> None:
    v = sub.add_parser("view", help="show a converted glTF/GLB scene in the browser (three.js or Babylon.js)",
                       description="Serve the scene and a three.js or Babylon.js viewer on 127.0.0.1 only: orbit controls, "
                                   "the shader variant and steps, the debug views (hit uv, iterations heat "
                                   "map) and each material's CSM settings. Ctrl-C stops it (exit 130).")
    v.add_argument("scene", metavar="SCENE", help="a converted .gltf or .glb")
    v.add_argument("--port", type=number(int, 0, 65535, what="a port number"), default=PORT, metavar="N",
                   help="port to listen on (default: a free one)")
    v.add_argument("--engine", choices=list(ENGINES), default="three",
                   help="the web engine that draws the scene (default: three); both are shipped, nothing is fetched")
    v.add_argument("--no-browser", action="store_true", help="print the URL only; do not open a browser")
    v.set_defaults(run=run)


def run(args) -> int:
    try:
        serve(args.scene, port=args.port, open_browser=not args.no_browser, engine=args.engine)
    except KeyboardInterrupt:
        sys.stderr.write("csm-assets: view stopped (interrupted)\n")
        return EXIT_INTERRUPTED
    return EXIT_OK
