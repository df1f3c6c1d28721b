"""The default must pass its own proof: step maps get the bits their relief needs
(:mod:`csm_assets.verify.bits`, by :mod:`csm_assets.verify.march`'s foresight of verify), checked against real ``verify`` runs on maps where 8 bits
pass and where they fail, through the library and the CLI (stepmap, verify, convert)."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from attack import assert_clean_run, run_cli
from conftest import SAMPLES
from csm_assets.formats import read_step_map, read_step_map_meta
from csm_assets.formats.image import write_rgba
from csm_assets.stepmap import StepMapSettings, make_step_map
from csm_assets.verify.bits import BUDGET, chooser
from csm_assets.verify.hints import rounding_bound
from csm_assets.verify.march import march_exact, quad_error, view_rays
from csm_assets.verify.maps import verify_step_map
from csm_assets.verify.trace import trace_heightfield

DEPTH = 0.1  # verify's default depth: a 1024-texel side makes it 102 texels deep


def scratched(rows=64, cols=1024, seed=1) -> np.ndarray:
    """A scratched-metal height map (as cgbookcase's Scratched_gold): a flat top with 16-bit
    grain under one 8-bit level, cut by a few hundred straight scratches; uint16 ``(rows, cols)``."""
    rng = np.random.default_rng(seed)
    a = np.full((rows, cols), 0.8) + 0.05 * rng.random((rows, cols))
    for _ in range(rows * cols // 200):
        r, c = rng.integers(rows), rng.integers(cols)
        d = rng.normal(size=2)
        d /= np.hypot(*d)
        t = np.arange(rng.integers(5, 60))
        a[(r + t * d[0]).astype(int) % rows, (c + t * d[1]).astype(int) % cols] -= 0.3 * rng.random()
    a = (a - a.min()) / (a.max() - a.min())
    return np.rint(a * 65535).astype(np.uint16)


def rolling(rows=64, cols=1024, seed=2) -> np.ndarray:
    """Smooth rolling 16-bit relief (a terrain): steep enough everywhere that 8-bit rounding
    moves no hit far, however deep."""
    rng = np.random.default_rng(seed)
    f = np.zeros((rows, cols), complex)
    f[:4, :24] = rng.normal(size=(4, 24)) + 1j * rng.normal(size=(4, 24))
    a = np.real(np.fft.ifft2(f))
    a = (a - a.min()) / (a.max() - a.min())
    return np.rint(a * 65535).astype(np.uint16)


def save_grey(a: np.ndarray, path) -> None:
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(a.shape[1], a.shape[0], 1, a.dtype.name))
    out.write_image(np.ascontiguousarray(a[:, :, None]))
    out.close()


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    d = tmp_path_factory.mktemp("bits")
    for name, a in (("scratched", scratched()), ("rolling", rolling()),
                    ("scratched_8bit", (scratched() // 257).astype(np.uint8))):
        save_grey(a, d / f"{name}.png")
    return d


def made(heights, bits=None, **given):
    """The default step map of ``heights`` (bits chosen for verify's defaults unless given)."""
    log = []
    choose = chooser(DEPTH, log=log, **given) if bits is None else None
    return make_step_map(heights, StepMapSettings(bits=bits or 8), choose=choose), (log or [None])[0]


def verified(sm) -> float:
    """verify's worst p95 at its defaults for step map ``sm``."""
    return verify_step_map(sm.pixels, depth=DEPTH, min_step=sm.min_step).variants[0].worst_p95


def test_the_rule_against_verify_where_8_bits_fail_and_where_they_pass():
    sm, choice = made(scratched())
    assert choice.bits == sm.settings.bits == 16 and sm.pixels.dtype == np.uint16, choice
    assert choice.errors[8] - choice.errors[16] > 1.0 and "8-bit maps cost" in choice.reason
    assert not choice.warning
    assert verified(sm) <= 0.5
    eight, _ = made(scratched(), 8)
    assert verified(eight) > 1.0  # what the default used to write: verify FAILs it at its own views
    sm, choice = made(rolling())
    assert choice.bits == 8 and choice.errors[8] <= BUDGET and 16 not in choice.errors, choice
    assert verified(sm) <= 1.0  # 8 bits are enough: 16 would only double the file


def test_whole_8bit_codes_still_need_16_bits_for_deep_flat_relief():
    """R holds 8-bit codes exactly, yet verify's renderer rounds its bilinear samples to 8 bits:
    the terraces between texels are what fails, so the source's bits do not decide."""
    codes = (scratched() // 257).astype(np.uint8)
    sm, choice = made(codes)
    assert choice.bits == 16 and verified(sm) <= 0.5
    assert verified(made(codes, 8)[0]) > 1.0


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("heights", [scratched, rolling], ids=["scratched", "rolling"])
def test_the_foresight_tracks_verify(heights, bits):
    """quad_error marches verify's own rays on the CPU: 16-bit maps to a few hundredths of a
    texel of verify's p95, 8-bit ones (whose samples the renderer rounds) within 35%."""
    sm, _ = made(heights(), bits)
    want = verified(sm)
    got = quad_error(sm.pixels, DEPTH, min_step=sm.min_step)
    if bits == 16:
        assert got == pytest.approx(want, abs=0.03)
    else:
        assert got == pytest.approx(want, rel=0.35)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([10.0, 35.0, 70.0]), st.floats(0.0, 360.0),
       st.sampled_from([(8, 8), (16, 5), (3, 12)]))
def test_the_march_meets_the_exact_hit_on_float_maps(seed, elevation, azimuth, shape):
    """On a float map (no rounding) the march never stops short of the exact hit on the same
    bilinear surface by more than its backed-off minimum step; it stops past it only where it
    stepped over a sub-step feature (white noise at grazing views: the known limit), rarely."""
    rng = np.random.default_rng(seed)
    sm = make_step_map(rng.random(shape).astype(np.float32), StepMapSettings(bits=32))
    dp, ds = view_rays(elevation, azimuth, 0.2, 16)
    sc, status = march_exact(sm.pixels, dp, ds, min_step=sm.min_step)
    ref, t, hit = trace_heightfield(sm.pixels[..., 0], np.column_stack([dp, np.ones(len(dp))]), ds * [1, 1, -1])
    assert hit.all() and (status == 0).all()
    w = sm.min_step / max(shape)
    assert (sc >= t - w - 1e-9).all()
    assert (sc - t <= w + 1e-9).mean() >= 0.75


def test_given_bits_are_kept_with_a_warning():
    sm, choice = made(scratched(), given=8)
    assert sm.settings.bits == choice.bits == 8 and choice.given and "--bits 16" in choice.warning
    assert not made(rolling(), given=8)[1].warning
    _, choice = made(scratched(), allowed=(8,))  # a TGA: the only bits it holds, verify may fail
    assert choice.bits == 8 and "only bits" in choice.reason and choice.warning
    assert rounding_bound(8, DEPTH * 1024, 10.0) == pytest.approx(0.5 / 255 * 102.4 / math.tan(math.radians(10)))


def test_stepmap_and_verify_cli_defaults_pass_and_a_fail_line_says_the_fix(maps, tmp_path):
    src = maps / "scratched.png"
    r = run_cli("stepmap", src, "-o", tmp_path / "s.png", "--json")
    assert_clean_run(r)
    out = json.loads(r.stdout)
    assert out["bits"]["bits"] == out["settings"]["bits"] == 16 and "8-bit maps cost" in out["bits"]["reason"]
    assert read_step_map(tmp_path / "s.png").dtype == np.uint16
    assert_clean_run(run_cli("verify", tmp_path / "s.png"))  # the default passes its own proof
    r = run_cli("stepmap", src, "-o", tmp_path / "s8.png", "--bits", "8")
    (warning,) = assert_clean_run(r)
    assert "s8.png" in warning and "--bits 16" in warning
    r = run_cli("verify", tmp_path / "s8.png")
    assert r.returncode == 1
    fail = r.stdout.strip().splitlines()[-1]
    assert fail.startswith("FAIL") and "to fix: make the step map again at 16 bits" in fail
    # verify of the height map itself chooses the same way, and says so in --json
    r = run_cli("verify", src, "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["bits"]["bits"] == 16
    r = run_cli("verify", src, "--bits", "8")
    assert r.returncode == 1 and "--bits 16, or leave --bits out" in r.stdout
    # 8 bits where 8 bits are enough
    for name, bits in (("rolling", 8), ("scratched_8bit", 16)):  # 8-bit sources too: the renderer's terraces
        r = run_cli("stepmap", maps / f"{name}.png", "-o", tmp_path / f"{name}.png", "--json")
        assert json.loads(r.stdout)["bits"]["bits"] == bits, r.stdout
        assert_clean_run(run_cli("verify", tmp_path / f"{name}.png"))


def test_a_tga_holds_8_bits_only_and_an_exr_floats(maps, tmp_path):
    r = run_cli("stepmap", maps / "scratched.png", "-o", tmp_path / "s.tga", "--json")
    (warning,) = assert_clean_run(r)
    assert json.loads(r.stdout)["bits"]["bits"] == 8 and "verify may fail" in warning
    r = run_cli("stepmap", maps / "scratched.png", "-o", tmp_path / "s.exr", "--json")
    assert json.loads(r.stdout)["bits"]["bits"] == 32 and not assert_clean_run(r)


def test_convert_chooses_per_map_by_the_materials_depth_and_reports_why(maps, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(SAMPLES, scene, ignore=shutil.ignore_patterns("*.py", "*.obj", "*.mtl", "*.usda", "*.glb"))
    shutil.copy(maps / "scratched.png", scene / "scratched.png")
    out = tmp_path / "out"
    r = run_cli("convert", scene / "brick_wall.gltf", "-o", out, "--height", f"bricks={scene / 'scratched.png'}", "--depth",
                str(DEPTH), "--json")
    assert not assert_clean_run(r)
    pick = json.loads(r.stdout)["results"][0]["picks"]["bricks"]
    assert pick["bits"] == 16 and "8-bit maps cost" in pick["bits_reason"]
    assert read_step_map_meta(out / "scratched_csm.png")["bits"] == 16
    assert_clean_run(run_cli("verify", out / "brick_wall.gltf"))
    r = run_cli("convert", scene / "brick_wall.gltf", "-o", tmp_path / "out8", "--height", f"bricks={scene / 'scratched.png'}",
                "--depth", str(DEPTH), "--bits", "8")
    (warning,) = assert_clean_run(r)
    assert "'bricks'" in warning and "--bits 16" in warning
    r = run_cli("verify", tmp_path / "out8" / "brick_wall.gltf")
    assert r.returncode == 1 and "to fix: convert again with --bits 16" in r.stdout
    # the sample's own 8-bit bricks at its own depth: 8 bits, nothing said
    r = run_cli("convert", scene / "brick_wall.gltf", "-o", tmp_path / "plain")
    assert r.stdout.count("-bit step map") == 0 and not assert_clean_run(r)
    assert read_step_map(tmp_path / "plain" / "bricks_height_csm.png").dtype == np.uint8


@pytest.mark.slow
@pytest.mark.parametrize("name, invert", [("bricks2_disp.jpg", True), ("toy_box_disp.png", True)])
def test_shared_data_default_outputs_pass_verify(name, invert, shared_data, tmp_path):
    src = shared_data / name
    if not src.is_file():
        pytest.skip(f"{src} is absent")
    r = run_cli("stepmap", src, "-o", tmp_path / "s.png", "--invert", "--json")
    assert_clean_run(r)
    r = run_cli("verify", tmp_path / "s.png", "--json")
    assert r.returncode == 0, r.stdout[-2000:]


def test_a_16bit_map_that_fails_is_not_told_to_take_more_bits(tmp_path):
    sm = make_step_map(scratched(64, 256), StepMapSettings(bits=16))
    write_rgba(sm.pixels, tmp_path / "deep.png", json.dumps({"csm": sm.settings.to_meta()}))
    r = run_cli("verify", tmp_path / "deep.png", "--depth", "0.4")
    assert r.returncode == 1 and "--bits" not in r.stdout and "a smaller --depth" in r.stdout


def test_where_no_bit_depth_passes_verify_says_what_stepmap_says(tmp_path):
    """Random 16-bit heights on 256 texels at verify's depth: stepmap warns CSM304 (no bit depth
    keeps the budget) and keeps 8 bits; verify's fix line then says the same, not "16 bits"."""
    from csm_assets.formats.image import write
    from csm_assets.heightfield import Heightfield

    src = tmp_path / "rough.png"
    write(Heightfield(np.random.default_rng(1).random((256, 256))), src)  # a grey 16-bit PNG
    r = run_cli("stepmap", src, "-o", tmp_path / "rough_csm.png")
    (warning,) = assert_clean_run(r)
    assert "CSM304" in warning and "no bit depth keeps" in warning
    for args in ((tmp_path / "rough_csm.png",), (src, "--bits", "8"), (src,)):
        r = run_cli("verify", *args)
        fail = r.stdout.strip().splitlines()[-1]
        assert r.returncode == 1 and fail.startswith("FAIL"), r.stdout
        assert "no bit depth keeps" in fail and "(CSM304)" in fail and "16 bits" not in fail and "--bits" not in fail
    scene = tmp_path / "scene"
    shutil.copytree(SAMPLES, scene, ignore=shutil.ignore_patterns("*.py", "*.obj", "*.mtl", "*.usda", "*.glb"))
    r = run_cli("convert", scene / "brick_wall.gltf", "-o", tmp_path / "out", "--height", f"bricks={src}",
                "--depth", str(DEPTH))
    assert any("CSM304" in w for w in assert_clean_run(r))
    r = run_cli("verify", tmp_path / "out" / "brick_wall.gltf")
    assert r.returncode == 1 and "(CSM304)" in r.stdout and "--bits 16" not in r.stdout, r.stdout
