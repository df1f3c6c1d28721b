"""Heavy dependencies only where used: matplotlib is the `plot` extra, imported by the plot alone."""

from __future__ import annotations

import subprocess
import sys

import pytest

from csm_assets.cli import main


def test_the_pipeline_does_not_import_matplotlib():
    """What a pre-commit hook runs (convert, check, hook, verify) never needs matplotlib."""
    code = ("import sys, csm_assets, csm_assets.cli, csm_assets.convert.pipeline, csm_assets.convert.batch, "
            "csm_assets.verify.maps, csm_assets.bench.trade, csm_assets.bench.cones; "
            "sys.exit('matplotlib' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_plot_without_matplotlib_is_an_options_error_before_measuring(tmp_path, monkeypatch, capsys):
    from PIL import Image
    import numpy as np

    src = tmp_path / "h.png"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(src)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib raises ImportError
    monkeypatch.setattr("csm_assets.bench.trade.measure_trade",
                        lambda *a, **k: pytest.fail("measured before checking --plot"))
    assert main(["bench", "trade", str(src), "--plot", str(tmp_path / "p.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'csm-assets[plot]'" in err
    assert not (tmp_path / "p.png").exists()
