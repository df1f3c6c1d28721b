"""Proof that step maps and converted scenes render right: GPU renders against exact CPU references.

- :mod:`.maps`: a step map drawn with the shipped shader against :mod:`.trace` (exact ray /
  heightfield intersection); :mod:`.stats` holds the numbers, :mod:`.images` the pictures.
- :mod:`.scene`: a converted glTF, GLB, OBJ or USD scene, each primitive from :mod:`.views`.
- :mod:`.shadows`, :mod:`.shadows_scene`: self-shadows against :mod:`.shadow_reference`.
"""
