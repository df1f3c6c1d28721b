"""One map's cone search in bands of rows on an executor: a Dask cluster's
(:func:`csm_assets.dask_client.dask_executor`), tile by tile, with the bytes of a local run.

Each band is a task, :func:`band_ratios`, that searches its rows against the whole map with the
same kernels and the same float64 steps as the local search (:func:`~.exact.exact_ratios` with
the method chosen here, on the whole map, as a local run chooses it; :func:`~.quadrant.quadrant_exact`),
so its ratios are those of the local run, bit for bit. The heights go to the cluster once
(``scatter``, to every worker) when the executor is Dask's; each worker builds their max pyramid
once (kept for the next band, until another map comes) . Other executors get the heights with each
band. A map whose conservative cones the levels method makes (few distinct heights: quick) and the
relaxed cones are made here, not on the cluster.
"""

from __future__ import annotations

import threading
import uuid
from concurrent.futures import as_completed

import numpy as np

from ..heightfield import tile_pair
from .exact import exact_ratios
from .pyramid import pyramid_heights
from .quadrant import GROUP, quadrant_exact

BAND_TEXELS = 1 << 21  # texels a band, about: a task's float64 ratios are 16 MiB (quadrant 64)
_LOCK = threading.Lock()
_PYRAMID: dict = {}  # token -> (h, pyramid): the latest map's, on each worker


def band_rows(H: int, W: int, texels: int | None = None) -> list[tuple[int, int]]:
    """``(r0, r1)`` bands covering 0..H, about ``texels`` each, starting at multiples of GROUP."""
    step = max(GROUP, (texels or BAND_TEXELS) // max(W, 1) // GROUP * GROUP)
    return [(r0, min(H, r0 + step)) for r0 in range(0, H, step)]


def _pyramid_of(token: str, heights: np.ndarray):
    with _LOCK:
        if token not in _PYRAMID:
            _PYRAMID.clear()  # another map's: its memory goes first
            _PYRAMID[token] = pyramid_heights(heights)
        return _PYRAMID[token]


def forget() -> None:
    """Drop the pyramid a worker keeps (run on each worker once a map is done)."""
    with _LOCK:
        _PYRAMID.clear()


def band_ratios(heights: np.ndarray, token: str, kind: str, method: str, r0: int, r1: int,
                tile_x: bool, tile_y: bool, max_ratio: float) -> np.ndarray:
    """A task: the exact ratios of rows ``r0..r1`` of validated heights ``heights`` (codes or float
    unit heights) as the local search makes them: float64 ``(r1 - r0, W)`` for "conservative"
    (:func:`~.exact.exact_ratios` by ``method``), ``(4, r1 - r0, W)`` for "quadrant"."""
    h, pyramid = _pyramid_of(token, heights)
    if kind == "quadrant":
        return quadrant_exact(h, tile_x, tile_y, max_ratio, pyramid=pyramid, rows=(r0, r1))
    return exact_ratios(h, tile_x, tile_y, max_ratio, method=method, pyramid=pyramid, rows=(r0, r1))


def remote_ratios(executor, heights: np.ndarray, kind: str, sink, *, tile=True, max_ratio=1.0,
                  method: str = "pyramid", progress=None, texels: int | None = None) -> None:
    """Search ``kind`` ("conservative" by ``method``, or "quadrant") cones of ``heights`` in bands of
    rows on ``executor`` (a ``concurrent.futures`` executor; Dask's gets the heights once by
    scatter); ``sink(r0, ratios)`` takes each band as it comes (:func:`band_ratios`' arrays, any
    order), ``progress(done_rows, total_rows)`` after each. A band's error is raised here."""
    tx, ty = tile_pair(tile)
    H, W = heights.shape
    client = getattr(executor, "_client", None)  # Dask's ClientExecutor: scatter once, to every worker
    data = client.scatter(heights, broadcast=True, hash=False) if client is not None else heights
    token = uuid.uuid4().hex
    futures = {executor.submit(band_ratios, data, token, kind, method, r0, r1, tx, ty, max_ratio): r0
               for r0, r1 in band_rows(H, W, texels)}
    done = 0
    try:
        for fut in as_completed(futures):
            ratios = fut.result()
            sink(futures[fut], ratios)
            done += ratios.shape[-2]
            if progress is not None:
                progress(done, H)
    finally:
        for fut in futures:
            fut.cancel()
        if client is not None:
            client.run(forget)
