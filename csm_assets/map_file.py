"""A map file as ``verify`` and ``bench trade`` read it: a step map, or a height map made into step maps.

:func:`load_step_maps` reads the file once (a step map written by csm-assets keeps its settings;
a height map is made into the step maps of the cone kinds asked for, from one conservative
cone pass); :func:`load_packed` is its one-map form, as :func:`csm_assets.verify.maps.verify_file`
takes it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def load_step_maps(path, *, invert=False, as_step_map=None, bits=8, max_ratio=None, tile=None, channel=None,
                   bilinear_safe=True, cones=("conservative",), nodata=None, levels="none") -> dict:
    """The :class:`~csm_assets.stepmap.StepMap` s of a file, by cone kind, read with one open.

    A step map file gives itself alone (under its own ``cones``, whatever ``cones`` asks); a
    height map gives one step map per kind in ``cones`` (``bits``, ``bilinear_safe``; the
    relaxed ones from the conservative cones already made; ``bits`` may be a function that
    chooses them, as :func:`~csm_assets.stepmap.make_step_maps`' ``choose``). ``max_ratio`` and ``tile`` given
    here win over a step map's own (None: its own, else :data:`~csm_assets.stepmap.DEFAULTS`').

    With ``as_step_map`` None, a map carrying csm-assets' settings is a step map; an RGBA
    image without them whose R, G and B differ is refused (FormatError): it may be a step map
    made elsewhere, and reading its packed channels as heights would verify the wrong thing.
    nodata: a height map's stored value of holes (:func:`~csm_assets.formats.load_heightfield`).
    levels: the level chain of step maps made from heights (default ``"none"``: verify and bench
    measure level 0; ``verify --distance`` asks for ``"average"``); a step map file keeps its own.
    Say ``as_step_map=True`` (``--step-map``, with ``--max-ratio``, ``--no-tile``), or False
    (``--height-map``), or name a ``channel`` to read heights from.
    """
    from .errors import FormatError
    from .formats import FORMATS, load_heightfield
    from .formats.image import read_pixels
    from .stepmap import DEFAULTS, load_step_map, make_step_maps

    given = DEFAULTS.replace(max_ratio=max_ratio, tile=tile)
    image = read_pixels(path, describe=True) if FORMATS.get(Path(path).suffix.lower()) == "image" else None
    sm = None if as_step_map is False else load_step_map(path, optional=True, image=image,  # the one open
                                                         external=given.replace(bilinear_safe=False)
                                                         if as_step_map else None)
    if as_step_map is None and sm is None and channel is None and maybe_step_map(image):
        raise FormatError(path, "is an RGBA image without csm-assets' step map settings: if it is a step "
                                "map, say so with --step-map (and its --max-ratio, --no-tile, --min-step); "
                                "if it holds heights, say --height-map (luminance) or name a --channel")
    if sm is not None:
        sm.settings = sm.settings.replace(max_ratio=max_ratio, tile=tile)  # arguments given here win
        return {sm.settings.cones: sm}
    hf = load_heightfield(path, channel=channel, invert=invert, image=image, nodata=nodata)
    settings = given.replace(bilinear_safe=bilinear_safe, levels=levels)
    if callable(bits):
        return make_step_maps(hf, settings, cones, choose=bits)
    return make_step_maps(hf, settings.replace(bits=bits), cones)


def load_packed(path, *, invert=False, as_step_map=None, bits=8, max_ratio=None, tile=None, channel=None,
                bilinear_safe=True, min_step=None, cones="conservative"):
    """(packed map, max_ratio, tile, exact's min_step) of a file, as :func:`csm_assets.verify.maps.verify_file`
    reads it: :func:`load_step_maps`' one map (``cones``: the cones of a step map made here from
    heights). min_step: None for the map's own (see :attr:`~csm_assets.stepmap.StepMapSettings.min_step`)."""
    (sm,) = load_step_maps(path, invert=invert, as_step_map=as_step_map, bits=bits, max_ratio=max_ratio,
                           tile=tile, channel=channel, bilinear_safe=bilinear_safe, cones=(cones,)).values()
    s = sm.settings
    return sm.pixels, s.max_ratio, s.tile, float(s.min_step if min_step is None else min_step)


def maybe_step_map(image) -> bool:
    """Whether an image already read (``read_pixels``' pixels, names, text; None for other
    formats) could be a packed step map: four integer channels that are not one grey (a grey
    image saved as RGBA, R = G = B, is certainly heights: a step map's G and B differ from R).
    Float images (EXR) and other formats are left to their readers."""
    if image is None:
        return False
    a = image[0]
    if a.shape[2] != 4 or a.dtype not in (np.uint8, np.uint16):
        return False
    return not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 0], a[..., 2]))
