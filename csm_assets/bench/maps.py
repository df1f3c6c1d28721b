"""Height maps for the cone benchmark: real depth maps and procedural kinds.

Every map is uint8 ``(n, n)`` (heights = value / 255), so the paper's
preprocessor (8-bit PGM input) and this library see the same data.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PROCEDURAL = ("terrain", "tiles", "noise")


def terrain(n: int, seed: int = 1, sea: float = 0.4) -> np.ndarray:
    """Tileable fractal terrain whose lowest ``sea`` fraction is a flat sea at 0."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(n) * n  # cycles per texture: the same landscape at every size
    k = np.hypot(f[:, None], f[None, :])
    k[0, 0] = 1.0
    spec = (rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n))) / k ** 2
    spec[0, 0] = 0.0
    z = np.fft.ifft2(spec).real
    level = np.quantile(z, sea)
    z = np.clip((z - level) / (z.max() - level), 0.0, 1.0)
    return np.round(z * 255).astype(np.uint8)


def tiles(n: int, seed: int = 2) -> np.ndarray:
    """Bricks: 8 courses of 4 bricks, bevelled edges, low mortar, slight roughness."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] / n
    course = np.floor(y * 8)
    bx = (x * 4 + 0.5 * (course % 2)) % 1.0
    by = (y * 8) % 1.0
    edge = np.minimum(np.minimum(bx, 1 - bx) * 4, np.minimum(by, 1 - by) * 8)  # ~0 at mortar
    z = 0.15 + 0.75 * np.clip(edge * 6, 0.0, 1.0) + rng.uniform(0, 0.1, (n, n))
    return np.round(np.clip(z, 0, 1) * 255).astype(np.uint8)


def noise(n: int, seed: int = 3) -> np.ndarray:
    """White noise: every texel a random 8-bit height."""
    return np.random.default_rng(seed).integers(0, 256, (n, n), dtype=np.uint8)


def real_maps(folder: Path) -> dict[str, Path]:
    """Depth maps (``*_disp.*``: white is deep) in ``folder``, by name; {} if absent."""
    if not folder.is_dir():
        return {}
    return {p.stem: p for p in sorted(folder.iterdir()) if "_disp" in p.stem}


def load_real(path: Path, n: int) -> np.ndarray:
    """The depth map at ``path`` as uint8 heights (inverted), resized to n x n with Pillow."""
    from PIL import Image

    with Image.open(path) as im:
        grey = im.convert("L").resize((n, n), Image.Resampling.LANCZOS)
    return (255 - np.asarray(grey, dtype=np.uint8)).astype(np.uint8)


def make_map(kind: str, n: int, real: dict[str, Path]) -> np.ndarray:
    """The map ``kind`` (a procedural kind or a key of ``real``) at n x n."""
    if kind in real:
        return load_real(real[kind], n)
    if kind not in PROCEDURAL:
        raise ValueError(f"unknown map {kind!r}: expected one of {list(PROCEDURAL) + list(real)}")
    return {"terrain": terrain, "tiles": tiles, "noise": noise}[kind](n)
