"""The step maps of a UDIM set's tiles, made one by one here or each as a task on an executor
(``convert --scheduler``: a Dask cluster's, :func:`csm_assets.dask_client.dask_executor`).

A task (:func:`tile_task`) gets the tile's file as bytes (on a Dask cluster scattered to one
worker: the workers need no view of this machine's files), makes its map with the same code and
settings as a local run and returns it with the Python warnings it raised; the caller saves it, so
the files are those of a local run, byte for byte. Each tile's cones use the cores of the worker
that makes it. A set's tiles made over a common height range (:func:`common_range`) go the same way.
"""

from __future__ import annotations

import tempfile
import warnings
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..formats import load_heightfield
from ..heightfield import Heightfield
from ..scene import HeightInput, safe_name
from ..stepmap import StepMap, StepMapSettings, make_step_map
from ..warning_codes import CodedWarning


def common_range(ranges) -> tuple[float, float]:
    """The ``(height_scale, height_offset)`` spanning every ``(scale, offset)`` of ``ranges`` (``raw =
    offset + scale * h``, h in [0, 1]); negative scales (depth maps read inverted) stay negative."""
    ranges = list(ranges)
    lo = min(min(o, o + s) for s, o in ranges)
    hi = max(max(o, o + s) for s, o in ranges)
    span = hi - lo if hi > lo else 1.0
    return (-span, hi) if ranges[0][0] < 0 else (span, lo)


def over_range(hf: Heightfield, scale: float, offset: float) -> Heightfield:
    """``hf``'s heights as unit heights over the range ``raw = offset + scale * h`` (holes 0)."""
    raw = float(hf.meta.get("height_offset", 0.0)) + float(hf.meta.get("height_scale", 1.0)) * \
        np.asarray(hf.data, np.float64)
    data = np.clip((raw - offset) / scale, 0.0, 1.0)
    data = data if hf.mask is None else np.where(hf.mask, 0.0, data)
    return Heightfield(data.astype(np.float32), hf.mask, {**hf.meta, "height_scale": scale, "height_offset": offset})


def tile_map(file: Path, channel, invert: bool, settings: StepMapSettings, choose=None, common=None,
             rows=None) -> StepMap:
    """The step map of the tile image ``file`` (read by ``channel`` and ``invert``), over the height
    range ``common`` (``(scale, offset)``) when given; ``choose`` picks its bits (else ``settings.bits``)."""
    hf = load_heightfield(file, channel=channel, invert=invert)
    return make_step_map(hf if common is None else over_range(hf, *common), settings, progress=rows, choose=choose)


def tile_task(data: bytes, name: str, channel, invert: bool, settings: StepMapSettings, choose=None,
              common=None) -> tuple[StepMap | None, list, str | None]:
    """A task: :func:`tile_map` of a tile image's bytes ``data`` (its file name ``name``, which picks
    the reader). Returns ``(map, [(message, category)] of the warnings raised, None)``, or ``(None,
    warnings, message)`` when the image cannot be read (a FormatError's message without its path)."""
    with tempfile.TemporaryDirectory(prefix="csm-tile-") as tmp, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CodedWarning)  # as python_warnings takes them in a local run
        file = Path(tmp) / safe_name(name)
        file.write_bytes(data)
        try:
            sm = tile_map(file, channel, invert, settings, choose, common)
        except FormatError as e:
            return None, [], str(e).removeprefix(f"{e.path}: ")
    return sm, [(str(w.message), w.category) for w in caught], None


def tile_maps(h: HeightInput, tiles, settings: StepMapSettings, *, choose=None, common=None, executor=None,
              progress=None):
    """``(tile, StepMap)`` of each tile in ``tiles`` of the set ``h.udim``: in tile order here, or as
    they come from ``executor`` (a task each, :func:`tile_task`; its warnings raised again here, its
    unreadable image a FormatError naming the tile's file), each over the height range ``common``
    when given. ``progress(done, total)``: rows of each tile here, tiles done on an executor."""
    if executor is None:
        for t in tiles:
            with h.udim.tiles[t].as_file() as file:
                yield t, tile_map(file, h.channel, h.invert, settings, choose, common, progress)
        return
    client = getattr(executor, "_client", None)  # Dask's ClientExecutor: each tile's bytes to a worker once
    futures = {}
    try:
        for t in tiles:
            tex = h.udim.tiles[t]
            data = tex.read_bytes()
            name = Path(tex.path).name if tex.path is not None else f"{tex.name}{tex.suffix}"
            sent = client.scatter(data, hash=False) if client is not None else data
            futures[executor.submit(tile_task, sent, name, h.channel, h.invert, settings, choose,
                                    common)] = t
        for done, fut in enumerate(as_completed(futures), 1):
            sm, said, error = fut.result()
            t = futures[fut]
            if error is not None:
                raise FormatError(h.udim.tiles[t].path or h.udim.tiles[t].name, error)
            for message, category in said:
                warnings.warn(message, category, stacklevel=2)
            if progress is not None:
                progress(done, len(futures))
            yield t, sm
    finally:
        for fut in futures:
            fut.cancel()
