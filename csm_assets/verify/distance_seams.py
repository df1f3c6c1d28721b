"""How visible the level chain's seams are: where neighbouring pixels march different levels.

The level march chooses one integer level a pixel (``csm_march_lod``), so on a receding surface
the level steps from k to k + 1 along a line across the image. Its hits are each level's own, so
a seam would show as a jump between the two pixels beside that line that the true picture does
not have. :func:`seam_contrast` compares the image's change across the pixel pairs that straddle
a level change with the reference's change across the same pairs, against the same comparison
over the pairs within one level: 1 means a seam stands out no more than any other pixel pair.
"""

from __future__ import annotations

import math

import numpy as np


def neighbour_pairs(shape) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices ``(a, b)`` of every horizontally and vertically adjacent pixel pair of an
    image of ``shape`` ``(rows, cols)``."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    return (np.concatenate([idx[:, :-1].ravel(), idx[:-1, :].ravel()]),
            np.concatenate([idx[:, 1:].ravel(), idx[1:, :].ravel()]))


def seam_contrast(image, reference, lod, valid) -> tuple[float, float]:
    """``(contrast, share)`` of the level seams of one image.

    Args:
        image: float ``(h, w)``, the shaded image.
        reference: float ``(h, w)``, the supersampled reference of the same view.
        lod: ``(h, w)``, the level each pixel marched.
        valid: bool ``(h, w)``, pixels both images hold.

    Returns:
        contrast: RMS over the pixel pairs across a level change of (the image's difference
        minus the reference's), over the same RMS for the pairs within one level (NaN when
        there are no pairs of either kind; inf when the pairs within a level are exact).
        share: the share of valid pairs that straddle a level change.
    """
    a, b = neighbour_pairs(np.shape(image))
    img, ref = np.ravel(image), np.ravel(reference)
    lev, ok = np.rint(np.ravel(lod)), np.ravel(valid)
    ok = ok[a] & ok[b]
    err = (img[a] - img[b]) - (ref[a] - ref[b])
    seam, rest = ok & (lev[a] != lev[b]), ok & (lev[a] == lev[b])
    share = float(seam.sum() / ok.sum()) if ok.any() else 0.0
    if not seam.any() or not rest.any():
        return math.nan, share
    within = float(np.sqrt(np.mean(err[rest] ** 2)))
    across = float(np.sqrt(np.mean(err[seam] ** 2)))
    return (across / within if within > 0 else math.inf), share
