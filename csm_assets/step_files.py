"""A step map's files: where they go and how they are saved.

A map saved at ``bricks.png`` is that image, a quadrant map's second image beside it
(:func:`second_path`: ``bricks_q.png``) and each image's levels 1..n in one atlas
(:func:`levels_path`: ``bricks_levels.png``, ``bricks_q_levels.png``). They are written as a set
(:class:`StepMapSaver`, :func:`csm_assets.formats.step_map_writes`): each on a thread into a
temporary file, then renamed together, the image that names the others last, so a full disk, an
error or Ctrl-C at any point leaves every old file as it was, and never new levels beside an old
map. Level 0 can be written while the level chain is still being made.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from .step_levels import atlas, level_shapes

SECOND_SUFFIX = "_q"  # a quadrant map's second image: OUT's stem + this + OUT's extension
LEVELS_SUFFIX = "_levels"  # an image's levels 1..n: its stem + this + its extension


def second_path(path) -> Path:
    """Where a quadrant map saved at ``path`` keeps its second image (``bricks.png`` ->
    ``bricks_q.png``)."""
    path = Path(path)
    return path.with_name(path.stem + SECOND_SUFFIX + path.suffix)


def levels_path(path) -> Path:
    """Where the levels 1..n of an image saved at ``path`` go (``bricks.png`` ->
    ``bricks_levels.png``; a quadrant map's second image's: ``bricks_q_levels.png``)."""
    path = Path(path)
    return path.with_name(path.stem + LEVELS_SUFFIX + path.suffix)


def step_map_files(path, settings, shape) -> list[tuple[Path, dict]]:
    """``(file, settings it stores)`` of each file a map of ``settings`` (a
    :class:`~csm_assets.step_settings.StepMapSettings`) and ``(H, W)`` ``shape`` saved at ``path``
    takes, in the order they are renamed: the levels atlases, a quadrant map's second image, then
    ``path``, which names the others."""
    path, meta = Path(path), settings.to_meta()
    images = ([second_path(path)] if settings.cones == "quadrant" else []) + [path]
    metas = {where: dict(meta) for where in images}
    files = []
    if settings.levels != "none" and level_shapes(shape):
        for where in images:
            files.append((levels_path(where), {**meta, "image": "levels", "first": path.name}))
            metas[where]["levels_image"] = levels_path(where).name
    if settings.cones == "quadrant":
        files.append((second_path(path), {**metas[second_path(path)], "image": 2, "first": path.name}))
        metas[path]["second"] = second_path(path).name
    return files + [(path, metas[path])]


def save_step_map(sm, path) -> None:
    """Write step map ``sm`` bit-exactly with its settings (PNG, TGA, TIFF, EXR): its image, a
    quadrant map's second image and their levels, as a set (see the module); nothing is written
    unless every file can be (a .tga's room for settings).

    Args:
        sm (StepMap): the map; a quadrant map's second image goes to :func:`second_path`, levels
            to :func:`levels_path`.
        path (str | os.PathLike): the image; its extension picks the format.

    Raises:
        ValueError: a format that cannot hold the pixels' type, a quadrant map without its
            second image, or levels of the wrong shapes.
        OutputError: a file cannot be written.
    """
    with StepMapSaver(path) as saver:
        saver.start(sm)
        saver.finish(sm)


class StepMapSaver(contextlib.ExitStack):
    """:func:`save_step_map` in two steps, so that level 0 is written while the level chain is
    made: ``with StepMapSaver(path) as saver:`` :meth:`start` with the map's level 0 (its levels
    not made yet), :meth:`finish` with the whole map; the files are published when the block
    ends without error, and none of them otherwise."""

    def __init__(self, path):
        super().__init__()
        self.path, self._write = Path(path), None

    def start(self, sm) -> None:
        """Check where and how ``sm`` (a StepMap; its levels are not read) is saved and start
        writing its image and a quadrant map's second image (on threads)."""
        from .formats import step_map_writes

        if sm.settings.cones == "quadrant" and (sm.second is None or sm.second.shape != sm.pixels.shape):
            raise ValueError("a quadrant step map needs its second image, of the first one's shape")
        files = step_map_files(self.path, sm.settings, sm.shape)
        self._write = self.enter_context(step_map_writes(files, sm.pixels.dtype))
        if sm.settings.cones == "quadrant":
            self._write(second_path(self.path), sm.second)
        self._write(self.path, sm.pixels)

    def finish(self, sm) -> None:
        """Start writing the levels of ``sm`` (the map :meth:`start` had, now with its levels)."""
        images = [(sm.pixels, self.path, sm.levels)]
        if sm.second is not None and sm.settings.cones == "quadrant":
            images.append((sm.second, second_path(self.path), sm.second_levels))
        for pixels, where, levels in images:
            want = level_shapes(pixels.shape[:2]) if sm.settings.levels != "none" else []
            if [lv.shape[:2] for lv in levels] != want or any(lv.dtype != pixels.dtype for lv in levels):
                raise ValueError(f"{where.name}: expected levels of shapes {want} and dtype {pixels.dtype} "
                                 f"(settings.levels {sm.settings.levels!r}), got "
                                 f"{[(lv.shape[:2], str(lv.dtype)) for lv in levels]}")
            if levels:
                self._write(levels_path(where), atlas(levels))
