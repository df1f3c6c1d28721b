"""Warning codes: one table (csm_assets.warning_codes.RULES) that every emitter uses and the docs
page is made from; identical warnings collapsed with a count; which warnings fail a run
(--strict, --error-on, --ignore) in the library and through the CLI's exit codes."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

from attack import assert_clean_error, assert_clean_run, run_cli
from conftest import OBJ_WALL, copy_samples
from csm_assets.convert.pipeline import convert
from csm_assets.errors import OptionError, StrictError
from csm_assets.scene import Scene
from csm_assets.warning_codes import BY_CODE, INFO, RULES, WARNING, Notice, Policy, checked_codes, markdown_table
from usd_stages import edit, wall_folder

ROOT = Path(__file__).resolve().parents[1]
CODE = re.compile(r"CSM\d{3}")


def test_the_table_is_well_formed():
    assert len(BY_CODE) == len(RULES) and len({r.name for r in RULES}) == len(RULES)
    for r in RULES:
        assert CODE.fullmatch(r.code) and re.fullmatch(r"[a-z0-9-]+", r.name), r
        assert r.severity in (INFO, WARNING), r
        assert r.meaning.endswith(".") and "\n" not in r.meaning and len(r.meaning) < 240, r


def _code_literals() -> dict[str, set[str]]:
    """Code strings in the package's source, by file (the table's own module left out)."""
    found: dict[str, set[str]] = {}
    for path in (ROOT / "csm_assets").rglob("*.py"):
        if path.name == "warning_codes.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                for code in CODE.findall(node.value):
                    found.setdefault(code, set()).add(path.name)
    return found


def test_every_code_emitted_is_in_the_table_and_every_rule_is_emitted():
    used = _code_literals()
    assert set(used) - set(BY_CODE) == set(), "codes used that the table lacks"
    kept_by_the_table_module = {"CSM000", "CSM301", "CSM900"}  # manifests before codes, NarrowCones, Python's
    kept_by_the_table_module |= {"CSM105"}  # retired: still accepted by --ignore/--error-on, never emitted
    assert set(BY_CODE) - set(used) - kept_by_the_table_module == set(), "rules nothing emits"


def test_every_scene_warning_names_its_code():
    """Each ``.warn(...)`` call of a scene passes a code literal first (or the code of a
    (code, text) pair: mesh_problems)."""
    for path in (ROOT / "csm_assets").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "warn" \
                    and not (isinstance(node.func.value, ast.Name) and node.func.value.id == "warnings"):
                first = node.args[0]
                ok = (isinstance(first, ast.Constant) and first.value in BY_CODE) or \
                     (isinstance(first, ast.Name) and first.id == "code") or \
                     (isinstance(first, ast.Attribute) and first.attr == "code")
                assert ok, f"{path.name}:{node.lineno}: a warning without a code"


def test_docs_page_holds_the_table_made_from_the_data():
    page = (ROOT / "docs" / "reference" / "warnings.md").read_text()
    start = page.index("<!-- table: made by csm_assets.warning_codes.markdown_table() -->\n")
    table = page[page.index("\n", start) + 1: page.index("<!-- end of table -->")]
    assert table == markdown_table(), ("docs/reference/warnings.md differs from the table in "
                                       "csm_assets/warning_codes.py: paste markdown_table() between the markers")


# ------------------------------------------------------------------ collapsing

def test_identical_warnings_collapse_with_a_count_and_their_subjects():
    scene = Scene(Path("ship.usda"), "usda")
    for i in range(5):
        scene.warn("CSM208", "a catmullClark subdivision surface", f"mesh /World/m{i}")
    scene.warn("CSM208", "a catmullClark subdivision surface", "mesh /World/m0")  # said twice: counted twice
    scene.warn("CSM208", "a loop subdivision surface", "mesh /World/x")  # other text: its own line
    scene.warn("CSM205", "a catmullClark subdivision surface", "mesh /World/m0")  # other code: its own line
    assert [n.count for n in scene.warnings] == [6, 1, 1]
    first = scene.warnings[0]
    assert first.about == tuple(f"mesh /World/m{i}" for i in range(5))
    assert first.message == ("ship.usda: 6 x mesh /World/m0, mesh /World/m1, mesh /World/m2 and 2 more: "
                             "a catmullClark subdivision surface")
    assert str(first).startswith("CSM208 ship.usda: 6 x ")
    assert str(scene.warnings[1]) == "CSM208 ship.usda: mesh /World/x: a loop subdivision surface"
    bare = Scene(Path("a.obj"), "obj")
    bare.warn("CSM207", "2 face(s) skipped")
    bare.warn("CSM207", "2 face(s) skipped")
    assert [str(n) for n in bare.warnings] == ["CSM207 a.obj: 2 x 2 face(s) skipped"]


def test_notices_round_trip_through_the_manifest_and_old_strings_are_unclassified():
    n = Notice("CSM208", "ship.usda", "a catmullClark subdivision surface", ("mesh /a", "mesh /b"), 3)
    assert Notice.from_dict(json.loads(json.dumps(n.record()))) == n
    d = n.to_dict()
    assert (d["code"], d["severity"], d["name"], d["count"]) == ("CSM208", "info", "subdivision", 3)
    old = Notice.from_dict("wall.obj: material 'bricks': disp texture gone.png is missing")
    assert old.code == "CSM000" and old.severity == WARNING and old.message.startswith("wall.obj: material")


# ------------------------------------------------------------------ the policy

def test_policy_levels():
    p = Policy()
    assert (p.level("CSM208"), p.level("CSM202")) == ("info", "warning")
    strict = Policy(strict=True)
    assert (strict.level("CSM208"), strict.level("CSM202")) == ("info", "error")
    assert Policy(error_on=("CSM208",)).level("CSM208") == "error"
    assert Policy(strict=True, ignore=("CSM202",)).level("CSM202") == "ignore"
    notices = [Notice("CSM208", "s", "t"), Notice("CSM202", "s", "u")]
    assert strict.failing(notices) == notices[1:] and strict.why(notices[1:]) == "--strict"
    both = Policy(strict=True, error_on=("CSM208",))
    assert both.failing(notices) == notices and both.why(notices) == "--strict and --error-on"
    assert Policy(ignore=("CSM208",)).kept(notices) == notices[1:]


def test_codes_are_checked():
    assert checked_codes(["csm205", " CSM205 ", "CSM208"], "x") == ("CSM205", "CSM208")
    assert checked_codes("CSM205", "x") == ("CSM205",)
    for bad in (["CSM999"], ["E501"], [205]):
        with pytest.raises(ValueError, match="^--ignore: .*warning code"):
            checked_codes(bad, "--ignore")


# ------------------------------------------------------------------ convert, the library

@pytest.fixture
def subdivided(tmp_path):
    """The sample USD wall as an exporter that leaves USD's default subdivision scheme writes it:
    one informational warning (CSM208)."""
    wall = wall_folder(tmp_path) / "brick_wall.usda"
    return edit(wall, lambda st: st.GetPrimAtPath("/World/wall").GetAttribute("subdivisionScheme").Clear())


def test_library_strict_passes_informational_warnings_and_promotes_or_ignores_by_code(subdivided, tmp_path):
    r = convert(subdivided, tmp_path / "a", strict=True)
    assert [n.code for n in r.warnings] == ["CSM208"] and r.warnings[0].severity == "info"
    with pytest.raises(StrictError) as e:
        convert(subdivided, tmp_path / "b", error_on=("csm208",))
    assert [n.code for n in e.value.failing] == ["CSM208"] and "--error-on (CSM208)" in str(e.value)
    assert not (tmp_path / "b" / "brick_wall.usda").exists()
    with pytest.raises(StrictError):  # fresh outputs keep their warnings, and fail the same way
        convert(subdivided, tmp_path / "a", error_on=("CSM208",))
    r = convert(subdivided, tmp_path / "a", ignore=("CSM208",), strict=True)
    assert r.skipped == "outputs are fresh" and r.warnings == []  # the policy does not make outputs stale
    assert convert(subdivided, tmp_path / "c", ignore=("CSM208",)).warnings == []
    recorded = json.loads((tmp_path / "c" / "csm-manifest.json").read_text())["scenes"]["brick_wall.usda"]
    assert [w["code"] for w in recorded["warnings"]] == ["CSM208"]  # ignored is not forgotten


def test_library_refuses_unknown_or_contradicting_codes(subdivided, tmp_path):
    with pytest.raises(OptionError, match="'CSM999' is not a warning code"):
        convert(subdivided, tmp_path / "o", error_on=("CSM999",))
    with pytest.raises(OptionError, match="CSM208 are both in error_on and in ignore"):
        convert(subdivided, tmp_path / "o", error_on=("CSM208",), ignore=("CSM208",))
    assert not (tmp_path / "o").exists()


def test_python_warnings_of_a_conversion_become_its_coded_warnings(tmp_path):
    """A max ratio so wide that cones fall below one 8-bit step: at 8 bits, packing's NarrowCones
    warning is CSM301 of the scene (severity warning), so --strict fails on it."""
    src = copy_samples(tmp_path / "in", ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png",
                                         "bricks_height.png", "bricks_normal.png"])
    r = convert(src / "brick_wall.gltf", tmp_path / "out", max_ratio=1e6, bits=8)
    narrow, chain = [n for n in r.warnings if n.code == "CSM301"]  # (and CSM304: --bits 16 would be better)
    assert "narrower than one 8-bit step" in narrow.text
    assert chain.text.startswith("levels 1-7: some cones are narrower")  # the level chain's, said apart
    with pytest.raises(StrictError, match="CSM301"):
        convert(src / "brick_wall.gltf", tmp_path / "out2", max_ratio=1e6, bits=8, strict=True)
    # left to choose, the bits are the fewest that store every cone exactly (16 here): nothing to say
    r = convert(src / "brick_wall.gltf", tmp_path / "out3", max_ratio=1e6)
    assert r.warnings == [] and r.picks["bricks"]["bits"] == 16


# ------------------------------------------------------------------ the CLI

def test_cli_exit_codes_for_strict_error_on_and_ignore(subdivided, tmp_path):
    out = tmp_path / "out"
    lines = assert_clean_run(run_cli("convert", subdivided, "-o", out, "--strict"))
    assert len(lines) == 1 and lines[0].startswith("csm-assets: info: CSM208 ") and "catmullClark" in lines[0]
    r = run_cli("convert", subdivided, "-o", tmp_path / "o2", "--error-on", "CSM208")
    assert "--error-on (CSM208)" in assert_clean_error(r, 3, "brick_wall.usda")
    assert not (tmp_path / "o2" / "brick_wall.usda").exists()
    assert assert_clean_run(run_cli("convert", subdivided, "-o", out, "--ignore", "CSM208")) == []
    for cmd in (["convert", subdivided, "-o", out], ["check", subdivided, "-o", out], ["hook", subdivided]):
        r = run_cli(*cmd, "--ignore", "CSM999")
        assert "--ignore: 'CSM999' is not a warning code" in assert_clean_error(r, 2)
        r = run_cli(*cmd, "--error-on", "CSM208", "--ignore", "csm208")
        assert "both in --error-on and in --ignore" in assert_clean_error(r, 2)
    assert_clean_run(run_cli("check", subdivided, "-o", out, "--strict"))  # informational: passes
    r = run_cli("check", subdivided, "-o", out, "--error-on", "CSM208", "-q")
    assert "CSM208" in assert_clean_error(r, 3, "brick_wall.usda")
    assert_clean_run(run_cli("check", subdivided, "-o", out, "--error-on", "CSM205"))
    r = run_cli("hook", subdivided, "--error-on", "CSM208")  # the hook fails the same way, writes nothing
    assert "--error-on (CSM208)" in assert_clean_error(r, 3, "brick_wall.usda")
    assert not (subdivided.parent / "brick_wall_usda_csm").exists()
    lines = assert_clean_run(run_cli("hook", subdivided, "--strict"), 1)  # wrote: add them to the commit
    assert [x.split()[2] for x in lines if x.startswith("csm-assets: info:")] == ["CSM208"]


def test_cli_json_report_carries_code_and_severity(subdivided, tmp_path):
    r = run_cli("convert", subdivided, "-o", tmp_path / "out", "--json")
    assert_clean_run(r)
    (w,) = json.loads(r.stdout)["results"][0]["warnings"]
    assert (w["code"], w["severity"], w["name"], w["count"]) == ("CSM208", "info", "subdivision", 1)
    assert w["message"].endswith("approximate the limit surface's") and w["about"] == ["mesh /World/wall"]


def test_check_fails_fresh_outputs_whose_recorded_warnings_are_errors(tmp_path):
    """The OBJ wall whose MTL names a missing texture (CSM101, severity warning): converted without
    --strict, its outputs are fresh; check --strict says they were made with that warning (exit 3)."""
    src = copy_samples(tmp_path / "in", OBJ_WALL)
    mtl = src / "brick_wall.mtl"
    mtl.write_text(mtl.read_text().replace("disp -mm 0 0.03 bricks_height.png", "disp -mm 0 0.03 gone.png"))
    out = tmp_path / "out"
    (line,) = assert_clean_run(run_cli("convert", src / "brick_wall.obj", "-o", out))
    assert line.startswith("csm-assets: warning: CSM101 ") and "gone.png" in line
    assert_clean_run(run_cli("check", src / "brick_wall.obj", "-o", out))
    r = run_cli("check", src / "brick_wall.obj", "-o", out, "--strict", "-q")
    assert "--strict" in assert_clean_error(r, 3, "brick_wall.obj")
    assert_clean_run(run_cli("check", src / "brick_wall.obj", "-o", out, "--strict", "--ignore", "CSM101"))


def test_python_warnings_go_to_their_own_scene_when_scenes_convert_in_threads(tmp_path):
    """Two conversions at once in one process (a Dask worker's threads): each scene gets its own
    CSM301, none is lost to the other or to stderr."""
    from concurrent.futures import ThreadPoolExecutor

    scenes = [copy_samples(tmp_path / f"in{i}", ["brick_wall.gltf", "brick_wall.bin", "bricks_color.png",
                                                  "bricks_height.png", "bricks_normal.png"]) / "brick_wall.gltf"
              for i in range(2)]
    with ThreadPoolExecutor(2) as pool:
        reports = list(pool.map(lambda i: convert(scenes[i], tmp_path / f"out{i}", max_ratio=1e6, bits=8),
                                range(2)))
    for i, r in enumerate(reports):
        assert [(n.code, n.where) for n in r.warnings if n.code == "CSM301"] == [("CSM301", str(scenes[i]))] * 2
