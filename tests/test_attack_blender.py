"""Attacks on the Blender add-on (bpy from PyPI, marker ``blender``): a converted scene whose
extension holds bad values is imported with a warning per bad material (that material without
relief, or a Blender hint at its default) and every other material set up; a huge step map is
refused from its header before Blender loads it; an export whose ``csm_depth`` is infinite or 0 is
a warning in the report; the installer refuses FIFOs, device links, links out and foreign folders
without reading them (a subprocess timeout far above the time it takes)."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy", reason="bpy (Blender as a Python module) is not installed")

import blender_scene as scene  # noqa: E402  (imports bpy)

import csm_assets.blender as addon  # noqa: E402

pytestmark = pytest.mark.blender
EXT = "EXT_materials_cone_step_mapping"
BIG = 10 ** 400  # a JSON integer past float's range


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    """brick_wall converted, with a second mesh and material ("good", the first's copy) beside the wall."""
    from csm_assets.convert.pipeline import convert

    tmp = tmp_path_factory.mktemp("wall")
    for name in ("brick_wall.gltf", "brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(scene.SAMPLES / name, tmp / name)
    convert(tmp / "brick_wall.gltf", tmp / "out")
    path = tmp / "out" / "brick_wall.gltf"
    doc = json.loads(path.read_text())
    good = dict(json.loads(json.dumps(doc["materials"][0])), name="good")
    doc["textures"].append(dict(doc["textures"][good["extensions"][EXT]["stepMapTexture"]["index"]]))
    good["extensions"][EXT]["stepMapTexture"]["index"] = len(doc["textures"]) - 1  # its own texture
    doc["materials"].append(good)
    doc["meshes"].append({"primitives": [dict(doc["meshes"][0]["primitives"][0], material=1)]})
    doc["nodes"].append({"mesh": 1, "name": "good", "translation": [3, 0, 0]})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    path.write_text(json.dumps(doc))
    return path


def big_png(path: Path, side: int) -> None:
    """A grey 8-bit PNG of side x side texels, written a row at a time (a few MB of memory)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    z, row, parts = zlib.compressobj(9), b"\0" + b"\x80" * side, []
    for _ in range(side):
        parts.append(z.compress(row))
    parts.append(z.flush())
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", b"".join(parts)) + chunk(b"IEND", b""))


def ext(doc):
    return doc["materials"][0]["extensions"][EXT]


def hint(doc, **values):
    ext(doc).setdefault("extras", {}).setdefault("blender", {}).update(values)


def step_texture(doc):
    return doc["textures"][ext(doc)["stepMapTexture"]["index"]]


def huge(doc, folder):
    big_png(folder / "huge.png", 30000)  # 900 M texels, about 0.9 MB of PNG
    doc["images"].append({"uri": "huge.png"})
    step_texture(doc)["source"] = len(doc["images"]) - 1


def special(doc, folder, kind):
    """The step map's image a FIFO or a link to a device (Blender would block on it or read it for ever)."""
    path = folder / "special.png"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(kind)
    doc["images"].append({"uri": "special.png"})
    step_texture(doc)["source"] = len(doc["images"]) - 1


def huge_embedded(doc, folder):
    """The huge map as a data URI (an embedded image: its bytes read, its header checked)."""
    import base64

    huge(doc, folder)
    data = base64.b64encode((folder / "huge.png").read_bytes()).decode()
    doc["images"][-1] = {"uri": f"data:image/png;base64,{data}"}


# case -> (change, what the warning says, whether the material still gets its relief)
CASES = {
    "texCoord x": (lambda d, f: ext(d)["stepMapTexture"].update(texCoord="x"), "texCoord: expected an integer", False),
    "texCoord -1": (lambda d, f: ext(d)["stepMapTexture"].update(texCoord=-1), "texCoord: expected an integer", False),
    "midlevel 10**400": (lambda d, f: hint(d, midlevel=BIG), "extras.blender.midlevel 1000", True),
    "midlevel text": (lambda d, f: hint(d, midlevel="half"), "extras.blender.midlevel 'half'", True),
    "strength 5": (lambda d, f: hint(d, node="BUMP", strength=5), "extras.blender.strength 5 is not in (0, 1]", True),
    "node __proto__": (lambda d, f: hint(d, node="__proto__"), "extras.blender.node '__proto__'", True),
    "space 7": (lambda d, f: hint(d, space=7), "extras.blender.space 7", True),
    "extras.blender a list": (lambda d, f: ext(d).update(extras={"blender": [1]}), "extras.blender is not an", True),
    "extras a string": (lambda d, f: ext(d).update(extras="x"), "extras is not an object", True),
    "image 99": (lambda d, f: step_texture(d).update(source=99), "source 99 names no image", False),
    "webp image 99": (lambda d, f: step_texture(d).update(extensions={"EXT_texture_webp": {"source": 99}}),
                      "EXT_texture_webp source 99 names no image", False),
    "sampler 99": (lambda d, f: step_texture(d).update(sampler=99), "sampler 99 names no sampler", False),
    "transform offset x": (lambda d, f: ext(d)["stepMapTexture"].update(
        extensions={"KHR_texture_transform": {"offset": ["x", 0]}}), "KHR_texture_transform/offset", False),
    "depthScale 1e308": (lambda d, f: ext(d).update(depthScale=1e308), "beyond Blender's 32-bit float range", False),
    "depthScale 10**400": (lambda d, f: ext(d).update(depthScale=BIG), "depthScale must be a finite number", False),
    "depthScale -1": (lambda d, f: ext(d).update(depthScale=-1), "depthScale must be a finite number >= 0", False),
    "variant __proto__": (lambda d, f: ext(d).update(variant="__proto__"), "variant '__proto__' is none of", False),
    "steps 1e9": (lambda d, f: ext(d).update(steps=1e9), "steps 1000000000.0 is outside", False),
    "huge step map": (huge, "30000x30000-pixel image declares 900,000,000 texels, over the limit", False),
    "huge embedded step map": (lambda d, f: huge_embedded(d, f), "30000x30000-pixel image declares", False),
    "transform scale 1e300": (lambda d, f: ext(d)["stepMapTexture"].update(
        extensions={"KHR_texture_transform": {"scale": [1e300, 1]}}), "scale [1e+300, 1] is beyond", False),
}


@pytest.mark.parametrize("case", CASES)
def test_a_bad_material_is_a_warning_and_the_rest_is_imported(converted, case, tmp_path):
    change, said, relief = CASES[case]
    folder = tmp_path / "s"
    shutil.copytree(converted.parent, folder)
    doc = json.loads((folder / converted.name).read_text())
    change(doc, folder)
    (folder / "bad.gltf").write_text(json.dumps(doc))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    report = addon.import_gltf(folder / "bad.gltf")  # never raises: the import goes on
    assert "good" in report.materials and len(bpy.data.objects) == 2, report.warnings
    (warning,) = [w for w in report.warnings if "'bricks'" in w]
    assert said in warning and len(warning) < 500, warning
    assert ("bricks" in report.materials) == relief, report.warnings
    if case == "huge step map":
        assert "huge.png" not in {i.name for i in bpy.data.images}  # never loaded


@pytest.mark.parametrize("kind", ["fifo", "/dev/zero"])
def test_a_step_map_that_is_a_fifo_or_a_device_is_not_read(converted, kind, tmp_path):
    """In a subprocess with a timeout far above an import's second: Blender would block on a FIFO
    or read a device for ever; the material gets a warning and no relief, the rest is imported."""
    folder = tmp_path / "s"
    shutil.copytree(converted.parent, folder)
    doc = json.loads((folder / converted.name).read_text())
    special(doc, folder, kind)
    (folder / "bad.gltf").write_text(json.dumps(doc))
    code = ("import sys, json, csm_assets.blender as a; r = a.import_gltf(sys.argv[1]); "
            "print('REPORT', json.dumps([sorted(r.materials), r.warnings]))")
    run = subprocess.run([sys.executable, "-c", code, str(folder / "bad.gltf")], capture_output=True, text=True,
                         timeout=300)
    line = next((x for x in run.stdout.splitlines() if x.startswith("REPORT ")), None)
    assert line, run.stdout[-2000:] + run.stderr[-2000:]
    materials, warnings = json.loads(line[len("REPORT "):])
    assert materials == ["good"] and any("'bricks'" in w and "is not a regular file" in w for w in warnings), warnings


def test_a_factor_beyond_32_bit_floats_leaves_the_relief_unwired(converted, tmp_path):
    """depthScale within float32 times a huge object's size per uv unit: a warning, the node unwired."""
    doc = json.loads(converted.read_text())
    ext(doc)["depthScale"] = 3e38
    hint(doc, space="WORLD")  # measured in world space, where the object's scale counts
    doc["nodes"][0]["scale"] = [1e3, 1e3, 1e3]
    (tmp_path / "far.gltf").write_text(json.dumps(doc))
    for name in ("brick_wall.bin", "bricks_color.png", "bricks_height.png"):
        shutil.copy(converted.parent / name, tmp_path / name)
    for p in converted.parent.glob("*_csm*.png"):
        shutil.copy(p, tmp_path / p.name)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    report = addon.import_gltf(tmp_path / "far.gltf")
    assert [w for w in report.warnings if "'bricks'" in w and "left unconnected" in w], report.warnings
    node = next(n for n in bpy.data.materials["bricks"].node_tree.nodes if n.label == "CSM relief")
    assert not node.outputs[0].links and "good" in report.materials


@pytest.mark.parametrize("depth", [float("inf"), 0.0, -1.0, float("nan"), 1e39])
def test_csm_depth_out_of_range_is_a_warning_in_the_export_report(tmp_path, depth):
    scene.build()
    bpy.data.materials["by_property"]["csm_depth"] = depth
    report = addon.export_gltf(tmp_path / "s.glb")
    (said,) = [w for w in report.warnings if "'by_property'" in w]
    assert "csm_depth" in said and "no texture-space depth" in said, said
    assert "by_property" not in report.materials and "displaced" in report.materials


def _check(addons: Path) -> subprocess.CompletedProcess:
    code = ("import sys; from pathlib import Path; from csm_assets.blender.install import check_folder; "
            "from csm_assets.errors import OutputError\n"
            "try:\n    check_folder(Path(sys.argv[1])); print('ACCEPTED')\n"
            "except OutputError as e:\n    print('REFUSED', e)")
    return subprocess.run([sys.executable, "-c", code, str(addons)], capture_output=True, text=True, timeout=60)


def _addons(tmp_path, name="addons") -> tuple[Path, Path]:
    addons = tmp_path / name
    (addons / "csm_assets_gltf").mkdir(parents=True)
    return addons, addons / "csm_assets_gltf" / "__init__.py"


def test_installer_refuses_a_fifo_and_device_links_without_reading_them(tmp_path):
    addons, init = _addons(tmp_path, "fifo")
    os.mkfifo(init)
    r = _check(addons)  # reading it would block for ever
    assert r.stdout.startswith("REFUSED") and "not a regular file" in r.stdout, r.stdout + r.stderr
    for device in ("/dev/zero", "/dev/urandom"):
        addons, init = _addons(tmp_path, Path(device).name)
        init.symlink_to(device)
        r = _check(addons)  # reading it would never end
        assert r.stdout.startswith("REFUSED") and "is a link" in r.stdout, r.stdout + r.stderr


def test_installer_refuses_a_link_out_and_a_foreign_folder(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    addons = tmp_path / "addons"
    addons.mkdir()
    (addons / "csm_assets_gltf").symlink_to(outside)
    r = _check(addons)
    assert "REFUSED" in r.stdout and "outside" in r.stdout and not list(outside.iterdir()), r.stdout
    for name, target in (("loop", "csm_assets_gltf"), ("dangling", str(tmp_path / "gone"))):
        links = tmp_path / name
        links.mkdir()
        (links / "csm_assets_gltf").symlink_to(target)
        assert "is a link that leads nowhere" in _check(links).stdout
    foreign, _ = _addons(tmp_path, "foreign")  # the user's own folder of that name, no __init__.py
    assert "REFUSED" in _check(foreign).stdout and "no __init__.py" in _check(foreign).stdout
    ours, init = _addons(tmp_path, "ours")
    init.write_text("# Written by `csm-assets blender install` (csm-assets 1)\n")
    assert _check(ours).stdout.startswith("ACCEPTED")
    theirs, init = _addons(tmp_path, "theirs")
    init.write_text("bl_info = {}\n")
    assert "was not written by csm-assets" in _check(theirs).stdout


def _plant(addons: Path, kind: str, outside: Path) -> None:
    folder = addons / "csm_assets_gltf"
    if kind == "link out":
        addons.mkdir(parents=True)
        folder.symlink_to(outside)
        return
    folder.mkdir(parents=True)
    if kind == "fifo":
        os.mkfifo(folder / "__init__.py")
    elif kind == "/dev/zero":
        (folder / "__init__.py").symlink_to("/dev/zero")
    # "foreign": the user's own folder of that name, without __init__.py


@pytest.mark.parametrize("kind, said", [("fifo", "not a regular file"), ("/dev/zero", "is a link"),
                                        ("link out", "outside"), ("foreign", "has no __init__.py")])
def test_install_command_refuses_with_one_line(tmp_path, kind, said):
    """The real command, Blender's add-ons folder under a private HOME: exit 4, one line, nothing written
    (a subprocess timeout far above the seconds it takes: a FIFO read would block for ever)."""
    from attack import run_cli

    home, outside = tmp_path / "home", tmp_path / "outside"
    outside.mkdir()
    addons = home / Path(bpy.utils.user_resource("SCRIPTS", path="addons")).relative_to(Path.home())
    _plant(addons, kind, outside)
    r = run_cli("blender", "install", env=dict(os.environ, HOME=str(home)), timeout=300)
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.returncode == 4 and len(lines) == 1 and said in lines[0], r.stdout + r.stderr
    assert not list(outside.iterdir()) and not list(addons.rglob("*.tmp*"))
    if kind == "foreign":
        assert not list((addons / "csm_assets_gltf").iterdir())  # the user's folder left as it was


@pytest.mark.parametrize("value, said", [(0.0, "has Scale 0: it displaces nothing"),
                                         (float("nan"), "has Scale nan; only a finite Scale is converted")])
def test_a_displacement_scale_of_0_or_nan_is_a_warning_in_the_export_report(tmp_path, value, said):
    scene.build()
    node = next(n for n in bpy.data.materials["displaced"].node_tree.nodes if n.bl_idname == "ShaderNodeDisplacement")
    node.inputs["Scale"].default_value = value
    report = addon.export_gltf(tmp_path / "s.glb")
    (warning,) = [w for w in report.warnings if "'displaced'" in w]
    assert said in warning and "displaced" not in report.materials and "bumped" in report.materials, warning


def test_a_file_blenders_importer_refuses_is_one_line(tmp_path):
    """Not the add-on's to set up: Blender's own parser refuses a texture whose source is text; the
    scripting call says so in one line (a FormatError naming the file), not Blender's traceback."""
    from csm_assets.errors import FormatError

    path = tmp_path / "broken.gltf"
    path.write_text('{"asset": {"version": "2.0"}, "textures": [{"source": "x"}]}')
    with pytest.raises(FormatError) as caught:
        addon.import_gltf(path)
    assert str(caught.value).startswith(f"{path}: Blender's glTF importer refused it") and "\n" not in str(caught.value)


@pytest.mark.parametrize("depth", [1e30, 1e-30])
def test_an_unmeasurable_csm_depth_is_named_in_the_export_warning(tmp_path, depth):
    """Was: the warning named 'depth_scale (the texture-space depth)', a library argument, not the
    custom property csm_depth the user set."""
    scene.build()
    bpy.data.materials["by_property"]["csm_depth"] = depth
    report = addon.export_gltf(tmp_path / "s.glb")
    (said,) = [w for w in report.warnings if "'by_property'" in w]
    assert f"its custom property csm_depth {depth:g} is" in said and "nothing can be measured" in said, said
    assert "by_property" not in report.materials and "displaced" in report.materials
