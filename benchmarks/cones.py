"""Exact cone ratios against the paper's preprocessor: ``python benchmarks/cones.py --help``.

The same as ``csm-assets bench cones`` (the logic is :mod:`csm_assets.bench.cones`).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from csm_assets.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["bench", "cones", *sys.argv[1:]]))
