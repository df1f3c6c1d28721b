"""Height sources that are not heights: the normal-map / photo detector and its confusion table.

The table runs on maps the project makes from heightfields (tangent-space normals by
finite differences, in 8 and 16 bit, linear and sRGB-encoded, OpenGL and DirectX green,
two-channel BC5-style as grey+alpha, as RGB with B constant and as signed float EXR),
grey height and depth maps, procedural colour images, and the real depth maps and
photographs of ../shared/data when present. docs/measurements/real-assets.md gives the table measured on a
real third-party set.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from csm_assets.formats import image
from csm_assets.height_source import NORMAL_NAME, classify, classify_pixels, srgb_to_linear
from csm_assets.scene import Texture

from conftest import random_field


def _heights(seed: int, n: int = 96) -> np.ndarray:
    """A relief with bricks-like steps and smooth noise, in [0, 1]."""
    h = random_field(n, seed, smooth=3.0).astype(np.float64)
    r, c = np.indices((n, n))
    h = 0.6 * h + 0.4 * (((r // 12) + (c // 24)) % 2)
    return (h - h.min()) / np.ptp(h)


def normals_of(h: np.ndarray, strength: float = 8.0, green: str = "gl") -> np.ndarray:
    """Unit tangent-space normals ``(H, W, 3)`` of heights by central differences (wrapped);
    OpenGL green points up the image (toward row 0), DirectX green down."""
    dx = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / 2 * strength
    dy = (np.roll(h, 1, 0) - np.roll(h, -1, 0)) / 2 * strength  # up the image
    n = np.stack([-dx, -dy if green == "gl" else dy, np.ones_like(h)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.clip(c, 0, None) ** (1 / 2.4) - 0.055)


def _quantize(c: np.ndarray, bits: int) -> np.ndarray:
    top = 255 if bits == 8 else 65535
    return np.rint(np.clip(c, 0, 1) * top).astype(np.uint8 if bits == 8 else np.uint16)


def made_maps(tmp_path):
    """(true kind, file) pairs the project writes for the table."""
    cases = []

    def save(name, pixels, kind):
        path = tmp_path / name
        image._write_pixels(pixels if pixels.ndim == 3 else pixels[..., None], path)
        cases.append((kind, path))

    for seed in range(3):
        h = _heights(seed)
        for green in ("gl", "dx"):
            enc = (normals_of(h, 4.0 + 4 * seed, green) + 1) / 2
            save(f"s{seed}_{green}_8.png", _quantize(enc, 8), "normal")
            save(f"s{seed}_{green}_16.png", _quantize(enc, 16), "normal")
            save(f"s{seed}_{green}_srgb.png", _quantize(linear_to_srgb(enc), 8), "normal")
            save(f"s{seed}_{green}.jpg", _quantize(enc, 8), "normal")
            rg = _quantize(enc[..., :2], 8)
            save(f"s{seed}_{green}_la.png", rg, "normal")  # two channels: PNG grey + alpha
            save(f"s{seed}_{green}_b0.png", np.dstack([rg, np.zeros_like(rg[..., 0])]), "normal")
            save(f"s{seed}_{green}_b1.tga", np.dstack([rg, np.full_like(rg[..., 0], 255)]), "normal")
            save(f"s{seed}_{green}_signed.exr", normals_of(h, 6.0, green).astype(np.float32), "normal")
        save(f"h{seed}_8.png", _quantize(h, 8), "height")
        save(f"h{seed}_16.png", _quantize(h, 16), "height")
        save(f"d{seed}_depth.png", _quantize(1 - h, 8), "height")
        save(f"h{seed}_rgb.jpg", _quantize(np.dstack([h, h, h]), 8), "height")
        save(f"h{seed}_alpha.png", np.dstack([_quantize(h, 8), np.full(h.shape, 255, np.uint8)]), "height")
        save(f"h{seed}.exr", (h * 3 - 1).astype(np.float32), "height")
        rgb = np.dstack([_heights(seed + 10), _heights(seed + 20), _heights(seed + 30)])
        save(f"p{seed}_colour.png", _quantize(rgb, 8), "photo")
        save(f"p{seed}_warm.jpg", _quantize(np.dstack([0.3 + 0.7 * h, 0.2 + 0.4 * rgb[..., 1], 0.1 * rgb[..., 2]]),
                                            8), "photo")
    return cases


def confusion(cases) -> dict[tuple[str, str], int]:
    return dict(Counter((kind, classify(Texture(p.stem, path=p)).kind) for kind, p in cases))


def test_confusion_table_on_maps_the_project_makes(tmp_path):
    table = confusion(made_maps(tmp_path))
    # 3 reliefs x 2 green conventions x 8 encodings; 6 height forms and 2 colour images per relief
    assert table == {("normal", "normal"): 48, ("height", "height"): 18, ("photo", "photo"): 6}


def test_real_depth_maps_and_photos_of_shared_data(shared_data):
    cases = [("height", shared_data / "bricks2_disp.jpg"), ("height", shared_data / "toy_box_disp.png"),
             ("photo", shared_data / "bricks2.jpg"), ("photo", shared_data / "toy_box_diffuse.png")]
    assert confusion(cases) == {("height", "height"): 2, ("photo", "photo"): 2}


def test_normal_maps_made_from_the_real_depth_maps(shared_data, tmp_path):
    """The real reliefs' own normal maps, in every encoding, are all recognised."""
    cases = []
    for name in ("bricks2_disp.jpg", "toy_box_disp.png"):
        d = image.read_unit_pixels(shared_data / name)[0][::4, ::4, 0]
        enc = (normals_of(1 - d, 6.0) + 1) / 2
        for suffix, pixels in (("8.png", _quantize(enc, 8)), ("srgb.png", _quantize(linear_to_srgb(enc), 8)),
                               ("la.png", _quantize(enc[..., :2], 8))):
            path = tmp_path / f"{name}_{suffix}"
            image._write_pixels(pixels, path)
            cases.append(("normal", path))
    assert confusion(cases) == {("normal", "normal"): 6}


def test_flat_normal_map_and_constant_height():
    flat = np.tile([0.5, 0.5, 1.0], (8, 8, 1))
    assert classify_pixels(flat).kind == "normal"
    assert classify_pixels(np.full((8, 8, 3), 0.79)).kind == "height"  # grey that would be unit length
    assert classify_pixels(np.full((8, 8, 1), 0.5)).kind == "height"


def test_srgb_encoded_map_is_read_as_srgb():
    enc = (normals_of(_heights(4), 10.0) + 1) / 2
    v = classify_pixels(linear_to_srgb(enc))
    assert v.kind == "normal" and "sRGB" in v.reason
    assert np.allclose(srgb_to_linear(linear_to_srgb(enc)), enc, atol=1e-9)


def test_name_decides_only_where_the_content_is_unclear():
    # a painted, un-normalised map (like nanosuit's glass_ddn): vectors ~0.85 long, off centre
    h = _heights(5)
    n = normals_of(h, 3.0) * 0.85 + [0.2, 0.0, 0.0]
    painted = (n + 1) / 2
    assert classify_pixels((normals_of(h, 3.0) * 0.85 + 1) / 2, "glass").kind == "normal"  # centred: filtered
    assert classify_pixels(painted, "glass").kind != "normal"
    assert classify_pixels(painted, "glass_ddn").kind == "normal"
    grey = np.dstack([h, h, h])
    assert classify_pixels(grey, "wall_normal").kind == "height"  # grey is never a normal map
    flat_rg = np.full((8, 8, 2), 0.5)  # a flat two-channel map is grey + alpha: only its name tells
    assert classify_pixels(flat_rg, "gold").kind == "height"
    assert classify_pixels(flat_rg, "gold_normal").kind == "normal"


@pytest.mark.parametrize("name, hit", [
    ("bricks_normal", True), ("arm_showroom_ddn", True), ("Cerberus_N", True), ("wood_nrm", True),
    ("rock_norm", True), ("BlueNoise-Normal", True), ("water_normals", True), ("normal", True),
    ("tile_nm", True), ("bricks_height", False), ("brick_n_color", False), ("bricks2_disp", False),
    ("green", False), ("terrain", False)])
def test_normal_names(name, hit):
    assert bool(NORMAL_NAME.search(name)) is hit


@pytest.mark.parametrize("scene_file, names", [
    ("brick_wall.gltf", ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png")),
    ("brick_wall.usda", ("brick_wall.usda", "bricks_color.png", "bricks_height.png")),
    ("brick_wall.obj", ("brick_wall.obj", "brick_wall.mtl", "bricks_color.png", "bricks_height.png",
                        "bricks_normal.png")),
])
def test_command_line_height_keeps_the_factor_the_scene_states(tmp_path, scene_file, names):
    """Every reader goes through height_source.override: a --height texture for a material
    whose scene states a displacement factor gets that factor's depth, not the default
    (test_attack_obj: one that states none gets DEFAULT_DEPTH); --depth MATERIAL=D beats both."""
    from csm_assets.convert.pipeline import DEFAULT_DEPTH, convert
    from csm_assets.height_source import HeightSpec

    from conftest import copy_samples

    wall = copy_samples(tmp_path / "in", names)
    own = convert(wall / scene_file, tmp_path / "a")
    scene_depth = own.step_maps and _depth_of(tmp_path / "a", scene_file)
    assert scene_depth != pytest.approx(DEFAULT_DEPTH)
    convert(wall / scene_file, tmp_path / "b", heights={"bricks": HeightSpec(wall / "bricks_height.png")})
    assert _depth_of(tmp_path / "b", scene_file) == pytest.approx(scene_depth)
    convert(wall / scene_file, tmp_path / "c", heights={"bricks": HeightSpec(wall / "bricks_height.png", True)},
            depths={"bricks": 0.07})
    assert _depth_of(tmp_path / "c", scene_file) == pytest.approx(0.07)


def _depth_of(out, scene_file) -> float:
    """The depth the converted material carries, whatever the format."""
    import json
    import re

    if scene_file.endswith(".gltf"):
        doc = json.loads((out / scene_file).read_text())
        return doc["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["depthScale"]
    if scene_file.endswith(".obj"):
        return float(re.search(r"csm_depth (\S+)", (out / "brick_wall.mtl").read_text()).group(1))
    return float(re.search(r"float inputs:depthScale = (\S+)", (out / scene_file).read_text()).group(1))


def test_confusion_table_on_real_normal_maps_and_matcaps_from_npm():
    """@pmndrs/assets' 29 CC0 normal maps (lossy WebP, resized: many vectors shorter than 1)
    in four more encodings each, and its 284 matcaps (colour renders of spheres, one of
    them the normals of a sphere: a normal map by content)."""
    from pmndrs import images

    table = Counter()
    for name, px in images("normals"):
        n = px * 2 - 1
        flip = n * [1, -1, 1]
        for form, pixels in (("as shipped", px), ("green flipped", (flip + 1) / 2),
                             ("two-channel", px[..., :2]), ("B constant", np.dstack([px[..., :2], np.ones(px.shape[:2])])),
                             ("sRGB-encoded", linear_to_srgb(px))):
            table["normal", form, classify_pixels(np.rint(pixels * 255) / 255, name).kind] += 1
    for name, px in images("matcaps"):
        table["matcap", classify_pixels(px, name).kind] += 1
    assert dict(table) == {**{("normal", form, "normal"): 29 for form in (
        "as shipped", "green flipped", "two-channel", "B constant", "sRGB-encoded")},
        ("matcap", "photo"): 215, ("matcap", "height"): 68, ("matcap", "normal"): 1}


@pytest.mark.parametrize("scene_file, names", [
    ("brick_wall.gltf", ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_normal.png")),
    ("brick_wall.usda", ("brick_wall.usda", "bricks_color.png", "bricks_normal.png")),
])
def test_normal_map_in_a_gltf_or_usd_height_slot_is_skipped_with_a_warning(tmp_path, scene_file, names):
    from attack import Attack, assert_clean_run, run_cli
    from conftest import copy_samples

    wall = copy_samples(tmp_path / "in", names)
    scene = wall / scene_file
    scene.write_text(scene.read_text().replace("bricks_height.png", "bricks_normal.png"))
    with Attack(wall):
        r = run_cli("convert", scene, "-o", tmp_path / "out")
    warnings = assert_clean_run(r)
    assert any("'bricks'" in w and "bricks_normal.png is a tangent-space normal map" in w for w in warnings), warnings
    text = (tmp_path / "out" / scene_file).read_text()
    assert "EXT_materials_cone_step_mapping" not in text and "CsmConeStepSurface" not in text
    assert not list((tmp_path / "out").glob("*_csm.png"))


def test_colour_image_in_a_gltf_height_slot_warns_naming_the_channel_read(tmp_path):
    from attack import Attack, assert_clean_run, run_cli
    from conftest import copy_samples

    wall = copy_samples(tmp_path / "in", ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png"))
    scene = wall / "brick_wall.gltf"
    scene.write_text(scene.read_text().replace("bricks_height.png", "bricks_color.png"))
    with Attack(wall):
        r = run_cli("convert", scene, "-o", tmp_path / "out")
    warnings = assert_clean_run(r)
    assert any("bricks_color.png is a colour image" in w and "its channel 0 is used" in w for w in warnings)
