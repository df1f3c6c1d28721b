"""The browser side of ``csm-assets view``, shipped as package data.

Shared by both engines' plugins (no engine imports): ``csm_settings.js`` (a material's checked
settings, its uniform values, the variants), ``csm_frame.js`` (the step map's uv placement and
the per-vertex frame inputs), ``csm_frag.js`` (the fragment glue around csm.glsl: the march,
the slope normal, the light share, the debug views).
``csm_plugin.js``: the three.js GLTFLoader plugin for ``EXT_materials_cone_step_mapping``
(with ``csm_geometry.js``: the frame inputs on a three geometry, and
``csm_shader.js``: the material's onBeforeCompile, which splices csm.glsl into three's shader);
``csm_glsl.js``: ``shaders/csm.glsl`` as an ES module (generated: :func:`glsl_module`);
``csm_schema.js``: the extension's JSON schema as an ES module (generated: :func:`schema_module`
from ``docs/EXT_materials_cone_step_mapping.schema.json``) and ``csm_check.js``, which checks a
material's extension against it;
``csm_babylon.js`` (with ``csm_babylon_shader.js``): the Babylon.js glTF loader extension and its
material plugin, which splices csm.glsl into Babylon's PBRMaterial;
``index.html``: the viewer page, whose ``viewer_entry.js`` starts ``viewer.js`` (three.js) or
``viewer_babylon.js`` (Babylon.js; ``babylon_meshopt.js`` hands Babylon three.js' meshopt decoder),
both with the panel of ``viewer_panel.js``; ``three/``: three.js
from npm (MIT, ``three/LICENSE``, version in ``three/VERSION``), only the modules the viewer imports;
``babylon/``: Babylon.js' UMD build and glTF 2 loader from npm (Apache-2.0, ``babylon/LICENSE`` and
``NOTICE``, version and sizes in ``babylon/VERSION``) and the two modules that export from it what
``csm_babylon.js`` imports from ``@babylonjs/core`` and ``@babylonjs/loaders``. The npm packages
(``packages/three``, ``packages/babylon``) copy the plugin modules from here.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

GLSL_MODULE = "csm_glsl.js"
SCHEMA_MODULE = "csm_schema.js"


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


def schema_module(schema_text: str) -> str:
    """The text of ``csm_schema.js``: the extension's JSON schema (``schema_text``, the
    contents of ``docs/EXT_materials_cone_step_mapping.schema.json``) exported as ``SCHEMA``."""
    import json

    body = json.dumps(json.loads(schema_text), indent=1, ensure_ascii=True)
    return ("// Generated from docs/EXT_materials_cone_step_mapping.schema.json by "
            "csm_assets.web.schema_module(); do not edit.\n"
            f"export const SCHEMA = Object.freeze({body});\n")
