"""The Blender add-on on real third-party .blend files.

``tests/data/armory_examples``: Armory3D's "material_bump" example (zlib licence, saved by
Blender 3.6), with reliefs of its own: two materials whose Image Texture (one packed in the file,
sRGB; one beside it) feeds a Bump node's Height, one with Strength 0.5, on a cube and two scaled
planes with uvs well outside 0..1. Exported as it is.

``tests/data/gltf_blender_io``: a scene of Khronos' glTF-Blender-IO test suite (Apache-2.0, saved
by Blender 2.78, two Material Outputs per material, a plane without UV maps) without a relief of
its own: the test gives two of its materials one as a user would, a Displacement node on the
sphere and a Bump node on the crate, both fed by the alpha of a third-party noise image from the
same repository.

Each is exported to glTF and GLB through Blender's exporter: valid (Khronos validator),
``csm-assets verify`` passes, and imported back into the same relief nodes, image, depth and
tiling (docs/guides/blender.md, "Real third-party scenes")."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="bpy (Blender as a Python module) is not installed")

from area_reference import slow_areas  # noqa: E402
from attack import run_cli  # noqa: E402
from blender_relief import relief_nodes  # noqa: E402
from khronos import errors, validate  # noqa: E402

import csm_assets as csm  # noqa: E402
import csm_assets.blender as addon  # noqa: E402
from csm_assets.formats import gltf_container as gc  # noqa: E402

pytestmark = pytest.mark.blender
DATA = Path(__file__).resolve().parent / "data" / "gltf_blender_io"
BLEND, NOISE = DATA / "04_common_materials.blend", DATA / "NoisePattern.png"
EXT = "EXT_materials_cone_step_mapping"
KINDS = ("gltf", "glb")
TIGHT = 0.005  # texels: a budget 8-bit maps of the noise cannot meet on these meshes
RELIEFS = {"Sphere": ("DISPLACEMENT", 0.05), "Crate": ("BUMP", 0.02)}  # material -> node, Scale/Distance


def open_with_reliefs() -> None:
    """The .blend as shipped, then a relief on two of its materials: an Image Texture of the noise
    (Non-Color, its Alpha output) into a Displacement node on the active Material Output, or
    into a Bump node on the surface shader's Normal."""
    bpy.ops.wm.open_mainfile(filepath=str(BLEND), load_ui=False)
    noise = bpy.data.images.load(str(NOISE), check_existing=True)
    noise.colorspace_settings.name = "Non-Color"
    for name, (node, factor) in RELIEFS.items():
        tree = bpy.data.materials[name].node_tree
        output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output)
        image = tree.nodes.new("ShaderNodeTexImage")
        image.image = noise
        if node == "DISPLACEMENT":
            relief = tree.nodes.new("ShaderNodeDisplacement")
            relief.inputs["Scale"].default_value = factor
            tree.links.new(relief.outputs["Displacement"], output.inputs["Displacement"])
        else:
            relief = tree.nodes.new("ShaderNodeBump")
            relief.inputs["Distance"].default_value = factor
            tree.links.new(relief.outputs["Normal"], output.inputs["Surface"].links[0].from_node.inputs["Normal"])
        tree.links.new(image.outputs["Alpha"], relief.inputs["Height"])


@dataclass
class Exported:
    path: Path
    report: addon.ExportReport
    doc: gc.Document
    imported: dict = field(default_factory=dict)

    def material(self, name):
        return next(m for m in self.doc.json["materials"] if m["name"] == name)

    def primitive(self, material):
        index = next(i for i, m in enumerate(self.doc.json["materials"]) if m["name"] == material)
        return next(p for mesh in self.doc.json["meshes"] for p in mesh["primitives"] if p["material"] == index)


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("blender_real")
    open_with_reliefs()
    return {"originals": relief_nodes(), **export_and_import(folder, "common_materials", relief_nodes)}


def export_and_import(folder, stem: str, read) -> dict:
    """The open scene exported through the add-on as glTF and GLB (16 bits), then each file
    imported into an empty scene; ``read()`` of each import in ``.imported``."""
    out = {}
    for kind in KINDS:
        path = folder / kind / f"{stem}.{kind}"
        out[kind] = Exported(path, addon.export_gltf(path, bits=16), None)
        out[kind].doc = gc.load(path)
    for kind in KINDS:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        addon.import_gltf(out[kind].path)
        out[kind].imported = read()
    return out


def test_the_file_is_the_third_party_one():
    """Guards the fixture: the .blend is the 2.78 file with no relief of its own."""
    bpy.ops.wm.open_mainfile(filepath=str(BLEND), load_ui=False)
    assert tuple(bpy.data.version[:2]) == (2, 78) and relief_nodes() == {}
    assert sum(n.bl_idname == "ShaderNodeOutputMaterial" for n in bpy.data.materials["Sphere"].node_tree.nodes) == 2


@pytest.mark.parametrize("kind", KINDS)
def test_the_reliefs_are_converted_without_warnings(exported, kind):
    e = exported[kind]
    assert set(e.report.materials) == set(RELIEFS) and e.report.warnings == []
    for m in e.doc.json["materials"]:
        assert (EXT in m.get("extensions", {})) == (m["name"] in RELIEFS), m["name"]
    for name, (node, factor) in RELIEFS.items():
        assert e.report.materials[name]["node"] == node and e.report.materials[name]["image"] == NOISE.name


SCENES = [("exported", 2), ("armory", 3)]  # each real scene's fixture and its primitives with relief


@pytest.mark.parametrize("scene, primitives", SCENES)
@pytest.mark.parametrize("kind", KINDS)
def test_files_pass_the_khronos_validator(request, scene, primitives, kind):
    assert errors(validate(request.getfixturevalue(scene)[kind].path)) == []


@pytest.mark.parametrize("scene, primitives", SCENES)
@pytest.mark.parametrize("kind", KINDS)
def test_verify_passes_on_the_export(request, scene, primitives, kind):
    from conftest import skip_without_gl

    skip_without_gl()
    r = run_cli("verify", request.getfixturevalue(scene)[kind].path, "--size", "64")
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"PASS: {primitives} primitive(s)" in r.stdout and "0 not verifiable" in r.stdout


@pytest.mark.parametrize("kind", KINDS)
def test_depth_is_the_factor_over_the_size_of_one_uv_unit(exported, kind):
    """Measured on the file's own triangles: the sphere's and the cube's objects are unscaled, so
    object and world space (Displacement's and Bump's) have the same areas."""
    e = exported[kind]
    for name, (_, factor) in RELIEFS.items():
        prim = e.primitive(name)
        p, uv = (gc.read_accessor(e.doc, prim["attributes"][k]) for k in ("POSITION", "TEXCOORD_0"))
        faces = gc.read_accessor(e.doc, prim["indices"]).reshape(-1, 3)
        world, uv_area = slow_areas([(p, uv, faces)])
        got = e.material(name)["extensions"][EXT]["depthScale"]
        assert got == pytest.approx(factor / np.sqrt(world / uv_area), rel=1e-4), name


@pytest.mark.parametrize("kind", KINDS)
def test_import_gives_back_the_relief_nodes(exported, kind):
    """The same node, space, factor and wrap, and the noise's alpha as the heights (16-bit map)."""
    before, after = exported["originals"], exported[kind].imported
    assert set(before) == set(after) == set(RELIEFS)
    noise = before["Sphere"]["red"]
    assert noise.shape == (128, 128) and noise.std() > 0.1  # the alpha channel, not the black colour
    for name in RELIEFS:
        old, new = before[name], after[name]
        for key in ("node", "space", "extension", "midlevel"):
            assert new[key] == old[key], (name, key)
        assert new["factor"] == pytest.approx(old["factor"], rel=1e-5), name
        assert new["colorspace"] == "Non-Color"
        assert np.abs(new["red"] - old["red"]).max() <= 1 / 65535 + 1e-6, name


@pytest.mark.slow
def test_max_error_is_confirmed_on_the_exported_meshes(tmp_path):
    """As ``convert --max-error``: the pick is confirmed with verify's measure on the meshes as
    exported; 8-bit maps cannot meet TIGHT texels here, so each material's map is made again at
    16 bits (CSM303 in the report) and ``verify --max-error TIGHT`` passes on the file."""
    from conftest import skip_without_gl

    skip_without_gl()
    open_with_reliefs()
    path = tmp_path / "confirmed.glb"
    report = addon.export_gltf(path, max_error=TIGHT, bits=8)
    assert set(report.materials) == set(RELIEFS)
    for name in RELIEFS:
        said = [w for w in report.warnings if w.startswith(f"CSM: material {name!r}: CSM303 an 8-bit step map")]
        assert len(said) == 1, report.warnings
    doc = gc.load(path)
    for m in doc.json["materials"]:
        if m["name"] in RELIEFS:
            ext = m["extensions"][EXT]
            image = doc.json["images"][doc.json["textures"][ext["stepMapTexture"]["index"]]["source"]]
            (tmp_path / "map.png").write_bytes(gc.view_bytes(doc, image["bufferView"]))
            assert csm.load_step_map(tmp_path / "map.png").settings.bits == 16, m["name"]
            assert (ext["variant"], ext["steps"]) == tuple(report.materials[m["name"]][k] for k in ("variant", "steps"))
    r = run_cli("verify", path, "--max-error", str(TIGHT))
    assert r.returncode == 0, r.stdout + r.stderr


# --- Armory3D's material_bump.blend: reliefs of its own -------------------------------------------

ARMORY = Path(__file__).resolve().parent / "data" / "armory_examples" / "material_bump.blend"
BUMPS = {"Material": ("bump.jpg", 0.1, 0.5), "Material.001": ("brick_bump.jpg", 0.1, 1.0)}  # image, Distance, Strength
SRGB = ("CSM: image 'bump.jpg' (material 'Material') is in colour space 'sRGB', which Blender linearises; "
        "the step map keeps the stored values (set it to Non-Color)")


def bump_strengths() -> dict:
    return {m.name: n.inputs["Strength"].default_value for m in bpy.data.materials if m.node_tree
            for n in m.node_tree.nodes if n.bl_idname == "ShaderNodeBump"}


def blender_heights(relief: dict) -> np.ndarray:
    """What Blender's Bump reads from an Image Texture's Color: the luminance (Rec. 709) of the
    stored values, in image order."""
    image = bpy.data.images[relief["image"]]
    w, h = image.size
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, -1)[::-1, :, :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def world_linear(node: dict) -> np.ndarray:
    """A glTF node's rotation times scale (the scene has no parents)."""
    x, y, z, w = node.get("rotation", (0, 0, 0, 1))
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    return r * np.asarray(node.get("scale", (1, 1, 1)), float)


@pytest.fixture(scope="module")
def armory(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("blender_armory")
    bpy.ops.wm.open_mainfile(filepath=str(ARMORY), load_ui=False)
    out = {"originals": relief_nodes(), "strengths": bump_strengths()}
    out["heights"] = {name: blender_heights(r) for name, r in out["originals"].items()}
    out.update(export_and_import(folder, "material_bump",
                                 lambda: {"reliefs": relief_nodes(), "strengths": bump_strengths()}))
    return out


def test_the_armory_file_has_its_own_image_fed_bump_nodes():
    """Guards the fixture: the file as shipped, nothing added."""
    bpy.ops.wm.open_mainfile(filepath=str(ARMORY), load_ui=False)
    assert tuple(bpy.data.version[:2]) == (3, 6)
    reliefs = relief_nodes()
    assert {k: (r["node"], r["image"], r["factor"]) for k, r in reliefs.items()} == {
        k: ("BUMP", image, pytest.approx(d)) for k, (image, d, _) in BUMPS.items()}
    assert bump_strengths() == {k: s for k, (_, _, s) in BUMPS.items()}
    assert bpy.data.images["bump.jpg"].packed_file is not None and bpy.data.images["brick_bump.jpg"].packed_file is None
    assert all(len(o.data.uv_layers) == 1 for o in bpy.data.objects if o.type == "MESH")


@pytest.mark.parametrize("kind", KINDS)
def test_the_armory_bumps_are_converted(armory, kind):
    """Both materials; the one warning is the packed image's sRGB colour space."""
    e = armory[kind]
    assert set(e.report.materials) == set(BUMPS) and e.report.warnings == [SRGB]
    for name, (image, distance, strength) in BUMPS.items():
        got = e.report.materials[name]
        assert (got["node"], got["image"], got["strength"], got["tile"]) == ("BUMP", image, strength, [True, True])
        assert e.material(name)["extensions"][EXT]["extras"]["blender"].get("strength", 1.0) == strength


@pytest.mark.parametrize("kind", KINDS)
def test_armory_depth_is_distance_times_strength_over_the_world_size_of_a_uv_unit(armory, kind):
    """Bump is world space: measured on every primitive of the material (a cube and a plane of
    scale 4 share ``Material``) with its node's rotation and scale applied."""
    e = armory[kind]
    for name, (_, distance, strength) in BUMPS.items():
        index = next(i for i, m in enumerate(e.doc.json["materials"]) if m["name"] == name)
        parts = []
        for node in e.doc.json["nodes"]:
            for prim in e.doc.json["meshes"][node["mesh"]]["primitives"]:
                if prim["material"] == index:
                    p, uv = (gc.read_accessor(e.doc, prim["attributes"][k]) for k in ("POSITION", "TEXCOORD_0"))
                    faces = gc.read_accessor(e.doc, prim["indices"]).reshape(-1, 3)
                    parts.append((p @ world_linear(node).T, uv, faces))
        world, uv_area = slow_areas(parts)
        got = e.material(name)["extensions"][EXT]["depthScale"]
        assert got == pytest.approx(distance * strength / np.sqrt(world / uv_area), rel=1e-4), name
    assert e.material("Material.001")["extensions"][EXT]["depthScale"] == pytest.approx(0.1 / 4, rel=1e-4)


@pytest.mark.parametrize("kind", KINDS)
def test_import_gives_back_the_armory_bumps(armory, kind):
    """The same node, Distance, Strength, wrap and mapping; heights as Blender reads the images
    (the luminance of their stored values) within a 16-bit step."""
    before, after = armory["originals"], armory[kind].imported["reliefs"]
    assert set(before) == set(after) == set(BUMPS)
    assert armory[kind].imported["strengths"] == armory["strengths"]
    for name in BUMPS:
        old, new = before[name], after[name]
        for key in ("node", "space", "extension", "mapping"):
            assert new[key] == old[key], (name, key)
        assert new["factor"] == pytest.approx(old["factor"], rel=1e-5), name
        assert new["colorspace"] == "Non-Color" and new["red"].shape == (1024, 1024)
        heights = armory["heights"][name]
        assert heights.std() > 0.05, name
        assert np.abs(new["red"] - heights).max() <= 1 / 65535 + 1e-6, name


def test_a_bump_of_strength_0_is_a_warning(tmp_path):
    """Strength 0 bumps nothing: no relief to convert, said in the report."""
    bpy.ops.wm.open_mainfile(filepath=str(ARMORY), load_ui=False)
    for m in bpy.data.materials:
        m.node_tree.nodes["Bump"].inputs["Strength"].default_value = 0.0
    report = addon.export_gltf(tmp_path / "strength0.glb")
    assert report.materials == {}
    for name in BUMPS:
        assert f"CSM: material {name!r} not converted: node 'Bump' (ShaderNodeBump) has Strength 0: it bumps nothing" \
            in report.warnings
