"""Step maps of relaxed cones: the library, the stored setting, the CLI, the relaxed variant."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from attack import assert_clean_error, assert_clean_run, run_cli
from csm_assets import cone_ratios, read_step_map, read_step_map_meta, step_map, unpack_step_map
from csm_assets.cones.relaxed import relaxed_exact


def field(n=24, seed=3):
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(seed).random((n, n)), 1.5, mode="wrap")
    return (h - h.min()) / (h.max() - h.min())


@pytest.mark.parametrize("bits", [8, 16, 32])
def test_relaxed_map_holds_relaxed_cones_never_wider(bits):
    h = field()
    got = unpack_step_map(step_map(h, bits=bits, cones="relaxed"))["ratio"]
    cons = unpack_step_map(step_map(h, bits=bits))["ratio"]
    exact = relaxed_exact(h, True, True, 1.0)  # float64, before float32 rounding
    assert (got <= exact).all()
    assert (got >= cons).all() and (got > cons).any()
    if bits == 32:
        np.testing.assert_allclose(got, exact, rtol=1e-6)


def test_conservative_is_the_default_and_other_kinds_raise():
    h = field(8)
    np.testing.assert_array_equal(step_map(h), step_map(h, cones="conservative"))
    np.testing.assert_allclose(unpack_step_map(step_map(h, bits=32))["ratio"], cone_ratios(h), rtol=1e-6)
    with pytest.raises(ValueError, match="cones"):
        step_map(h, cones="loose")


def test_stepmap_cli_writes_and_records_the_cones(tmp_path):
    d = (field() * 255).astype(np.uint8)
    Image.fromarray(d).save(tmp_path / "h.png")
    assert_clean_run(run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "r.png", "--cones", "relaxed"))
    np.testing.assert_array_equal(read_step_map(tmp_path / "r.png"), step_map(d, cones="relaxed", bilinear_safe=True))  # the CLI default
    assert read_step_map_meta(tmp_path / "r.png")["cones"] == "relaxed"
    assert_clean_run(run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "c.png"))
    assert read_step_map_meta(tmp_path / "c.png")["cones"] == "conservative"
    assert_clean_error(run_cli("stepmap", tmp_path / "h.png", "-o", tmp_path / "x.png", "--cones", "loose"), 2)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("kind", ["smooth", "noise", "spikes"])
def test_relaxed_variant_on_relaxed_map_agrees_with_the_exact_tracer(kind):
    """p95 within a texel at every view down to 10 degrees (bilinear-safe map, 0.25 texel)."""
    from conftest import skip_without_gl

    from csm_assets.packing import SAFE_MIN_STEP
    from csm_assets.bench.trade import measure_trade

    skip_without_gl()
    rng = np.random.default_rng(9)
    h = {"smooth": field(48), "noise": rng.random((48, 48))}.get(kind)
    if h is None:
        h = np.zeros((48, 48))
        h[rng.integers(0, 48, 12), rng.integers(0, 48, 12)] = 1.0
    packed = step_map(h, bits=8, bilinear_safe=True, cones="relaxed")
    views = ((90.0, 0.0), (35.0, 200.0), (10.0, 45.0))
    rep = measure_trade(packed, configs=[("relaxed", 4)], views=views, size=40, draws=1,
                        min_step=SAFE_MIN_STEP)
    row = rep.rows[0]
    assert all(v.p95_error <= 1.0 for v in row.views), [v.p95_error for v in row.views]
    assert row.nonconverged_share == 0.0
