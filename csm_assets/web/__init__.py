"""The browser side of ``csm-assets view``, shipped as package data.

``csm_plugin.js``: the three.js GLTFLoader plugin for ``EXT_materials_cone_step_mapping``
(with ``csm_geometry.js``: the step map's uv placement and the per-vertex frame inputs);
``csm_glsl.js``: ``shaders/csm.glsl`` as an ES module (generated: :func:`glsl_module`);
``index.html`` and ``viewer.js``: the viewer page; ``three/``: three.js from npm (MIT,
``three/LICENSE``, version in ``three/VERSION``), only the modules the viewer imports.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

GLSL_MODULE = "csm_glsl.js"


def web_root() -> Path:
    """The folder holding the page, the plugin and the vendored three.js."""
    return Path(str(resources.files(__name__)))


def glsl_module() -> str:
    """The text of ``csm_glsl.js``: ``shaders/csm.glsl`` exported as ``CSM_GLSL``."""
    from ..render.glsl import shader_source

    src = shader_source("csm.glsl")
    if "`" in src or "${" in src or "\\" in src.replace("\\\n", ""):
        raise ValueError("csm.glsl holds characters a JS template literal would change")
    body = src.replace("\\\n", "\\\\\n")  # line continuations survive the template literal
    return ("// Generated from shaders/csm.glsl by csm_assets.web.glsl_module(); do not edit.\n"
            f"export const CSM_GLSL = `\n{body}`;\n")
