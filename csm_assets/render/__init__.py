"""Headless OpenGL renders with the project's shaders.

- :mod:`.renderer`: ``Renderer``, the one owner of the GL context (:mod:`.gl_context` opens it).
- :mod:`.mesh`: what the renderer draws (triangle meshes with a tangent frame, the unit quad).
- :mod:`.camera`: view and projection matrices, rays through pixel centres, orbits.
- :mod:`.glsl`: the GLSL sources, loaded by name.
- :mod:`.textures`: step maps and colour maps uploaded as textures (with or without mipmaps).
"""
