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
import warnings
from pathlib import Path

import numpy as np

from .. import limits
from ..atomic import atomic_path
from ..errors import FormatError
from ..heightfield import Heightfield

BACKGROUND = -1000.0  # written for holes whose own depth is not negative
F32_LIMIT = 2.0**128 - 2.0**103  # |v| below it rounds to a finite float32

_NUM = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_RES_RE = re.compile(r"resolution\D*?(\d{1,9})\s*x\s*(\d{1,9})\b", re.I)
_C = r"\s*(-?\d{1,9})\s*"
_WIN_RE = re.compile(rf"window\s+from\s*\({_C},{_C}\)\s*to\s*\({_C},{_C}\)", re.I)
_RAY_RE = re.compile(r'input\s+ray\s+file:\s*"(.*)"', re.I)


def _text(path) -> str:
    """The whole of ``path`` as text (UTF-8, bad bytes replaced)."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror or e}") from e
    if not raw.strip():
        raise FormatError(path, "empty file: expected '#' comments and depth values")
    if b"\0" in raw:
        raise FormatError(path, "binary data (NUL bytes) in a text depth file")
    return raw.decode("utf-8", "replace")


def _header(lines) -> dict:
    """Facts from the comment lines: resolution (W, H), window (x0, y0, x1, y1), ray file."""
    out = {}
    for text in lines:
        s = text.strip()
        if (m := _RES_RE.search(s)) and "resolution" not in out:
            out["resolution"] = (int(m[1]), int(m[2]))
        if (m := _WIN_RE.search(s)) and "window" not in out:
            out["window"] = tuple(int(g) for g in m.groups())
        if (m := _RAY_RE.search(s)) and "ray_file" not in out:
            out["ray_file"] = m[1]
    return out


def _line_of(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _bad_token(path, data: str, pattern: str, what: str) -> None:
    """FormatError at the first whitespace-separated token of ``data`` that is not a whole
    ``pattern`` (one regex pass, no list of tokens)."""
    m = re.search(rf"(?<!\S)(?!(?:{pattern})(?!\S))\S+", data, re.ASCII)
    if m:
        t = m[0]
        shown = "NaN" if t.lower().lstrip("+-") == "nan" else repr(t[:20])
        raise FormatError(path, f"line {_line_of(data, m.start())}: expected {what}, got {shown}")


def _tokens_per_line(data: str) -> tuple[np.ndarray, np.ndarray]:
    """(line numbers, token counts) of the lines of ASCII ``data`` that hold tokens."""
    b = np.frombuffer(data.encode("ascii"), np.uint8)
    space = (b == 32) | ((b >= 9) & (b <= 13))
    start = ~space
    start[1:] &= space[:-1]
    tok = np.flatnonzero(start)
    line = np.searchsorted(np.flatnonzero(b == 10), tok) + 1  # 1-based line of each token
    del b, space, start, tok
    first = np.flatnonzero(np.diff(line, prepend=-1))  # line is sorted: runs are lines
    numbers, counts = line[first], np.diff(np.append(first, line.size))
    return numbers, counts


def _values(path, data: str, count: int) -> np.ndarray:
    """float64 of the ``count`` validated numbers in ``data``; float32 overflow refused."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            d = np.fromstring(data, dtype=np.float64, sep=" ")
        except (ValueError, DeprecationWarning) as e:  # pragma: no cover - tokens were validated
            raise FormatError(path, f"unreadable depth values ({e})") from e
    if d.size != count:  # pragma: no cover - tokens were validated
        raise FormatError(path, f"read {d.size} values where {count} numbers stand")
    return d


def _float32(path, depths: np.ndarray, data: str, k: int) -> np.ndarray:
    """Check the depths (token ``k * i + k - 1`` of ``data`` for depth i) fit a float32."""
    big = ~(np.abs(depths) < F32_LIMIT)  # depths are float32, as in the patch's Float buffer
    if big.any():
        pos = _nth_token(data, k * int(np.argmax(big)) + k - 1)
        tok = re.match(r"\S+", data[pos:])[0]
        raise FormatError(path, f"line {_line_of(data, pos)}: depth {tok[:20]!r} is out of float32 range")
    return depths


def _nth_token(data: str, i: int) -> int:
    """Where token ``i`` of ``data`` starts (error path only)."""
    for n, m in enumerate(re.finditer(r"\S+", data)):
        if n == i:
            return m.start()
    return 0  # pragma: no cover


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
    non-numeric values, and (``.etxt``) duplicate, missing or out-of-window pixels,
    and for more values, or a declared resolution or window of more texels, than
    the TEXELS limit (:mod:`csm_assets.limits`) allows (checked before the grid exists).
    Memory: a few bytes per character of the file (no Python object per value).
    """
    if channel not in (None, 0, "0"):
        raise FormatError(path, f"a depth file has one channel, cannot read channel {channel!r}")
    text = _text(path)
    comment = re.compile(r"^[ \t\f\v\r]*#.*$", re.M)
    head = _header(m[0] for m in comment.finditer(text))
    if "resolution" in head:
        w, h = head["resolution"]
        limits.check(path, "TEXELS", w * h, f"the header's resolution {w}x{h}")
    if "window" in head:
        x0, y0, x1, y1 = head["window"]
        if x1 >= x0 and y1 >= y0:
            limits.check(path, "TEXELS", (x1 - x0 + 1) * (y1 - y0 + 1),
                         f"the header's window {x1 - x0 + 1}x{y1 - y0 + 1}")
    data = comment.sub("", text)  # comment lines blanked, line numbers kept
    etxt = Path(path).suffix.lower() == ".etxt"
    _bad_token(path, data, _NUM, "a depth")
    linenos, counts = _tokens_per_line(data)
    if not linenos.size:
        raise FormatError(path, "no depth values after the comments")
    total = int(counts.sum())
    limits.check(path, "TEXELS", total // 3 if etxt else total, f"a file of {total} values")
    if etxt:
        return _field(path, _grid(path, data, linenos, counts, head), head, "zbuf-etxt")
    width = int(counts[0])
    ragged = np.flatnonzero(counts != width)
    if ragged.size:
        i = int(ragged[0])
        raise FormatError(path, f"line {linenos[i]}: ragged rows: {counts[i]} depths where the first row has {width}")
    d = _float32(path, _values(path, data, total), data, 1).reshape(len(counts), width)
    return _field(path, d[::-1], head, "zbuf-txt")


def _grid(path, data: str, linenos, counts, head) -> np.ndarray:
    """``x y depth`` lines -> image-order depths (row 0 = top = highest y)."""
    wrong = np.flatnonzero(counts != 3)
    if wrong.size:
        i = int(wrong[0])
        raise FormatError(path, f"line {linenos[i]}: expected 'x y depth', got {counts[i]} values")
    coord = r"[+-]?\d{1,9}"
    m = re.search(rf"^(?![ \t\f\v\r]*(?:{coord})[ \t\f\v\r]+(?:{coord})[ \t\f\v\r]+\S+[ \t\f\v\r]*$)"
                  rf"[ \t\f\v\r]*\S.*$", data, re.M | re.ASCII)
    if m:
        raise FormatError(path, f"line {_line_of(data, m.start())}: expected integer pixel coordinates, "
                                f"got {m[0].strip()[:40]!r}")
    v = _values(path, data, 3 * len(linenos)).reshape(-1, 3)
    depth = _float32(path, v[:, 2], data, 3)
    x, y = v[:, 0].astype(np.int64), v[:, 1].astype(np.int64)
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
