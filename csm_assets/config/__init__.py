"""Project configuration: ``csm-assets.toml`` or ``[tool.csm-assets]`` in ``pyproject.toml``,
found walking up from each scene and read as a bounded regular file (:mod:`.files`), read
with the line of every key (:mod:`.load`, :mod:`.toml_lines`), its ``[scenes."GLOB"]``
globs matched in one walk (:mod:`.globs`), and turned into each scene's settings with where
each comes from (:mod:`.settings`). Kept free of imports here, so that :mod:`.files` loads alone."""
