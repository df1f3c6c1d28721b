"""Measurements: what the project costs and what it buys.

- :mod:`.cones`: the exact cones timed against the paper's preprocessor (``bench cones``), on the
  maps of :mod:`.maps`.
- :mod:`.trade`: the speed/accuracy trade of the shader variants and the cheapest setting that
  meets a budget (``bench trade``, ``convert --max-error``); :mod:`.trade_plot` draws it.
"""
