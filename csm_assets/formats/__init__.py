"""Heightfield file formats, chosen by extension from a plain registry.

The formats and what each can hold are one table, :mod:`.registry`. Each format module has ``read(path, **options) -> Heightfield`` and
``write(hf, path, **options)``; heavy imports stay inside the modules.
Formats: images (``image``), Rayshade ``.hf`` (``rayshade``), Rayshade z-buffer
text ``.txt``/``.etxt`` (``zbuf``), POV-Ray ``.gif`` and Fractint ``.pot`` (``povray``).
"""

from __future__ import annotations

import contextlib
import importlib
import json
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path

import numpy as np

from ..errors import FormatError, OutputError
from ..heightfield import Heightfield
from .registry import HEIGHTFIELD_FORMATS

# extension -> module in this package, from the one table (registry.HEIGHTFIELD_FORMATS)
FORMATS: dict[str, str] = {f.extension: f.module for f in HEIGHTFIELD_FORMATS}


def format_module(path):
    """The module that handles ``path``'s extension; FormatError if none does."""
    ext = Path(path).suffix.lower()
    name = FORMATS.get(ext)
    if name is None:
        known = " ".join(sorted(FORMATS))
        raise FormatError(path, f"unknown heightfield format {ext or '(no extension)'!r}; known: {known}")
    return importlib.import_module(f".{name}", __name__)


def load_heightfield(path, *, channel=None, invert=False, waterlevel=None, image=None, nodata=None) -> Heightfield:
    """Read a heightfield file (format by extension: see the Formats page).

    With ``invert`` or ``waterlevel`` the field is first normalized
    (:meth:`Heightfield.normalized`); ``meta`` height_scale/height_offset then
    still map the result back to raw values (a negative scale after ``invert``).

    Args:
        path (str | os.PathLike): the file.
        channel (int | str | None): for images, None (first channel of a grey image, luminance
            of a colour one), an index or a channel name.
        invert (bool): turn a depth map (white = deep) into a height map: ``1 - d`` on
            normalized data.
        waterlevel (float | None): POV-Ray's waterlevel, a height in ``[0, 1]``: heights below
            it are raised to it (on normalized data, holes included).
        image (tuple | None): for an image file, what ``image.read_pixels(path, describe=True)``
            already read of it (one open for callers that also look for step map settings).
        nodata (float | None): for an image file, the stored value of texels without a height
            (holes; a TIFF's GDAL_NODATA tag is used without it).

    Returns:
        The Heightfield: float32 data in image order, holes in ``mask``, facts in ``meta``.

    Raises:
        FormatError: the file is missing, unreadable, malformed, or of an unknown extension
            (a ValueError whose message starts with the path).
        ValueError: ``waterlevel`` outside ``[0, 1]``, or ``nodata`` for a format that is
            not an image.
    """
    if waterlevel is not None:
        waterlevel = float(waterlevel)
        if not 0.0 <= waterlevel <= 1.0:  # also refuses NaN
            raise ValueError(f"waterlevel is a height in [0, 1], got {waterlevel!r}")
    options = {} if channel is None else {"channel": channel}
    is_image = FORMATS.get(Path(path).suffix.lower()) == "image"
    if image is not None and is_image:
        options["image"] = image
    if nodata is not None:
        if not is_image:
            raise ValueError(f"{path}: a nodata value applies to image height maps; "
                             f"{Path(path).suffix} files mark their holes themselves")
        options["nodata"] = float(nodata)
    hf = format_module(path).read(path, **options)
    if invert or waterlevel is not None:
        hf = hf.normalized()
    if invert:
        hf.data = (1.0 - hf.data).astype(np.float32)
        if hf.mask is not None:  # holes stay the lowest height
            hf.data[hf.mask] = 0.0
        scale, offset = hf.meta["height_scale"], hf.meta["height_offset"]
        hf.meta.update(height_scale=-scale, height_offset=offset + scale)
    if waterlevel is not None:
        hf.data = np.maximum(hf.data, np.float32(waterlevel))
        hf.meta["waterlevel"] = waterlevel
    return hf


def save_heightfield(hf: Heightfield, path, **options) -> None:
    """Write ``hf`` to ``path`` (format by extension), atomically.

    Args:
        hf: the field to write.
        path (str | os.PathLike): the file; its extension picks the format.
        **options: go to the format's writer, e.g. ``byteorder='>'`` for a big-endian ``.hf``
            or ``source='scene.ray'`` for a z-buffer text header.

    Raises:
        FormatError: an unknown extension, or data the format cannot hold.
        OutputError: the file cannot be written.
    """
    format_module(path).write(hf, path, **options)


def read_step_map(path) -> np.ndarray:
    """A packed step map from an image.

    Args:
        path (str | os.PathLike): a PNG, TGA, TIFF or EXR step map.

    Returns:
        ``(H, W, 4)`` pixels in the stored type (uint8, uint16 or float32).

    Raises:
        FormatError: the file is missing, unreadable or not 4 channels.
    """
    from . import image
    return image.read_rgba(path)


def read_step_map_meta(path) -> dict:
    """The settings a step map was made with, as :func:`write_step_map` stored them.

    Args:
        path (str | os.PathLike): the step map image.

    Returns:
        ``max_ratio``, ``tile``, ``height_scale``, ``height_offset``, ...; ``{}`` for maps made
        elsewhere and for files that are no image.

    Raises:
        FormatError: the image is missing or unreadable.
    """
    from . import image
    if FORMATS.get(Path(path).suffix.lower()) != "image":
        return {}  # only images carry step maps
    return step_map_meta(image.read_description(path))


def step_map_meta(description: str) -> dict:
    """The ``{"csm": ...}`` settings in an image description ({} when there are none)."""
    try:
        meta = json.loads(description).get("csm", {}) if description.startswith("{") else {}
    except (ValueError, AttributeError):
        return {}
    return meta if isinstance(meta, dict) else {}


def write_step_map(packed: np.ndarray, path, meta: dict | None = None) -> None:
    """Write a packed map bit-exactly (PNG, TGA, TIFF, EXR), atomically.

    Args:
        packed: ``(H, W, 4)``: PNG holds uint8/uint16, TGA uint8, TIFF uint8/uint16/float32,
            EXR float32.
        path (str | os.PathLike): the image; its extension picks the format.
        meta: settings the shader needs (max_ratio, tile, height scale and offset), kept as
            JSON ``{"csm": meta}`` in the image's description; see :func:`read_step_map_meta`.

    Raises:
        ValueError: another extension (JPEG is lossy), a type the format cannot hold, or
            settings longer than a TGA holds.
        OutputError: the file cannot be written.
    """
    with step_map_writes([(path, meta)], packed.dtype) as write:
        write(path, packed)


@contextlib.contextmanager
def step_map_writes(files, dtype):
    """Write the images of one step map, each on a thread into a temporary file beside it, and
    publish them together when the block ends (:func:`csm_assets.atomic.atomic_paths`: a full disk,
    an error or Ctrl-C anywhere leaves every old file as it was).

    Args:
        files (list[tuple]): ``(path, meta)`` of every image (meta as for :func:`write_step_map`),
            in the order they are renamed: the last one names the others.
        dtype: the pixels' dtype (every image's).

    Yields:
        ``write(path, packed)``, which starts the write of one of ``files``; each must be written.

    Raises:
        ValueError: before anything is written, a format that cannot hold ``dtype`` or a ``meta``
            (the last file named first: it is the path a user gave).
        OutputError: a file that cannot be written (the first in ``files``' order).
    """
    from ..atomic import atomic_paths
    from . import image

    texts = {Path(path): _description(path, meta) for path, meta in files}
    for path, text in reversed(texts.items()):
        image.check_rgba(np.empty((0, 0, 4), dtype), path, text)
    main = list(texts)[-1]
    if not main.parent.is_dir():
        raise OutputError(main, f"cannot write here: its folder {main.parent} does not exist")
    stop, started = threading.Event(), {}
    with atomic_paths(texts) as tmps, ThreadPoolExecutor(len(texts), "csm-write") as pool:
        into = dict(zip(texts, tmps))

        def write(path, packed):
            path = Path(path)
            started[path] = pool.submit(image.write_rgba, packed, path, texts[path], into[path], stop.is_set)

        try:
            yield write
            wait(started.values())
        except BaseException:
            stop.set()  # the writers stop at their next band of rows
            _settle(started.values())
            raise
        for path in texts:
            e = started[path].exception() if path in started else ValueError(f"{path}: not written")
            if isinstance(e, OutputError) and path != main:  # one the map names (its levels): say which
                raise OutputError(path, f"{str(e).removeprefix(f'{path}: ')} ({main.name}, which names it, "
                                        "is not written)") from e
            if e is not None:
                raise e


def _settle(futures) -> None:
    """Wait for ``futures`` (stopping), through any further Ctrl-C: no writer outlives the block."""
    while True:
        try:
            wait(futures)
            return
        except KeyboardInterrupt:
            continue


def _description(path, meta: dict | None) -> str:
    """The image description :func:`write_step_map` stores ``meta`` as."""
    from . import image
    text = json.dumps({"csm": meta}, sort_keys=True) if meta else ""
    if Path(path).suffix.lower() == ".tga" and len(text) > image.TGA_DESCRIPTION_CHARS and "source" in meta:
        # a TGA has room for 323 characters: the source's name (a note, read by nothing) goes first
        text = json.dumps({"csm": {k: v for k, v in meta.items() if k != "source"}}, sort_keys=True)
    return text
