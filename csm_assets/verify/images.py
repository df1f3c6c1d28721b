"""PNG pictures of a verification view, for people who would rather look.

Per view, ``<stem>_color.png`` (the render), ``<stem>_uv.png`` and
``<stem>_ref_uv.png`` (hit texture coordinates of the render and of the exact
reference as red = u, green = v, wrapped into [0, 1); blue marks pixels where
it missed), ``<stem>_error.png`` (texel error: black 0, through blue and green
to red at 2 texels or more; magenta where only one of the two hit; dark grey
not compared) and ``<stem>_iterations.png`` (iterations, black 0 to white at
the view's maximum). For scenes, :func:`contact_sheet` puts every view's render and
error picture on one labelled PNG with a legend of the error colours.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import OutputError

_RAMP = np.array([[0, 0, 0], [0, 0, 255], [0, 255, 0], [255, 255, 0], [255, 0, 0]], np.float64)


def save_view_images(directory: Path, stem: str, res, ref_uv, ref_hit, err) -> list[Path]:
    """Write the five PNGs of one view into ``directory`` (created if needed); returns their paths."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(directory, f"cannot create the image directory: {e.strerror or e}") from e
    covered = res.covered
    pictures = {
        "color": np.clip(res.color[..., :3] * 255 + 0.5, 0, 255).astype(np.uint8),
        "uv": _uv_picture(res.hit_uv, covered & (res.status != 2), covered),
        "ref_uv": _uv_picture(ref_uv, covered & ref_hit, covered),
        "error": _error_picture(err),
        "iterations": _iteration_picture(res.iterations, covered),
    }
    paths = []
    for name, img in pictures.items():
        path = directory / f"{stem}_{name}.png"
        write_png(img, path)
        paths.append(path)
    return paths


def heat(x: np.ndarray) -> np.ndarray:
    """uint8 RGB ``(..., 3)`` for values in [0, 1] along black-blue-green-yellow-red."""
    s = np.clip(np.nan_to_num(x), 0.0, 1.0) * (len(_RAMP) - 1)
    i = np.minimum(s.astype(int), len(_RAMP) - 2)
    f = (s - i)[..., None]
    return (_RAMP[i] * (1 - f) + _RAMP[i + 1] * f + 0.5).astype(np.uint8)


def _uv_picture(uv, hit, covered):
    img = np.zeros(uv.shape[:2] + (3,), np.uint8)
    frac = np.mod(np.nan_to_num(uv), 1.0)
    img[hit, 0] = (frac[hit, 0] * 255).astype(np.uint8)
    img[hit, 1] = (frac[hit, 1] * 255).astype(np.uint8)
    img[covered & ~hit, 2] = 255
    return img


def _error_picture(err):
    img = heat(err / 2.0)
    img[np.isnan(err)] = 40
    img[np.isinf(err)] = (255, 0, 255)
    return img


def _iteration_picture(iterations, covered):
    top = max(int(iterations[covered].max()) if covered.any() else 1, 1)
    g = (iterations.astype(np.float64) / top * 255).clip(0, 255).astype(np.uint8)
    g[~covered] = 0
    return np.repeat(g[..., None], 3, axis=2)


def write_png(img: np.ndarray, path: Path) -> None:
    from PIL import Image

    with atomic_path(path) as tmp:
        Image.fromarray(img, "RGB").save(tmp, format="PNG")


def contact_sheet(path: Path, entries, max_error: float, columns: int = 3) -> Path:
    """One PNG of every view drawn: per entry ``(label, RenderResult, err (h, w))`` the
    render and its error picture side by side under the label (two lines at most, split at a
    newline, each fitted to the cell keeping its start and end), and a legend of the error
    colours (texels; magenta: only one of render and reference hit; grey: not compared)."""
    from PIL import Image, ImageDraw

    from .stats import fit

    h, w = entries[0][1].color.shape[:2]
    pad, text_h = 4, 26  # two lines: what was drawn (a primitive), then how (variant and view)
    cell_w, cell_h = 2 * w + 3 * pad, h + text_h + 2 * pad
    rows = -(-len(entries) // columns)
    legend_h = 46
    sheet = Image.new("RGB", (max(columns * cell_w, 360), rows * cell_h + legend_h), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for k, (label, res, err) in enumerate(entries):
        x, y = (k % columns) * cell_w, (k // columns) * cell_h
        for i, line in enumerate(label.split("\n")[:2]):  # long names keep their start and end
            draw.text((x + pad, y + 1 + 12 * i), fit(line, max(cell_w // 6, 8)), fill=(0, 0, 0))
        colour = np.clip(res.color[..., :3] * 255 + 0.5, 0, 255).astype(np.uint8)
        sheet.paste(Image.fromarray(colour, "RGB"), (x + pad, y + text_h))
        sheet.paste(Image.fromarray(_error_picture(err), "RGB"), (x + 2 * pad + w, y + text_h))
    y = rows * cell_h + 4
    ramp = heat(np.linspace(0.0, 1.0, 200)[None, :].repeat(12, axis=0))
    sheet.paste(Image.fromarray(ramp, "RGB"), (pad, y + 12))
    draw.text((pad, y), f"texel error (right-hand pictures); budget {max_error:g}", fill=(0, 0, 0))
    for value in (0, 0.5, 1, 1.5, 2):
        draw.text((pad + int(value / 2 * 199) - 3, y + 26), f"{value:g}" + ("+" if value == 2 else ""),
                  fill=(0, 0, 0))
    draw.rectangle((220, y + 12, 232, y + 24), fill=(255, 0, 255))
    draw.text((236, y + 12), "one side hit", fill=(0, 0, 0))
    draw.rectangle((220, y + 28, 232, y + 40), fill=(40, 40, 40))
    draw.text((236, y + 28), "not compared", fill=(0, 0, 0))
    write_png(np.asarray(sheet), path)
    return path


def unique_stem(name: str, taken: set) -> str:
    """A file-name stem for a primitive: its whole name made safe (USD paths keep their
    folders as '_'), numbered when another primitive already has it."""
    from ..scene import safe_name

    base = safe_name(name.replace("/", "_").replace("\\", "_"))
    stem, n = base, 2
    while stem in taken:
        stem, n = f"{base}_{n}", n + 1
    taken.add(stem)
    return stem


def save_case_images(directory: Path, prim: str, stem: str, variant: str, case, res, err, size):
    """The PNGs of one view of a scene's primitive (``case``: its :class:`~csm_assets.verify.maps.ViewCase`);
    the entry :func:`contact_sheet` takes for it."""
    from ..scene import safe_name

    view = case.name or f"el{case.elevation:g}_az{case.azimuth:g}"
    ref_uv, ref_hit, _ = case.reference(res)
    save_view_images(directory, f"{stem}_{variant}_{safe_name(view)}", res, ref_uv.reshape(size, size, 2),
                     ref_hit.reshape(size, size), err)
    return f"{prim}\n{variant} {view}", res, err
