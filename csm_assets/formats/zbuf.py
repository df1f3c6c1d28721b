"""Rayshade z-buffer text output (Maimone's zbuf patch): ``.txt`` and ``.etxt``.

``.txt``: '#' comment lines, then one line per image row, **bottom row first**
(Rayshade's y points up), depths separated by whitespace.
``.etxt``: '#' comment lines, then ``x y depth`` lines (integer column ``x``,
integer row ``y`` counted from the bottom), in blocks separated by blank lines;
the patch keeps ``x`` fixed within a block, but any order is read.

Depths are distances (positive); any negative depth is background (the patch's
text says -1000, its own example shows -1) and goes into ``mask``; ``data`` keeps
the raw depths, background values included. Comments are free text, but when a
``Resolution ... is WxH`` line is present it must match the data (W columns,
H rows), and an ``.etxt`` ``window from (x0,y0) to (x1,y1)`` line fixes the grid:
each of its pixels must appear exactly once (without it, the coordinates' bounds).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import FormatError
from ..heightfield import Heightfield

EXTENSIONS = (".txt", ".etxt")
BACKGROUND = -1000.0  # written for holes whose own depth is not negative
F32_LIMIT = 2.0**128 - 2.0**103  # |v| below it rounds to a finite float32

_NUM = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_RES_RE = re.compile(r"resolution\D*?(\d{1,9})\s*x\s*(\d{1,9})\b", re.I)
_C = r"\s*(-?\d{1,9})\s*"
_WIN_RE = re.compile(rf"window\s+from\s*\({_C},{_C}\)\s*to\s*\({_C},{_C}\)", re.I)
_RAY_RE = re.compile(r'input\s+ray\s+file:\s*"(.*)"', re.I)


def _lines(path) -> list[str]:
    """Every line of ``path`` (UTF-8, bad bytes replaced); line n is item n - 1."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from e
    if not raw.strip():
        raise FormatError(path, "empty file: expected '#' comments and depth values")
    if b"\0" in raw:
        raise FormatError(path, "binary data (NUL bytes) in a text depth file")
    return raw.decode("utf-8", "replace").splitlines()


def _header(path, lines) -> dict:
    """Facts from the comment lines: resolution (W, H), window (x0, y0, x1, y1), ray file."""
    out = {}
    for text in lines:
        s = text.strip()
        if not s.startswith("#"):
            continue
        if (m := _RES_RE.search(s)) and "resolution" not in out:
            out["resolution"] = (int(m[1]), int(m[2]))
        if (m := _WIN_RE.search(s)) and "window" not in out:
            out["window"] = tuple(int(g) for g in m.groups())
        if (m := _RAY_RE.search(s)) and "ray_file" not in out:
            out["ray_file"] = m[1]
    return out


def _numbers(path, toks: list[str], linenos, per_line: int, what: str, pattern) -> list[str]:
    """Check every token fully matches ``pattern`` (one regex pass over all of them);
    on failure name the first bad token's line. ``linenos[i // per_line]`` is token i's line."""
    if re.fullmatch(rf"(?:(?:{pattern})\n)*(?:{pattern})", "\n".join(toks)):
        return toks
    rx = re.compile(pattern)
    i = next(i for i, t in enumerate(toks) if not rx.fullmatch(t))
    t = toks[i]
    shown = "NaN" if t.lower().lstrip("+-") == "nan" else repr(t[:20])
    raise FormatError(path, f"line {linenos[i // per_line]}: expected {what}, got {shown}")


def _depths(path, toks: list[str], linenos, per_line: int) -> np.ndarray:
    """float64 depths of decimal ``toks``; NaN, inf, words and float32 overflow refused."""
    d = np.array(_numbers(path, toks, linenos, per_line, "a depth", _NUM), dtype=np.float64)
    big = ~(np.abs(d) < F32_LIMIT)  # depths are float32, as in the patch's Float buffer
    if big.any():
        i = int(np.argmax(big))
        raise FormatError(path, f"line {linenos[i // per_line]}: depth {toks[i][:20]!r} is out of float32 range")
    return d


def _field(path, depth: np.ndarray, head: dict, fmt: str) -> Heightfield:
    """Image-order depths -> Heightfield, checking the header's resolution."""
    h, w = depth.shape
    if "resolution" in head and head["resolution"] != (w, h):
        rw, rh = head["resolution"]
        raise FormatError(path, f"header says resolution {rw}x{rh}, the data is {w}x{h} (columns x rows)")
    mask = depth < 0.0
    meta = {"source": str(path), "format": fmt, "holes": int(mask.sum()),
            **{k: head[k] for k in ("window", "ray_file") if k in head}}
    return Heightfield(depth.astype(np.float32), mask if mask.any() else None, meta)


def read(path, *, channel=None) -> Heightfield:
    """Read a ``.txt`` or ``.etxt`` depth file into raw depths in image order.

    Returns float32 ``(H, W)`` depths with ``mask`` True where a depth is negative
    (background). Raises FormatError for an empty file, ragged rows, NaN or
    non-numeric values, and (``.etxt``) duplicate, missing or out-of-window pixels.
    """
    if channel not in (None, 0, "0"):
        raise FormatError(path, f"a depth file has one channel, cannot read channel {channel!r}")
    lines = _lines(path)
    head = _header(path, lines)
    # flat lists of str and int, no list per line: a million small lists wake the GC up
    linenos = [n for n, t in enumerate(lines, 1) if t.strip() and not t.lstrip().startswith("#")]
    if not linenos:
        raise FormatError(path, "no depth values after the comments")
    texts = [lines[n - 1] for n in linenos]
    if Path(path).suffix.lower() == ".etxt":
        return _field(path, _grid(path, texts, linenos, head), head, "zbuf-etxt")
    toks, counts = [], []
    for t in texts:
        row = t.split()
        counts.append(len(row))
        toks.extend(row)
    width = counts[0]
    for n, c in zip(linenos, counts):
        if c != width:
            raise FormatError(path, f"line {n}: ragged rows: {c} depths where the first row has {width}")
    d = _depths(path, toks, linenos, width).reshape(len(counts), width)
    return _field(path, d[::-1], head, "zbuf-txt")


def _grid(path, texts, linenos, head) -> np.ndarray:
    """``x y depth`` lines -> image-order depths (row 0 = top = highest y)."""
    xs, ys, ds = [], [], []
    for n, t in zip(linenos, texts):
        row = t.split()
        if len(row) != 3:
            raise FormatError(path, f"line {n}: expected 'x y depth', got {len(row)} values")
        xs.append(row[0])
        ys.append(row[1])
        ds.append(row[2])
    for c in (xs, ys):
        _numbers(path, c, linenos, 1, "integer pixel coordinates", r"[+-]?\d{1,9}")
    depth = _depths(path, ds, linenos, 1)
    x, y = np.array(xs).astype(np.int64), np.array(ys).astype(np.int64)
    if "window" in head:
        x0, y0, x1, y1 = head["window"]
        if x1 < x0 or y1 < y0:
            raise FormatError(path, f"header window from ({x0},{y0}) to ({x1},{y1}) is empty")
        outside = (x < x0) | (x > x1) | (y < y0) | (y > y1)
        if outside.any():
            i = int(np.argmax(outside))
            raise FormatError(path, f"line {linenos[i]}: pixel ({x[i]},{y[i]}) is outside the header's "
                                    f"window ({x0},{y0})-({x1},{y1})")
    else:
        x0, y0, x1, y1 = int(x.min()), int(y.min()), int(x.max()), int(y.max())
    w, h = x1 - x0 + 1, y1 - y0 + 1
    key = (y - y0) * w + (x - x0)
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(key[order][1:] == key[order][:-1])
    if dup.size:
        i = int(order[dup[0] + 1])
        raise FormatError(path, f"line {linenos[i]}: duplicate pixel ({x[i]},{y[i]})")
    if len(key) != w * h:  # checked before allocating the grid
        have = np.zeros(w * h, bool) if w * h <= 4 * len(key) else None
        where = ""
        if have is not None:
            have[key] = True
            miss = int(np.argmin(have))
            where = f", e.g. ({x0 + miss % w},{y0 + miss // w})"
        raise FormatError(path, f"missing pixels: {len(key)} given for a {w}x{h} grid "
                                f"from ({x0},{y0}) to ({x1},{y1}){where}")
    grid = np.empty(w * h, dtype=np.float64)
    grid[key] = depth
    return grid.reshape(h, w)[::-1]


def _fmt(v: float) -> str:
    """The shortest text that reads back as the same float32 (``3.75485``, ``-1``)."""
    v = np.float32(v)
    if v != 0 and not 1e-4 <= abs(v) < 1e16:
        return np.format_float_scientific(v, unique=True, trim="-")
    return np.format_float_positional(v, unique=True, trim="-")


def write(hf: Heightfield, path, *, source=None) -> None:
    """Write depths as ``.txt`` (rows, bottom first) or ``.etxt`` (``x y depth``
    blocks, x fixed in a block), atomically, under the patch's comment header.

    source: the "Input RAY file" of the header (default: ``meta['ray_file']`` or
    ``meta['source']``). Holes are written as their own depth when it is negative,
    else as -1000. Raises FormatError for negative or non-finite valid depths
    (they would read back as background).
    """
    d = np.asarray(hf.data, dtype=np.float32)
    holes = np.zeros(d.shape, bool) if hf.mask is None else np.asarray(hf.mask, bool)
    valid = d[~holes]
    if not np.isfinite(valid).all():
        raise FormatError(path, "cannot write NaN or infinite depths outside the holes")
    if valid.size and valid.min() < 0:
        raise FormatError(path, f"valid depth {valid.min():g} is negative and would read back as background")
    d = np.where(holes & ~(d < 0), np.float32(BACKGROUND), d)
    d = np.where(np.isfinite(d), d, np.float32(BACKGROUND))
    h, w = d.shape
    x0, y0 = 0, 0
    win = hf.meta.get("window")
    if win is not None and len(win) == 4 and (win[2] - win[0] + 1, win[3] - win[1] + 1) == (w, h):
        x0, y0 = int(win[0]), int(win[1])
    src = source if source is not None else hf.meta.get("ray_file", hf.meta.get("source", "unknown"))
    src = " ".join(str(src).splitlines())  # one comment line
    out = ["# Depth Map for Rayshade output file",
           f'# Input RAY file: "{src}"',
           f"# Resolution for this rendering is {w}x{h}",
           f"# window from ({x0},{y0}) to ({x0 + w - 1},{y0 + h - 1})"]
    up = d[::-1]  # row 0 = bottom
    text = [[_fmt(v) for v in row] for row in up]
    if Path(path).suffix.lower() == ".etxt":
        for c in range(w):
            out.extend(f"{x0 + c} {y0 + r} {text[r][c]}" for r in range(h))
            out.append("")
    else:
        out.extend(" ".join(row) for row in text)
    with atomic_path(path) as tmp:
        Path(tmp).write_text("\n".join(out) + "\n", encoding="utf-8")
