"""The concepts page's figure (docs/cone_steps.png): a ray stepping through cones.

A profile of 64 texels (row 96 of ``samples/cobbles.png``) is packed with the project's own
:func:`csm_assets.step_map` (16 bits, not tiled, bilinear safety pass) and decoded with
:func:`csm_assets.unpack_step_map`; the ray then marches as ``csm_cone_march`` in
``shaders/csm.glsl`` does: at each point it reads the height and cone under it (linear
interpolation, as the GPU samples), moves to where the ray meets that cone, adds the minimum
step, and stops once it is under the surface. The exact hit comes from
:func:`csm_assets.trace_heightfield`. Run from the repository root:
``python docs/figures/cone_steps.py [OUT.png]`` (needs matplotlib, the ``[plot]`` extra).
``tests/test_docs_figures.py`` runs it and checks what the caption says.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import csm_assets as csm  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "cone_steps.png"
W = 64  # texels in the profile
MIN_STEP = 0.25 / W  # the exact variant's default: a quarter texel, in uv


def profile() -> np.ndarray:
    """float32 ``(1, W)``: a row of the sample height map, heights in [0, 1]."""
    return csm.load_heightfield(ROOT / "samples" / "cobbles.png").data[96:97, :W].copy()


def sample(channel: np.ndarray, u: float) -> float:
    """``channel`` (W,) at uv ``u``, linearly between texel centres, clamped at the ends."""
    return float(np.interp(u * W - 0.5, np.arange(W), channel))


def march(height: np.ndarray, ratio: np.ndarray, u0: float, d: np.ndarray, max_steps: int = 40):
    """The ray's points ``[(u, z, h, r)]``: each point, the height and cone ratio read there."""
    iz, dz = abs(d[0]), -d[1]  # horizontal and downward parts of the unit direction
    s, points = 0.0, []
    for _ in range(max_steps):
        u, z = u0 + d[0] * s, 1.0 + d[1] * s
        h, r = sample(height, u), sample(ratio, u)
        points.append((u, z, h, r))
        above = z - h
        if above <= 0:
            break
        s += MIN_STEP + above * r / max(dz * r + iz, 1e-30)  # csm_cone_step, plus the minimum step
    return points


def figure(out: Path = OUT) -> dict:
    """Draw the figure into ``out``; the march as data: ``points`` ``[(u, z, h, r)]`` (the last one
    under the surface), ``hit_u`` the exact hit's u and ``texels`` (W)."""
    h = profile()
    maps = csm.unpack_step_map(csm.step_map(h, tile=False, bits=16, bilinear_safe=True))
    height, ratio = maps["height"][0], maps["ratio"][0]
    u0, d = 0.25, np.array([np.cos(np.radians(-45)), np.sin(np.radians(-45))])  # 45 degrees below the horizon
    points = march(height, ratio, u0, d)
    hit_uv, t, _ = csm.trace_heightfield(h, np.array([u0, 0.5, 1.0]), np.array([d[0], 0.0, d[1]]), tile=False)

    fig, ax = plt.subplots(figsize=(9, 4.2), dpi=110)
    us = (np.arange(W) + 0.5) / W
    ax.fill_between(us, 0, height, color="#b9a58a", lw=0, label="height field (R)")
    ax.plot(us, height, color="#6b5a45", lw=1)
    for k, (u, z, hh, r) in enumerate(points[:-1]):
        top = z  # the cone up to the ray's height: how far the ray may go
        xs = [u - r * (top - hh), u, u + r * (top - hh)]
        ax.fill(xs, [top, hh, top], color="#4c8cd6", alpha=0.16, lw=0,
                label="cone read at each step (G)" if k == 0 else None)
        ax.plot(xs, [top, hh, top], color="#4c8cd6", lw=0.8, alpha=0.7)
    ray = np.array([(u, z) for u, z, _, _ in points])
    ax.plot(ray[:, 0], ray[:, 1], "-", color="#c0392b", lw=1.2)
    ax.plot(ray[:, 0], ray[:, 1], "o", color="#c0392b", ms=4, label=f"ray: {len(points) - 1} steps")
    ax.plot(hit_uv[0, 0], 1.0 + d[1] * t[0], "x", color="black", ms=9, mew=2, label="exact hit")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("u (64 texels)")
    ax.set_ylabel("height")
    ax.set_title("Cone step mapping: each step goes as far as the cone under the ray allows")
    ax.legend(loc="lower left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    return {"points": points, "hit_u": float(hit_uv[0, 0]), "texels": W}


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else OUT
    r = figure(out)
    print(f"wrote {out}: {len(r['points']) - 1} steps, stopped at u = {r['points'][-1][0]:.4f}, "
          f"exact hit at u = {r['hit_u']:.4f}")


if __name__ == "__main__":
    main()
