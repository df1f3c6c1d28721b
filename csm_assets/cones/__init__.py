"""Cone ratio kernels over heightfields: pure numpy/numba functions, no paths, no GL.

- :mod:`.exact`: the exact conservative cone ratios (``cone_ratios``, ``exact_ratios``) and the
  choice among the three exact methods:
  :mod:`.ring` (outward square rings), :mod:`.pyramid` (branch and bound over a max-height
  pyramid), :mod:`.levels` (one distance transform per height level).
- :mod:`.relaxed`: exact relaxed cone ratios (``relaxed_cone_ratios``), with its search kernel
  in :mod:`.relaxed_search`.
"""
