"""What a new user runs from the README, and what used to go wrong: each case runs the real
CLI (``tests/attack.py``) and checks the documented result."""

from __future__ import annotations

import json

import numpy as np
import pytest

import csm_assets as csm
from attack import Attack, assert_clean_error, assert_clean_run, run_cli
from conftest import SAMPLES, skip_without_gl


def test_tga_step_map_keeps_its_settings(tmp_path):
    """`stepmap -o x.tga` keeps the settings (OpenImageIO splits a TGA comment into 80-character
    lines: the JSON came back broken and the map read as 'made elsewhere'); a name too long
    for the TGA's 323 characters drops only the source note."""
    long_name = tmp_path / ("h" * 200 + ".png")
    long_name.write_bytes((SAMPLES / "cobbles.png").read_bytes())
    for src, out in [(SAMPLES / "cobbles.png", tmp_path / "c.tga"), (long_name, tmp_path / "long.tga")]:
        with Attack(src):
            assert_clean_run(run_cli("stepmap", src, "-o", out, "--invert", "--max-ratio", "2"))
        meta = csm.read_step_map_meta(out)
        assert meta["max_ratio"] == 2.0 and meta["height_scale"] == -1.0 and meta["tile"] == [True, True]
        sm = csm.load_step_map(out)
        assert sm.settings.max_ratio == 2.0 and sm.settings.bilinear_safe
        png = tmp_path / "same.png"
        assert_clean_run(run_cli("stepmap", src, "-o", png, "--invert", "--max-ratio", "2"))
        assert np.array_equal(sm.pixels, csm.load_step_map(png).pixels)
    assert csm.read_step_map_meta(tmp_path / "c.tga")["source"] == "cobbles.png"
    assert "source" not in csm.read_step_map_meta(tmp_path / "long.tga")


def test_tga_description_too_long_is_refused(tmp_path):
    packed = np.zeros((2, 2, 4), np.uint8)
    with pytest.raises(ValueError, match="323 characters"):
        csm.write_step_map(packed, tmp_path / "x.tga", meta={"note": "x" * 400})
    assert not (tmp_path / "x.tga").exists()
    csm.write_step_map(packed, tmp_path / "x.png", meta={"note": "x" * 400})  # PNG has room
    assert csm.read_step_map_meta(tmp_path / "x.png")["note"] == "x" * 400


def _rgba_heights(path, seed=3):
    """An RGBA height map whose R, G, B differ a little (as LearnOpenGL's toy_box_disp.png)."""
    from csm_assets.formats.image import write_rgba

    rng = np.random.default_rng(seed)
    h = (np.add.outer(np.sin(np.arange(24) / 3), np.cos(np.arange(24) / 4)) * 60 + 128).astype(np.uint8)
    rgba = np.stack([h, np.clip(h.astype(int) + rng.integers(-2, 3, h.shape), 0, 255).astype(np.uint8), h,
                     np.full_like(h, 255)], axis=-1)
    write_rgba(rgba, path)
    return path


@pytest.mark.parametrize("command", [["verify"], ["bench", "trade"]])
def test_rgba_map_options_the_error_names_are_accepted(tmp_path, command):
    """The RGBA-map error tells the user to say --step-map, --height-map or --channel (with
    --max-ratio, --no-tile, --min-step): `bench trade` printed it but rejected every one (exit 2
    'unrecognized arguments'), so an RGBA height map could not be benched at all."""
    skip_without_gl()
    src = _rgba_heights(tmp_path / "toy_disp.png")
    quick = ["--size", "8", "--views", "45/0", "--json"]
    with Attack(src):
        message = assert_clean_error(run_cli(*command, src, *quick), 3, src)
        named = sorted(set(w.strip("(),;") for w in message.split() if w.startswith("--")))
        assert named == ["--channel", "--height-map", "--max-ratio", "--min-step", "--no-tile", "--step-map"]
        for extra in (["--height-map", "--invert"], ["--channel", "0", "--no-tile"],
                      ["--step-map", "--max-ratio", "1", "--min-step", "1"]):
            r = run_cli(*command, src, *quick, *extra)
            assert_clean_run(r, r.returncode)
            assert r.returncode in (0, 1), r.stderr
            assert json.loads(r.stdout)
    if command == ["bench", "trade"]:  # a step map made elsewhere: no relaxed-cone rows made from it
        rows = json.loads(run_cli(*command, src, *quick, "--step-map").stdout)["rows"]
        assert rows and {row.get("cones", "conservative") for row in rows} == {"conservative"}


def test_stepmap_refuses_a_normal_map_and_warns_on_a_photo(tmp_path):
    """`stepmap` ran no height-source check: a normal map (the samples' bricks_normal.png) gave
    exit 0 and a nonsense step map. Now exit 3 naming the file, unless --channel says what to
    read; a colour photograph is converted from luminance with one warning line, as in convert."""
    out = tmp_path / "o.png"
    normal = SAMPLES / "bricks_normal.png"
    with Attack(normal):
        msg = assert_clean_error(run_cli("stepmap", normal, "-o", out), 3, normal)
        assert "normal map" in msg and "--channel" in msg and not out.exists()
        assert_clean_run(run_cli("stepmap", normal, "-o", out, "--channel", "2"))
    rng = np.random.default_rng(1)
    photo = tmp_path / "photo.png"
    from csm_assets.formats.image import write_rgba

    blocks = rng.integers(0, 256, (8, 8, 3)).repeat(8, 0).repeat(8, 1).astype(np.uint8)
    write_rgba(np.concatenate([blocks, np.full((64, 64, 1), 255, np.uint8)], -1), photo)
    warnings = assert_clean_run(run_cli("stepmap", photo, "-o", out))
    assert len(warnings) == 1 and "colour image" in warnings[0] and str(photo) in warnings[0]
    assert out.exists()
    assert assert_clean_run(run_cli("stepmap", SAMPLES / "cobbles.png", "-o", tmp_path / "c.png")) == []


@pytest.mark.parametrize("bad", ["heights.ktx2", "truncated.png"])
def test_unreadable_height_named_on_the_command_line_is_exit_3(tmp_path, bad):
    """A --height texture that does not exist was exit 3, but one in a format csm-assets does
    not read (a .ktx2, as Bevy's models ship) or a truncated PNG was a warning, exit 0 and the
    scene 'unchanged': the user's request silently dropped. Now exit 3 naming the file, nothing
    written; a bad texture the scene itself names stays a counted warning."""
    from conftest import GLTF_WALL, copy_samples

    scene = copy_samples(tmp_path / "in", GLTF_WALL) / "brick_wall.gltf"
    tex = tmp_path / bad
    tex.write_bytes((SAMPLES / "bricks_height.png").read_bytes()[:300])
    out = tmp_path / "out"
    with Attack(scene.parent, tex):
        msg = assert_clean_error(run_cli("convert", scene, "-o", out, "--height", f"bricks={tex}"), 3, tex)
        assert not out.exists() or not any(out.iterdir()), msg
    (scene.parent / "bricks_height.png").write_bytes(tex.read_bytes())  # the scene's own: a warning
    warnings = assert_clean_run(run_cli("convert", scene, "-o", out))
    assert len(warnings) == 1 and "bricks_height.png" in warnings[0]


COMMANDS = ["stepmap", "convert", "check", "hook", "verify", "bench cones", "bench trade", "view"]


def _readme_synopsis() -> dict[str, set[str]]:
    """The options each command's lines in the command-line reference's Synopsis block name
    (docs/reference/cli/index.md, where the README's Command line block moved)."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "reference" / "cli" / "index.md").read_text()
    block = text.split("## Synopsis", 1)[1].split("```", 2)[1]
    found: dict[str, set[str]] = {}
    current = None
    settings = set()
    for line in block.splitlines():
        m = re.match(r"csm-assets (bench \w+|\w+)", line)
        if m:
            current = m.group(1)
        elif line.startswith("python"):
            current = None
        if line.lstrip().startswith("# SETTINGS"):
            current = "SETTINGS"
        opts = set(re.findall(r"(?<![\w-])(--[a-z][a-z-]*|-[a-zA-Z])\b", line.split(" # ")[0] if current != "SETTINGS"
                                                                             else line))
        if current == "SETTINGS":
            settings |= opts
        elif current:
            found.setdefault(current, set()).update(opts)
    for cmd in ("check", "hook"):
        found[cmd] |= settings
    return found


def _help_options(command: str) -> set[str]:
    import re

    r = run_cli(*command.split(), "--help")
    assert r.returncode == 0, r.stderr
    return set(re.findall(r"(?<![\w-])(--[a-z][a-z-]*|-[a-zA-Z])\b", r.stdout.split("options:", 1)[1])) - {"-h", "--help"}


@pytest.mark.parametrize("command", COMMANDS)
def test_readme_synopsis_and_help_agree(command):
    """Every option the reference's synopsis names is one the command takes, and every option the
    command takes is in its synopsis (verify's `[...]` stands for its map options, which the
    Verifying renders page documents; the short -o/-q forms count as their long ones)."""
    readme = _readme_synopsis()[command]
    cli = _help_options(command)
    aliases = {"--output": "-o", "--quiet": "-q"}
    cli = {aliases.get(o, o) for o in cli}
    assert readme - cli == set(), f"the synopsis names options `{command} --help` does not have"
    missing = cli - readme - ({"--bilinear-safe"} if command == "stepmap" else set())
    if command == "verify":  # `[...]`: documented in the Verifying renders page
        from pathlib import Path

        text = (Path(__file__).resolve().parents[1] / "docs" / "reference" / "verify.md").read_text()
        missing = {o for o in missing if f"`{o}" not in text}
    assert missing == set(), f"`{command} --help` has options the synopsis does not name"


@pytest.mark.parametrize("kind", ["gltf", "usda"])
def test_material_no_mesh_can_draw_gets_no_csm(tmp_path, kind):
    """glTF and USD as OBJ: a material whose meshes all lack the uvs its heights need got the
    CSM material and a step map anyway (exit 0, 'converted'), which no viewer can draw and
    verify called 'no mesh uses a CSM material' (assimp's 2CylinderEngine and issue_3269,
    usd-wg's TextureCoordinateTest BackPlane). Now one warning naming the material, the
    scene 'unchanged', nothing of CSM written."""
    from conftest import GLTF_WALL, copy_samples

    if kind == "gltf":
        folder = copy_samples(tmp_path / "in", GLTF_WALL)
        doc = json.loads((folder / "brick_wall.gltf").read_text())
        for mesh in doc["meshes"]:
            for prim in mesh["primitives"]:
                prim["attributes"].pop("TEXCOORD_0")
        (folder / "bare.gltf").write_text(json.dumps(doc))
        extra = []
    else:
        from usd_stages import edit, wall_folder

        folder = wall_folder(tmp_path)
        (folder / "bare.usda").write_bytes((folder / "brick_wall.usda").read_bytes())
        edit(folder / "bare.usda", lambda stage: stage.GetPrimAtPath("/World/wall").RemoveProperty("primvars:st"))
        extra = ["--height", f"bricks={folder / 'bricks_height.png'}"]  # the sample's own has uvs named st
    out = tmp_path / "out"
    with Attack(folder):
        r = run_cli("convert", folder / f"bare.{kind}", "-o", out, "--json", *extra)
    warnings = assert_clean_run(r)
    assert any("material 'bricks'" in w and "no CSM material" in w for w in warnings), warnings
    assert json.loads(r.stdout)["results"][0]["status"] == "unchanged"
    text = (out / f"bare.{kind}").read_text()
    assert "EXT_materials_cone_step_mapping" not in text and "CsmSurface" not in text
    assert not list(out.glob("*_csm*"))


def test_stepmap_output_without_an_extension_says_what_to_name(tmp_path):
    """`stepmap IN -o folder/` (or a name without an extension): exit 2 saying to name a file,
    not the garbled 'not no extension'; nothing written."""
    (tmp_path / "out").mkdir()
    for out in (tmp_path / "out", tmp_path / "noext"):
        with Attack(SAMPLES / "cobbles.png"):
            r = run_cli("stepmap", SAMPLES / "cobbles.png", "-o", f"{out}/" if out.is_dir() else out)
        assert_clean_error(r, 2, out.name)
        assert "has no extension (name a file, e.g. height_csm.png)" in r.stderr and "not no" not in r.stderr
    assert list((tmp_path / "out").iterdir()) == [] and not (tmp_path / "noext").exists()


def test_uvs_outside_the_untiled_map_are_warned_and_never_verified_as_passing(tmp_path):
    """A mesh whose uvs lie outside [0, 1] (DamagedHelmet's v runs 1..2, meant to repeat),
    converted with --no-tile: convert counts a warning naming the axis; verify measured no
    pixel there and used to say PASS (0 pixels at every view), now NOT VERIFIABLE, exit 1.
    Tiled, the same mesh converts without that warning and passes."""
    skip_without_gl()
    src = tmp_path / "in"
    src.mkdir()
    for name in ("brick_wall.mtl", "bricks_color.png", "bricks_height.png", "bricks_normal.png"):
        (src / name).write_bytes((SAMPLES / name).read_bytes())
    lines = []
    for line in (SAMPLES / "brick_wall.obj").read_text().splitlines():
        if line.startswith("vt "):
            u, v = map(float, line.split()[1:3])
            line = f"vt {u:g} {v + 1:g}"
        lines.append(line)
    (src / "wall.obj").write_text("\n".join(lines) + "\n")
    r = run_cli("convert", src / "wall.obj", "-o", tmp_path / "flat", "--no-tile")
    assert r.returncode == 0, r.stderr
    assert "outside [0, 1] on an axis that does not tile" in r.stderr and "along v" in r.stderr
    r = run_cli("verify", tmp_path / "flat" / "wall.obj", "--size", "32")
    assert r.returncode == 1 and "NOT VERIFIABLE: no pixel" in r.stdout, r.stdout
    r = run_cli("convert", src / "wall.obj", "-o", tmp_path / "tiled")
    assert r.returncode == 0 and "outside [0, 1]" not in r.stderr
    assert_clean_run(run_cli("verify", tmp_path / "tiled" / "wall.obj", "--size", "32"))
