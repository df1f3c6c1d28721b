"""The Blender add-on (csm_assets.blender) with bpy from PyPI, headless: a scene built here
(tests/blender_scene.py) exported through Blender's own glTF exporter to glTF and GLB, both valid
(Khronos validator) and passing ``csm-assets verify``, imported back into the same relief nodes;
export options, warnings, and the install command. One bpy session for the module."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="bpy (Blender as a Python module) is not installed")

import blender_scene as scene  # noqa: E402  (imports bpy)
from blender_relief import relief_nodes  # noqa: E402
from attack import run_cli  # noqa: E402
from khronos import errors, validate  # noqa: E402
from area_reference import slow_areas  # noqa: E402

import csm_assets as csm  # noqa: E402
import csm_assets.blender as addon  # noqa: E402
from csm_assets.errors import OptionError  # noqa: E402
from csm_assets.formats import gltf_container as gc  # noqa: E402

pytestmark = pytest.mark.blender
EXT = "EXT_materials_cone_step_mapping"
KINDS = ("gltf", "glb")
REPEAT, CLAMP = 10497, 33071


@dataclass
class Exported:
    path: Path
    report: addon.ExportReport
    doc: gc.Document
    imported: dict = field(default_factory=dict)  # material -> its relief nodes, read back as data
    import_report: addon.ImportReport | None = None

    def material(self, name):
        return next(m for m in self.doc.json["materials"] if m["name"] == name)

    def primitive(self, material):
        index = next(i for i, m in enumerate(self.doc.json["materials"]) if m["name"] == material)
        return next(p for mesh in self.doc.json["meshes"] for p in mesh["primitives"] if p["material"] == index)

    def step_map_file(self, material, folder: Path) -> Path:
        info = self.material(material)["extensions"][EXT]["stepMapTexture"]
        image = self.doc.json["images"][self.doc.json["textures"][info["index"]]["source"]]
        if "uri" in image:
            return self.path.parent / image["uri"]
        out = folder / f"{material}_from_glb.png"
        out.write_bytes(gc.view_bytes(self.doc, image["bufferView"]))
        return out


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("blender")
    scene.build()
    out = {}
    for kind in KINDS:
        path = folder / kind / f"scene.{kind}"
        report = addon.export_gltf(path, bits=16, export_apply=kind == "glb")  # the GLB with modifiers applied
        out[kind] = Exported(path, report, gc.load(path))
    out["originals"] = relief_nodes()
    out["active_uv"] = bpy.data.objects["two_uvs"].data.uv_layers.active.name
    for kind in KINDS:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        out[kind].import_report = addon.import_gltf(out[kind].path)
        out[kind].imported = relief_nodes()
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_every_height_material_gets_the_extension(exported, kind):
    e = exported[kind]
    assert set(e.report.materials) == set(scene.CONVERTED)
    for m in e.doc.json["materials"]:
        assert (EXT in m.get("extensions", {})) == (m["name"] in scene.CONVERTED), m["name"]
    assert EXT in e.doc.json["extensionsUsed"] and EXT not in e.doc.json.get("extensionsRequired", [])
    for name, (node, *_rest) in scene.CONVERTED.items():
        ext = e.material(name)["extensions"][EXT]
        assert ext["extras"]["blender"]["node"] == node
        assert ext["variant"] == "exact" and ext["steps"] == 0 and ext["minStep"] == 0.25


@pytest.mark.parametrize("kind", KINDS)
def test_what_cannot_be_converted_is_a_warning_not_a_failure(exported, kind):
    e = exported[kind]
    assert e.path.is_file()
    for name in scene.WARNED:
        said = [w for w in e.report.warnings if f"material {name!r} not converted" in w]
        assert len(said) == 1, (name, e.report.warnings)
    text = "\n".join(e.report.warnings)
    assert "Noise Texture" in text and "has no UV map" in text and "not a readable image" in text
    assert "of type VECTOR; only a Point mapping" in text and "more than 4 corners" in text


@pytest.mark.parametrize("kind", KINDS)
def test_files_pass_the_khronos_validator(exported, kind):
    report = validate(exported[kind].path)
    assert errors(report) == []


@pytest.mark.parametrize("kind", KINDS)
def test_verify_passes_on_the_export(exported, kind):
    from conftest import skip_without_gl

    skip_without_gl()
    r = run_cli("verify", exported[kind].path, "--size", "64", "--no-cameras")
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"PASS: {len(scene.CONVERTED)} primitive(s)" in r.stdout and "0 not verifiable" in r.stdout


def test_depth_is_the_factor_over_the_size_of_one_uv_unit(exported):
    """Grids are 2 x 2 in object space; Displacement works in object space (the object's scale is
    the glTF node's), Bump in world space (the 3 x 3 scaled plane: 6 units per uv unit)."""
    expected = {"displaced": 0.06 / 2, "bumped": 0.03 / 6, "mirrored": 0.04 / np.sqrt(2),  # mirrored: uv area halved
                "second_uv": 0.05 / 2, "by_property": 0.1,  # the custom property's default, as convert --height
                "mapped": 0.05 / np.sqrt(4 / 6)}  # the Mapping node's 2 x 3 scale: 6 uv units of area
    for kind in KINDS:
        for name, depth in expected.items():
            got = exported[kind].material(name)["extensions"][EXT]["depthScale"]
            assert got == pytest.approx(depth, rel=1e-6), (kind, name)
        e = exported[kind]  # the sphere, measured on the file's own triangles (object space, as glTF stores them)
        prim = e.primitive("sphere")
        p, uv = (gc.read_accessor(e.doc, prim["attributes"][k]) for k in ("POSITION", "TEXCOORD_0"))
        faces = gc.read_accessor(e.doc, prim["indices"]).reshape(-1, 3)
        world, uv_area = slow_areas([(p, uv, faces)])
        got = e.material("sphere")["extensions"][EXT]["depthScale"]
        assert got == pytest.approx(0.05 / np.sqrt(world / uv_area), rel=1e-4)


@pytest.mark.parametrize("kind", KINDS)
def test_step_map_holds_the_height_image_exactly(exported, kind, tmp_path):
    e = exported[kind]
    cobbles = csm.load_heightfield(scene.COBBLES)  # 16-bit, as the map (bits=16)
    sm = csm.load_step_map(e.step_map_file("displaced", tmp_path))
    assert sm.pixels.dtype == np.uint16 and sm.settings.bits == 16
    assert np.array_equal(sm.pixels[..., 0], np.round(cobbles.data * 65535).astype(np.uint16))
    assert sm.settings.tile == (True, True)
    bricks = csm.load_step_map(e.step_map_file("bumped", tmp_path))
    assert bricks.settings.tile == (False, False)  # the image's Extend: no tiling, CLAMP_TO_EDGE
    info = e.material("bumped")["extensions"][EXT]["stepMapTexture"]
    sampler = e.doc.json["samplers"][e.doc.json["textures"][info["index"]]["sampler"]]
    assert (sampler["wrapS"], sampler["wrapT"], sampler["minFilter"]) == (CLAMP, CLAMP, 9729)


@pytest.mark.parametrize("kind", KINDS)
def test_tangents_follow_the_reliefs_uv_map(exported, kind):
    """The relief of two_uvs uses its second UV map (turned a quarter), which is not the active
    one: the exported TANGENT follows it (the GLB from the modifier's evaluated mesh), and the
    mesh's active UV map is put back."""
    e = exported[kind]
    prim = e.primitive("second_uv")
    assert e.material("second_uv")["extensions"][EXT]["stepMapTexture"]["texCoord"] == 1
    tangent = gc.read_accessor(e.doc, prim["attributes"]["TANGENT"])[:, :3]
    positions = gc.read_accessor(e.doc, prim["attributes"]["POSITION"])

    def du_direction(uvs):  # where u grows on the surface, from the first triangle
        tri = gc.read_accessor(e.doc, prim["indices"]).reshape(-1)[:3]
        (p0, p1, p2), (t0, t1, t2) = positions[tri], uvs[tri]
        e1, e2, d1, d2 = p1 - p0, p2 - p0, t1 - t0, t2 - t0
        r = 1.0 / (d1[0] * d2[1] - d2[0] * d1[1])
        v = (e1 * d2[1] - e2 * d1[1]) * r
        return v / np.linalg.norm(v)

    along = du_direction(gc.read_accessor(e.doc, prim["attributes"]["TEXCOORD_1"]))
    other = du_direction(gc.read_accessor(e.doc, prim["attributes"]["TEXCOORD_0"]))
    assert abs(float(along @ other)) < 1e-3  # the two uv sets run a quarter turn apart
    assert (tangent @ along).min() > 0.999
    assert exported["active_uv"] == "UVMap"


def test_mirrored_uvs_get_both_handednesses(exported):
    e = exported["glb"]
    tangent = gc.read_accessor(e.doc, e.primitive("mirrored")["attributes"]["TANGENT"])
    assert set(np.unique(tangent[:, 3])) == {-1.0, 1.0}


@pytest.mark.parametrize("kind", KINDS)
def test_import_gives_back_the_relief_nodes(exported, kind):
    before, after = exported["originals"], exported[kind].imported
    assert set(after) == set(scene.CONVERTED)
    assert set(exported[kind].import_report.materials) == set(scene.CONVERTED)
    for name in scene.CONVERTED:
        old, new = before.get(name), after[name]
        assert new["colorspace"] == "Non-Color"
        if old is None:  # by_property: no node before; a Displacement node of its depth now
            assert new["node"] == "DISPLACEMENT" and new["factor"] == pytest.approx(0.1 * 2, rel=1e-5)
            continue
        for key in ("node", "space", "extension", "midlevel"):
            assert new[key] == old[key], (name, key)
        assert new["factor"] == pytest.approx(old["factor"], rel=1e-5), name
        assert np.abs(new["red"] - old["red"]).max() <= 1 / 65535 + 1e-6, name  # the same heights
    assert after["second_uv"]["uv_map"] == "UVMap.001"  # the importer's name for the second UV map
    for key, old, new in zip(("Location", "Rotation", "Scale"), before["mapped"]["mapping"],
                             after["mapped"]["mapping"]):
        assert old == pytest.approx(scene.MAPPING[key], abs=1e-6)
        assert new == pytest.approx(old, abs=1e-6)  # the Mapping node back, through KHR_texture_transform


def test_export_options_reach_the_material(tmp_path):
    scene.build()
    report = addon.export_gltf(tmp_path / "o.gltf", bits=8, variant="loop", steps=12, self_shadow=True,
                               light_size=0.05, tile=False, max_ratio=0.5, bilinear_safe=False, use_selection=False)
    doc = json.loads((tmp_path / "o.gltf").read_text())
    ext = next(m for m in doc["materials"] if m["name"] == "displaced")["extensions"][EXT]
    assert (ext["variant"], ext["steps"], ext["selfShadow"], ext["lightSize"]) == ("loop", 12, True, 0.05)
    assert (ext["maxRatio"], ext["tile"], ext["minStep"]) == (0.5, [False, False], 1.0)
    sm = csm.load_step_map(tmp_path / doc["images"][doc["textures"][ext["stepMapTexture"]["index"]]["source"]]["uri"])
    assert sm.pixels.dtype == np.uint8 and sm.settings.max_ratio == 0.5
    assert report.materials["displaced"]["variant"] == "loop"
    relaxed = addon.export_gltf(tmp_path / "r.glb", cones="relaxed")
    assert {(m["variant"], m["steps"]) for m in relaxed.materials.values()} == {("relaxed", 2)}
    assert bpy.context.scene.csm_assets_gltf.cones == "conservative"  # the panel's settings are put back


def test_max_error_picks_a_variant(tmp_path):
    from conftest import skip_without_gl

    skip_without_gl()
    scene.build()
    report = addon.export_gltf(tmp_path / "e.glb", max_error=0.5)
    for picked in report.materials.values():
        assert picked["variant"] in ("exact", "loop", "fixed", "parallax", "pom", "relief", "relaxed")


@pytest.mark.parametrize("options, error", [
    (dict(bits=32), OptionError), (dict(steps=500), OptionError), (dict(light_size=0.1), OptionError),
    (dict(cones="relaxed", variant="pom"), OptionError), (dict(variant="best"), OptionError),
    (dict(no_such_option=1, bits=8), TypeError)])
def test_bad_options_are_refused_before_anything_is_written(tmp_path, options, error):
    scene.build()
    if "no_such_option" in options:  # Blender's exporter refuses unknown keywords itself
        with pytest.raises(error):
            addon.export_gltf(tmp_path / "x.glb", **options)
    else:
        with pytest.raises(error):
            addon.export_gltf(tmp_path / "x.glb", **options)
    assert not (tmp_path / "x.glb").exists()


def test_panel_settings_are_registered():
    from io_scene_gltf2 import exporter_extension_layout_draw

    addon.enable()
    props = bpy.context.scene.csm_assets_gltf
    from csm_assets.blender.options import OPTIONS

    assert all(hasattr(props, o.name) for o in OPTIONS) and props.enabled
    assert exporter_extension_layout_draw[addon.DRAW_KEY] is addon.panel.draw_export
    assert not hasattr(addon, "draw_export") and not hasattr(addon, "draw")  # Blender 4.2 would draw it twice
    assert bpy.context.scene.csm_assets_gltf_import.node == "AUTO"


def test_install_command_enables_the_addon_for_blenders_own_exporter(tmp_path):
    """``csm-assets blender install`` into Blender (here bpy, with its own HOME); a new Blender
    session that loads its preferences exports through the plain glTF operator with CSM."""
    env = dict(os.environ, HOME=str(tmp_path / "home"))
    r = run_cli("blender", "install", env=env, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "csm_assets_gltf" in r.stdout and "enabled" in r.stdout
    if bpy.app.version < (4, 3):  # bpy 4.2 as a module crashes in wm.read_userpref: no session can load them
        assert list((tmp_path / "home").rglob("csm_assets_gltf/__init__.py")), r.stdout
        return
    code = ("import sys, json; sys.path.insert(0, %r); import bpy, blender_scene; blender_scene.build(); "
            "bpy.ops.wm.read_userpref(); "
            "print('ADDONS', [a for a in bpy.context.preferences.addons.keys() if 'csm' in a]); "
            "bpy.ops.export_scene.gltf(filepath=%r, export_format='GLB')") % (
        str(Path(__file__).parent), str(tmp_path / "plain.glb"))
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert "ADDONS ['csm_assets_gltf']" in run.stdout, run.stdout + run.stderr
    doc = gc.load(tmp_path / "plain.glb")
    assert {m["name"] for m in doc.json["materials"] if EXT in m.get("extensions", {})} == set(scene.CONVERTED)


def test_panel_settings_no_material_can_carry_are_a_warning(tmp_path):
    """Through Blender's own operator (the file dialog's path): a light size without self-shadowing
    is refused with one warning and the export still finishes, without CSM."""
    scene.build()
    addon.enable()
    props = bpy.context.scene.csm_assets_gltf
    props.light_size, props.self_shadow = 0.1, False
    assert bpy.ops.export_scene.gltf(filepath=str(tmp_path / "p.glb"), export_format="GLB") == {"FINISHED"}
    from csm_assets.blender import export_hooks

    assert [w for w in export_hooks.LAST_REPORT.warnings if "options refused" in w and "self_shadow" in w]
    assert not export_hooks.LAST_REPORT.materials
    assert not any(EXT in m.get("extensions", {}) for m in gc.load(tmp_path / "p.glb").json["materials"])


def test_an_image_blender_linearises_is_converted_with_a_warning(tmp_path):
    scene.build()
    bpy.data.images[scene.BRICKS.name].colorspace_settings.name = "sRGB"
    report = addon.export_gltf(tmp_path / "s.glb")
    said = [w for w in report.warnings if "colour space 'sRGB'" in w]
    assert len(said) == 1 and f"image {scene.BRICKS.name!r}" in said[0], report.warnings  # once per image
    assert {"bumped", "mirrored", "mapped", "by_property"} <= set(report.materials)  # all using it: converted


def test_import_warns_about_a_step_map_texture_the_file_has_not(exported, tmp_path):
    doc = json.loads(exported["gltf"].path.read_text())
    for m in doc["materials"]:
        if m["name"] == "displaced":
            m["extensions"][EXT]["stepMapTexture"]["index"] = 99
    broken = exported["gltf"].path.parent / "broken_index.gltf"
    broken.write_text(json.dumps(doc))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    report = addon.import_gltf(broken)
    assert "displaced" not in report.materials and "bumped" in report.materials
    assert [w for w in report.warnings if "stepMapTexture/index: expected the index of one of the" in w and "99" in w]


@pytest.mark.parametrize("kind", KINDS)
def test_materials_sharing_a_height_image_share_its_step_map(exported, kind):
    """As convert does: one map per (image, channel, inversion, tiling), written once."""
    e = exported[kind]

    def texture(name):
        return e.material(name)["extensions"][EXT]["stepMapTexture"]["index"]

    assert texture("displaced") == texture("second_uv")                                # cobbles, repeating
    assert texture("mirrored") == texture("mapped") == texture("by_property")          # bricks, repeating
    assert len({texture("displaced"), texture("mirrored"), texture("bumped")}) == 3    # bricks clamped: its own
    sources = [e.doc.json["textures"][texture(n)]["source"] for n in scene.CONVERTED]
    assert len(set(sources)) == 3


def test_import_of_a_file_convert_wrote(tmp_path):
    """A scene converted by ``convert`` (no Blender extras): a Displacement node whose Scale is the
    source file's displacement factor again (0.03), Midlevel 1 (the relief goes into the surface)."""
    import shutil

    from csm_assets.convert.pipeline import convert

    src = tmp_path / "src"
    src.mkdir()
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(scene.SAMPLES / name, src / name)
    convert(src / "brick_wall.gltf", tmp_path / "out")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    report = addon.import_gltf(tmp_path / "out" / "brick_wall.gltf")
    (name,) = report.materials
    relief = relief_nodes()[name]
    assert (relief["node"], relief["space"], relief["midlevel"]) == ("DISPLACEMENT", "OBJECT", 1.0)
    assert relief["factor"] == pytest.approx(0.03, rel=1e-5)
    heights = csm.load_heightfield(src / "bricks_height.png").data
    assert np.abs(relief["red"] - heights).max() <= 1 / 255 + 1e-6
