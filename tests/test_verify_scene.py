"""verify on converted scenes: curved meshes, mirrored uvs, two materials, in glTF, GLB, OBJ and
USD; a forged step map fails; unverifiable primitives; images and the contact sheet."""

from __future__ import annotations

import json

import numpy as np
import pytest
from attack import assert_clean_run, run_cli
from conftest import skip_without_gl
from curved_scenes import write_gltf, write_obj, write_usd, write_usdz

from csm_assets.convert.pipeline import convert
from csm_assets.formats import read_step_map, write_step_map
from csm_assets.verify.scene import verify_scene

VIEWS = ((90.0, 0.0), (35.0, 200.0), (10.0, 45.0))
WRITERS = {"gltf": write_gltf, "glb": lambda d: write_gltf(d, binary=True), "obj": write_obj, "usd": write_usd,
           "usdz": write_usdz}


@pytest.fixture(scope="module", autouse=True)
def needs_gl():
    skip_without_gl()


def converted(tmp_path, kind, **options):
    src = WRITERS[kind](tmp_path / "src")
    convert(src, tmp_path / "out", **options)
    return tmp_path / "out" / src.name


@pytest.mark.parametrize("kind,cones", [*((k, "conservative") for k in sorted(WRITERS)), ("gltf", "quadrant"),
                                        ("usdz", "quadrant")])  # quadrant: two images per map, its own variant
def test_curved_scenes_pass_in_every_format(tmp_path, kind, cones):
    variant = "quadrant" if cones == "quadrant" else "exact"
    out = converted(tmp_path, kind, bits=16, cones=cones, variant=variant)
    report = verify_scene(out, size=48, views=VIEWS)
    assert report.passed, report.to_dict()
    assert sorted(p.material for p in report.primitives) == ["ridges", "stones"]
    for p in report.primitives:
        assert p.dtype == "uint16" and not p.problem
        (v,) = p.variants
        assert v.variant == variant
        automatic = [s for s in v.views if not s.camera]
        assert len(automatic) == len(VIEWS) and all(s.pixels > 150 for s in automatic), v.views
        assert v.worst_p95 <= 1.0
    cameras = {s.camera for p in report.primitives for s in p.variants[0].views if s.camera}
    assert cameras == (set() if kind == "obj" else {"cam"})  # the scene's own camera (OBJ has none)
    seen = [s.pixels for p in report.primitives for s in p.variants[0].views if s.camera]
    assert all(n > 50 for n in seen), seen


def test_forged_step_map_with_wider_cones_fails(tmp_path):
    out = converted(tmp_path, "gltf", bits=16, depth=0.3)
    assert verify_scene(out, size=48, views=((60.0, 0.0), (20.0, 100.0))).passed  # deep, and right
    maps = sorted(out.parent.glob("*_csm.png"))
    assert len(maps) == 2
    for path in maps:
        packed = read_step_map(path)
        g = packed[..., 1].astype(np.float64) / 65535
        packed[..., 1] = np.round(np.minimum(g * 3.0, 1.0) * 65535).astype(np.uint16)  # cones 9x wider
        write_step_map(packed, path, {})
    r = run_cli("verify", out, "--size", "48", "--views", "60/0", "20/100", "--json")
    assert r.returncode == 1, r.stderr
    d = json.loads(r.stdout)
    assert not d["passed"] and all(not p["passed"] for p in d["primitives"])


def test_each_material_is_verified_with_its_own_variant_and_steps(tmp_path):
    out = converted(tmp_path, "obj", variant="loop", steps=8)
    report = verify_scene(out, size=32, views=VIEWS[:1])
    assert {(v.variant, v.steps) for p in report.primitives for v in p.variants} == {("loop", 8)}
    report = verify_scene(out, size=32, views=VIEWS[:1], variants=["relief"], steps=4)
    assert {(v.variant, v.steps) for p in report.primitives for v in p.variants} == {("relief", 4)}


def test_primitive_without_normals_is_reported_not_verifiable(tmp_path):
    out = converted(tmp_path, "obj")
    text = out.read_text().splitlines()
    out.write_text("\n".join(ln if not ln.startswith("f ") else
                             "f " + " ".join(c.rsplit("/", 1)[0] for c in ln.split()[1:]) for ln in text) + "\n")
    r = run_cli("verify", out, "--size", "32", "--views", "60/0")
    assert_clean_run(r, 1)
    assert r.stdout.count("NOT VERIFIABLE: no normals") == 2 and "FAIL" in r.stdout
    fix = r.stdout.strip().splitlines()[-1]  # what lacks, not "too deep" (it said so of meshes it never drew)
    assert "to fix:" in fix and "no normals" in fix and "too deep" not in fix, fix


def test_images_per_primitive_and_a_contact_sheet(tmp_path):
    from PIL import Image

    out = converted(tmp_path, "gltf")
    pics = tmp_path / "pics"
    r = run_cli("verify", out, "--size", "32", "--views", "60/0", "--images", pics, "--no-cameras")
    assert_clean_run(r, 0)
    names = {p.name for p in pics.iterdir()}
    assert {"sphere_0_exact_el60_az0_error.png", "cylinder_0_exact_el60_az0_error.png",
            "contact_sheet.png"} <= names, names
    assert len(names) == 2 * 5 + 1
    sheet = Image.open(pics / "contact_sheet.png")
    assert sheet.size[0] >= 2 * 32 and sheet.size[1] > 32


def test_scene_without_csm_material_is_a_clean_error(tmp_path):
    src = write_gltf(tmp_path / "src")
    r = run_cli("verify", src, "--size", "32")
    assert r.returncode == 3 and "convert the scene first" in r.stderr and "Traceback" not in r.stderr
