"""GLSL sources shipped with csm-assets (installed as ``csm_assets.shaders``)."""
