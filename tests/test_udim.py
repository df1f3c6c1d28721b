"""UDIM height sets: a step map per tile, each tile's cones exact within its own uv square
(clamped at its borders, as the single map of that tile made alone), written as a UDIM set and
named by a ``<UDIM>`` asset path; verify draws each tile; glTF and OBJ refuse a set; a tile
changed, added or removed makes the outputs stale."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import SHARED_DATA, copy_samples
from csm_assets.convert import manifest
from csm_assets.convert.pipeline import convert
from csm_assets.errors import OptionError
from csm_assets.formats import image, load_heightfield, read_step_map
from csm_assets.stepmap import StepMapSettings, make_step_map
from csm_assets.udim import corner, face_tiles, tile_files

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
TILES = (1001, 1002, 1011)
QUADS = {1001: (0.0, 0.0), 1002: (1.2, 0.0), 1011: (0.0, 1.2)}  # tile -> where its quad lies in the scene


def _source() -> np.ndarray:
    """Real heights to cut tiles from: the LearnOpenGL bricks' displacement (../shared/data), else the
    project's own cobbles sample (a fresh clone has no shared data)."""
    real = SHARED_DATA / "bricks2_disp.jpg"
    pixels, _ = image.read_pixels(real if real.is_file() else SAMPLES / "cobbles.png")
    return pixels[..., :1]


def _write(pixels: np.ndarray, path: Path) -> Path:
    image._write_pixels(np.ascontiguousarray(pixels), path)
    return path


def cut_tiles(folder: Path, tiles=TILES, name="h") -> dict[int, Path]:
    """Tiles ``name.<tile>.png`` cut from real heights: quadrants of the source image (the last one
    non-square, 3/4 as tall), 8 or 16 bits as the source is."""
    src = _source()
    h, w = src.shape[0] // 2, src.shape[1] // 2
    cuts = [src[:h, :w], src[:h, w:], src[h:, :w][: 3 * h // 4]]
    folder.mkdir(parents=True, exist_ok=True)
    return {t: _write(c, folder / f"{name}.{t}.png") for t, c in zip(tiles, cuts)}


def udim_stage(path: Path, file: str = "./h.<UDIM>.png", tiles=TILES) -> Path:
    """A USD scene of one mesh: a quad per tile, side by side, its uvs in that tile's square; a
    UsdPreviewSurface whose displacement reads ``file`` (a UDIM set)."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetDefaultPrim(stage.DefinePrim("/World", "Xform"))
    mesh = UsdGeom.Mesh.Define(stage, "/World/tiles")
    points, st = [], []
    for t in tiles:
        (x, y), (u, v) = QUADS.get(t, (2.4, 2.4)), corner(t)
        points += [(x, y, 0), (x + 1, y, 0), (x + 1, y + 1, 0), (x, y + 1, 0)]
        st += [(u, v), (u + 1, v), (u + 1, v + 1), (u, v + 1)]
    mesh.CreatePointsAttr(points)
    mesh.CreateFaceVertexCountsAttr([4] * len(tiles))
    mesh.CreateFaceVertexIndicesAttr(list(range(4 * len(tiles))))
    mesh.CreateNormalsAttr([(0, 0, 1)] * len(points))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                            UsdGeom.Tokens.vertex).Set(st)
    material = UsdShade.Material.Define(stage, "/World/Looks/rock")
    reader = UsdShade.Shader.Define(stage, "/World/Looks/rock/stReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex = UsdShade.Shader.Define(stage, "/World/Looks/rock/heightTex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((0.03, 0.03, 0.03, 1))
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    tex.CreateOutput("r", Sdf.ValueTypeNames.Float)
    surface = UsdShade.Shader.Define(stage, "/World/Looks/rock/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(tex.ConnectableAPI(), "r")
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()
    return path


@pytest.fixture
def scene(tmp_path):
    folder = tmp_path / "in"
    cut_tiles(folder)
    return udim_stage(folder / "tiles.usda")


def single_map(tile_file: Path, bits: int) -> np.ndarray:
    """The step map of one tile made alone, clamped at its borders (as ``stepmap --no-tile``)."""
    return make_step_map(load_heightfield(tile_file), StepMapSettings(tile=(False, False), bits=bits)).pixels


def assert_tiles_exact(out: Path, tiles: dict[int, Path], stem="h_csm"):
    for t, src in tiles.items():
        stored = read_step_map(out / f"{stem}.{t}.png")
        bits = 16 if stored.dtype == np.uint16 else 8
        np.testing.assert_array_equal(stored, single_map(src, bits), err_msg=f"tile {t}")


def test_a_usd_udim_height_set_gets_a_step_map_per_tile_each_exact_within_its_tile(scene, tmp_path):
    out = tmp_path / "out"
    report = convert(scene, out)
    assert report.warnings == []
    assert sorted(report.step_maps) == [f"h_csm.{t}" for t in TILES]
    assert_tiles_exact(out, tile_files(scene.parent / "h.<UDIM>.png"))
    stage = Usd.Stage.Open(str(out / scene.name))
    shader = stage.GetPrimAtPath("/World/Looks/rock/CsmSurface")
    assert shader.GetAttribute("inputs:stepMap").Get().path == "./h_csm.<UDIM>.png"
    assert (shader.GetAttribute("inputs:tileU").Get(), shader.GetAttribute("inputs:tileV").Get()) == (0, 0)
    # no level chain for a set, whatever --levels says (docs/reference/levels.md): none written, none named
    assert not shader.GetAttribute("inputs:stepMapLevels") and not list(out.glob("*_levels*"))


def test_the_single_map_of_a_tile_differs_when_wrapped(scene):
    """The test above can fail: a tile's clamped map is not its wrapped one."""
    src = scene.parent / "h.1001.png"
    wrapped = make_step_map(load_heightfield(src), StepMapSettings(tile=(True, True), bits=8)).pixels
    assert not np.array_equal(wrapped, single_map(src, 8))


def test_tile_says_the_set_repeats(scene, tmp_path):
    convert(scene, tmp_path / "out", tile=True)
    for t, src in tile_files(scene.parent / "h.<UDIM>.png").items():
        stored = read_step_map(tmp_path / "out" / f"h_csm.{t}.png")
        bits = 16 if stored.dtype == np.uint16 else 8
        want = make_step_map(load_heightfield(src), StepMapSettings(tile=(True, True), bits=bits)).pixels
        np.testing.assert_array_equal(stored, want)


def test_verify_draws_each_tile_and_passes(scene, tmp_path):
    from csm_assets.verify.scene import verify_scene

    convert(scene, tmp_path / "out")
    report = verify_scene(tmp_path / "out" / scene.name, views=((60, 0), (45, 90)), cameras=False)
    assert [p.name for p in report.primitives] == [f"/World/tiles [{t}]" for t in TILES]
    assert [p.shape for p in report.primitives] == [read_step_map(tmp_path / "out" / f"h_csm.{t}.png").shape[:2]
                                                    for t in TILES]
    assert report.passed, [(p.name, p.problem, p.worst_p95) for p in report.primitives]


def test_height_option_names_a_udim_set_on_a_usd_scene(tmp_path):
    folder = copy_samples(tmp_path / "in", ("brick_wall.usda", "bricks_color.png", "bricks_height.png"))
    tiles = cut_tiles(folder / "rock", tiles=(1001, 1002, 1011), name="rock")
    r = run_cli("convert", folder / "brick_wall.usda", "-o", tmp_path / "out", "--height",
                f"bricks={folder / 'rock' / 'rock.<UDIM>.png'}")
    warnings = assert_clean_run(r)
    assert_tiles_exact(tmp_path / "out", {t: f for t, f in tiles.items() if t in (1001, 1002, 1011)}, "rock_csm")
    # the wall's uvs span tiles 1001 and 1002 only: tile 1011's map is made, none of its faces lack a tile
    assert not any("CSM108" in w for w in warnings), warnings
    stage = Usd.Stage.Open(str(tmp_path / "out" / "brick_wall.usda"))
    assert stage.GetAttributeAtPath("/World/Looks/bricks/CsmSurface.inputs:stepMap").Get().path == \
        "./rock_csm.<UDIM>.png"
    r = run_cli("verify", tmp_path / "out" / "brick_wall.usda")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "/World/wall [1001]" in r.stdout and "/World/wall [1002]" in r.stdout and "PASS" in r.stdout


@pytest.mark.parametrize("scene_name", ["brick_wall.gltf", "brick_wall.obj"])
def test_gltf_and_obj_refuse_a_udim_set(tmp_path, scene_name):
    names = {"brick_wall.gltf": ("brick_wall.gltf", "brick_wall.bin"), "brick_wall.obj": ("brick_wall.obj",
                                                                                          "brick_wall.mtl")}
    folder = copy_samples(tmp_path / "in", (*names[scene_name], "bricks_color.png", "bricks_height.png"))
    cut_tiles(folder)
    r = run_cli("convert", folder / scene_name, "-o", tmp_path / "out", "--height", f"bricks={folder / 'h.<UDIM>.png'}")
    line = assert_clean_error(r, 2, scene_name)
    assert "--height bricks=" in line and "UDIM" in line and "name one tile" in line
    assert not (tmp_path / "out").exists()
    with pytest.raises(OptionError, match="no UDIM textures"):
        convert(folder / scene_name, tmp_path / "lib", heights={"bricks": folder / "h.<UDIM>.png"})


def test_a_height_option_naming_a_set_without_tiles_is_refused(tmp_path):
    folder = copy_samples(tmp_path / "in", ("brick_wall.usda", "bricks_color.png", "bricks_height.png"))
    r = run_cli("convert", folder / "brick_wall.usda", "-o", tmp_path / "out", "--height",
                f"bricks={folder / 'gone.<UDIM>.png'}")
    line = assert_clean_error(r, 3, "gone.<UDIM>.png")
    assert "no tile" in line and "--height" in line


def test_a_missing_tile_is_a_warning_and_verify_reports_its_faces(tmp_path):
    folder = tmp_path / "in"
    cut_tiles(folder, tiles=(1001, 1002))  # the mesh has a quad in tile 1011 too
    scene = udim_stage(folder / "tiles.usda")
    report = convert(scene, tmp_path / "out")
    (w,) = report.warnings
    assert w.code == "CSM108" and "2 of 6 triangle(s) lie in UDIM tile(s) the set lacks (1011)" in str(w)
    from csm_assets.verify.scene import verify_scene

    r = verify_scene(tmp_path / "out" / scene.name, views=((60, 0),), cameras=False)
    by_name = {p.name: p for p in r.primitives}
    assert "UDIM tile 1011, which has no step map" in by_name["/World/tiles [1011]"].problem
    assert by_name["/World/tiles [1001]"].passed(r.max_error) and not r.passed


def test_tiles_of_mixed_bit_depths_share_the_bits_the_set_needs(tmp_path):
    """A 16-bit tile beside 8-bit ones: each tile's heights are read in [0, 1] by its own depth; the
    set's maps share one bit depth, each tile still equal to its own map made alone at those bits."""
    folder = tmp_path / "in"
    tiles = cut_tiles(folder)
    deep = image.read_pixels(tiles[1002])[0].astype(np.uint16) * 257  # the same heights, 16-bit
    _write(deep if deep.ndim == 3 else deep[..., None], tiles[1002])
    scene = udim_stage(folder / "tiles.usda")
    out = tmp_path / "out"
    convert(scene, out, bits=16)
    assert {read_step_map(out / f"h_csm.{t}.png").dtype for t in TILES} == {np.dtype(np.uint16)}
    assert_tiles_exact(out, tiles)


def test_a_tile_changed_added_or_removed_makes_the_scene_stale(scene, tmp_path):
    out = tmp_path / "out"
    convert(scene, out)
    assert manifest.staleness(scene, out, {**_settings(scene)}) is None
    tile = scene.parent / "h.1002.png"
    data = tile.read_bytes()
    pixels = image.read_pixels(tile)[0].copy()
    pixels[0, 0] = 255 - pixels[0, 0]
    _write(pixels, tile)
    assert "h.1002.png changed" in manifest.staleness(scene, out, _settings(scene))
    tile.write_bytes(data)
    assert manifest.staleness(scene, out, _settings(scene)) is None
    shutil.copy(tile, scene.parent / "h.1012.png")
    assert "UDIM set h.<UDIM>.png changed (tiles 1001,1002,1011,1012" in manifest.staleness(scene, out,
                                                                                           _settings(scene))
    report = convert(scene, out)
    assert "h_csm.1012" in report.step_maps
    (scene.parent / "h.1012.png").unlink()
    assert "1012" in manifest.staleness(scene, out, _settings(scene))


def _settings(scene):
    from csm_assets.convert.options import ConvertOptions
    from csm_assets.convert.pipeline import scene_root

    opts = ConvertOptions()
    return opts.settings(scene_root(scene, opts))


def test_face_tiles_follow_the_standard_numbering():
    from csm_assets.scene import Mesh

    uvs = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [9.5, 0.5], [3.5, 2.5], [-0.5, 0.5]])
    mesh = Mesh("m", np.zeros((6, 3)), np.repeat(np.arange(6), 3).reshape(6, 3), uvs=uvs, uv_origin="bottom-left")
    assert face_tiles(mesh).tolist() == [1001, 1002, 1011, 1010, 1024, 0]
    flipped = Mesh("m", mesh.positions, mesh.faces, uvs=uvs * [1, -1] + [0, 1], uv_origin="top-left")
    assert face_tiles(flipped).tolist() == face_tiles(mesh).tolist()


def test_a_configuration_names_a_udim_set(tmp_path):
    """``height.MATERIAL`` in csm-assets.toml: a set on a USD scene is converted; on a glTF scene the
    refusal names the configuration's key and line."""
    folder = copy_samples(tmp_path / "in", ("brick_wall.usda", "brick_wall.gltf", "brick_wall.bin",
                                            "bricks_color.png", "bricks_height.png"))
    tiles = cut_tiles(folder / "tex")
    (folder / "csm-assets.toml").write_text('height = { bricks = "tex/h.<UDIM>.png" }\n')
    assert_clean_run(run_cli("convert", folder / "brick_wall.usda", "-o", tmp_path / "usd"))
    assert sorted(p.name for p in (tmp_path / "usd").glob("h_csm.*.png")) == [f"h_csm.{t}.png" for t in tiles]
    line = assert_clean_error(run_cli("convert", folder / "brick_wall.gltf", "-o", tmp_path / "gltf"), 2,
                              "brick_wall.gltf")
    assert "height.bricks" in line and "csm-assets.toml:1" in line and "no UDIM textures" in line


def test_float_tiles_of_other_ranges_are_made_over_the_sets_common_range(tmp_path):
    """Float heights leaving [0, 1] are rescaled over their own range when a map is made alone; a
    material holds one range, so a set's tiles are made over the range spanning them all."""
    from csm_assets.convert.udim_tiles import over_range

    folder = tmp_path / "in"
    tiles = cut_tiles(folder)
    for t, (scale, offset) in {1001: (2.0, 0.0), 1002: (2.0, -1.0), 1011: (1.0, 0.0)}.items():  # [0, 2], [-1, 1]
        unit = image.read_pixels(tiles[t])[0].astype(np.float32) / 255.0
        tiles[t].unlink()
        tiles[t] = _write(offset + scale * unit, folder / f"h.{t}.exr")
    scene = udim_stage(folder / "tiles.usda", "./h.<UDIM>.exr")
    out = tmp_path / "out"
    convert(scene, out, bits=16)
    raw = [image.read_pixels(f)[0].astype(np.float64) for f in tiles.values()]
    lo, hi = min(min(r.min(), 0.0) for r in raw), max(max(r.max(), 1.0) for r in raw)  # [0, 1] tiles: kept
    alone = [make_step_map(load_heightfield(f), StepMapSettings(tile=(False, False))).settings for f in tiles.values()]
    assert len({(a.height_scale, a.height_offset) for a in alone}) == 3  # made alone, each its own range
    stage = Usd.Stage.Open(str(out / scene.name))
    shader = stage.GetPrimAtPath("/World/Looks/rock/CsmSurface")
    scale, offset = shader.GetAttribute("inputs:heightScale").Get(), shader.GetAttribute("inputs:heightOffset").Get()
    assert (scale, offset) == (pytest.approx(hi - lo, rel=1e-6), pytest.approx(lo, rel=1e-6))
    for t, src in tiles.items():
        want = make_step_map(over_range(load_heightfield(src), hi - lo, lo), StepMapSettings(tile=(False, False),
                                                                                            bits=16)).pixels
        np.testing.assert_array_equal(read_step_map(out / f"h_csm.{t}.png"), want, err_msg=f"tile {t}")


def test_a_tile_added_concerns_the_scenes_that_read_its_set(scene, tmp_path, monkeypatch):
    """pre-commit passes a hook the files being committed: a new tile alone (not yet in any manifest)
    names the scenes whose manifests record its set."""
    from csm_assets.convert.dependents import concerned

    convert(scene, scene.parent / "out")
    new = scene.parent / "h.1012.png"
    shutil.copy(scene.parent / "h.1001.png", new)
    monkeypatch.chdir(scene.parent)
    is_scene = lambda p: p.suffix == ".usda"  # noqa: E731
    assert concerned([new], is_scene) == ([Path(scene.name)], [])
    other = scene.parent / "rock.1012.png"
    shutil.copy(new, other)
    assert concerned([other], is_scene) == ([], [])


def test_a_tile_that_needs_16_bits_raises_the_whole_set_to_16_bits(tmp_path):
    """Bits are chosen per tile, then the set shares the most any needs: an 8-bit tile that alone
    gets an 8-bit map is made again at 16 bits, still equal to its own map made alone at 16 bits."""
    from conftest import random_field
    from csm_assets.verify.bits import chooser

    folder = tmp_path / "in"
    tiles = cut_tiles(folder)
    smooth = random_field(512, 3, smooth=40.0)  # deep, smooth relief: 8-bit maps would terrace it
    smooth = (smooth - smooth.min()) / (smooth.max() - smooth.min())
    _write(np.rint(smooth * 65535).astype(np.uint16)[..., None], tiles[1002])
    alone = make_step_map(load_heightfield(tiles[1001]), StepMapSettings(tile=(False, False)),
                          choose=chooser(1.0, allowed=(8, 16)))
    assert alone.settings.bits == 8
    scene = udim_stage(folder / "tiles.usda")
    report = convert(scene, tmp_path / "out", depth=1.0)
    assert report.picks["rock"]["bits"] == 16 and "terraces" in report.picks["rock"]["bits_reason"]
    assert {read_step_map(tmp_path / "out" / f"h_csm.{t}.png").dtype for t in TILES} == {np.dtype(np.uint16)}
    assert_tiles_exact(tmp_path / "out", tiles)
