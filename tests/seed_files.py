"""Seed-format files written independently of csm_assets (struct, plain text, Pillow),
from the seeds' descriptions, so readers are checked against the formats themselves."""

from __future__ import annotations

import struct

import numpy as np
from PIL import Image


def hf_file(path, values, order="<", size=None):
    """Rayshade .hf: int32 size, then size*size float32 in file order (value i at x=i%size, y=i//size)."""
    values = list(values)
    n = size if size is not None else int(round(len(values) ** 0.5))
    path.write_bytes(struct.pack(f"{order}i", n) + struct.pack(f"{order}{len(values)}f", *values))
    return path


def txt_file(path, rows_bottom_first, header=True):
    head = ['# Depth Map for Rayshade output file', '# Input RAY file: "planet.ray"',
            f"# Resolution for this rendering is {len(rows_bottom_first[0])}x{len(rows_bottom_first)}"]
    lines = (head if header else []) + [" ".join(str(v) for v in row) for row in rows_bottom_first]
    path.write_text("\n".join(lines) + "\n")
    return path


def etxt_file(path, triples, window=None):
    head = ["# Depth Map for Rayshade output file", '# Input RAY file: "../Examples/planet.ray"']
    if window:
        x0, y0, x1, y1 = window
        head += [f"# Resolution for this rendering is {x1 - x0 + 1}x{y1 - y0 + 1}",
                 f"# window from ({x0},{y0}) to ({x1},{y1})"]
    head.append("# Index 0: 11412 hits")
    body, last_x = [], None
    for x, y, d in triples:
        if last_x is not None and x != last_x:
            body.append("")
        body.append(f"{x} {y} {d}")
        last_x = x
    path.write_text("\n".join(head + body) + "\n")
    return path


def gif_file(path, indices, palette=None):
    """A palette GIF holding ``indices`` (row 0 on top); ``palette`` maps index -> (r, g, b)."""
    im = Image.fromarray(np.asarray(indices, dtype=np.uint8), mode=None).convert("P")
    im.putdata(np.asarray(indices, dtype=np.uint8).ravel().tolist())
    if palette is None:
        palette = [(i, i, i) for i in range(256)]
    im.putpalette([c for rgb in palette for c in rgb])
    im.save(path, format="GIF", optimize=False)
    return path


def pot_file(path, heights16):
    v = np.asarray(heights16, dtype=np.uint16)
    return gif_file(path, np.concatenate([v >> 8, v & 0xFF], axis=1).astype(np.uint8))
